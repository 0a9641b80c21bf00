"""Linear least-squares models: the industry's polynomials and the lag-temperature profile.

- `poly`: SF error as a polynomial in the board temperature.
- `polyrate`: polynomial in T plus a filtered dT/dt and its products with T (the industry
  standard for hysteresis).
- `profile_effective_node`: identifies the effective sensing temperature
  T_eff = w T + (1 - w) lag(T, tau) (the physics: the sensing parts lag the board) by
  profiling a grid of (tau, w), with least squares inside (profile likelihood).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from fogsf.models.features import SeqData, prepare
from fogsf.models.front_end import FrontEnd, filter_alpha


def poly_design(z: np.ndarray, degree: int, with_rate: bool) -> np.ndarray:
    """Columns T^0..T^degree (z[:, 0] = normalised T); with a rate (z[:, 1]): R, R T, R T^2."""
    t = z[:, 0].astype(np.float64)
    cols = [t**k for k in range(degree + 1)]
    if with_rate:
        r = z[:, 1].astype(np.float64)
        cols += [r, r * t, r * t * t]
    return np.column_stack(cols)


@dataclass
class LinearFit:
    coef: np.ndarray
    degree: int
    with_rate: bool

    def predict(self, z: np.ndarray) -> np.ndarray:
        return poly_design(z, self.degree, self.with_rate) @ self.coef

    @property
    def params(self) -> int:
        return int(self.coef.size)


def fit_linear(data: list[SeqData], z: list[np.ndarray], degree: int,
               with_rate: bool) -> LinearFit:
    x = np.concatenate([poly_design(a[d.train_mask], degree, with_rate)
                        for a, d in zip(z, data, strict=True)])
    y = np.concatenate([d.target_ppm[d.train_mask] for d in data])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return LinearFit(coef, degree, with_rate)


TAU_GRID_S = tuple(float(t) for t in np.geomspace(60.0, 7200.0, 11).round(0))
LEAD_GRID_S = (0.0, 60.0, 120.0, 240.0, 400.0)
NODE_DEGREE = 3
# The physics prior of every lag model: no node's temperature moves the SF by more than this
# (the default gyro's largest is 13 ppm/C). Without it, quadratic forms of nearly collinear
# nodes fit with huge cancelling coefficients that amplify thermometer noise and extrapolate
# wildly.
MAX_NODE_SLOPE_PPM_PER_C = 50.0


def node_weight(lead_s: float, tau_s: float) -> float:
    """w in T_eff = w T + (1 - w) lag(T, tau) for a node with time constant tau behind a
    common driver that the board follows with time constant lead_s: the node's transfer from
    the board is (1 + lead s) / (1 + tau s) = w + (1 - w) / (1 + tau s), w = lead / tau."""
    return min(lead_s / tau_s, 1.0)


T_EFF_SCALE_C = 50.0  # node temperatures enter the designs as (T - t_ref) / 50


def _t_eff(s: np.ndarray, k: int, w: float) -> np.ndarray:
    return (w * s[:, 0].astype(np.float64) + (1.0 - w) * s[:, k].astype(np.float64)) \
        / T_EFF_SCALE_C


def _node_design(s: np.ndarray, k: int, w: float, degree: int = NODE_DEGREE) -> np.ndarray:
    t_eff = _t_eff(s, k, w)
    return np.column_stack([t_eff**p for p in range(degree + 1)])


def _two_node_design(s: np.ndarray, k1: int, w1: float, k2: int, w2: float) -> np.ndarray:
    """The SF as a quadratic form of two nodes (the simulator's physics: each factor is a
    quadratic in a weighted mean of node temperatures)."""
    a, b = _t_eff(s, k1, w1), _t_eff(s, k2, w2)
    return np.column_stack([np.ones_like(a), a, b, a * a, a * b, b * b])


def grid_data(logs: list, fe: FrontEnd, grid: tuple[float, ...], latitude_deg: float | None
              ) -> tuple[list[SeqData], np.ndarray]:
    """Every log through a front end with one lag filter per grid time constant, and the
    targets of all their measured steps stacked (rows: `measured_rows`)."""
    full = replace(fe, filter_alpha=filter_alpha(list(grid), fe.decimation, fe.sample_dt_s),
                   filter_tau_s=tuple(float(t) for t in grid))
    data = [prepare(lg, full, None, latitude_deg) for lg in logs]
    return data, np.concatenate([d.target_ppm[d.measured] for d in data])


def measured_rows(data: list[SeqData]) -> np.ndarray:
    """The front-end rows of the measured steps of `data`, stacked (`grid_data`'s targets)."""
    return np.concatenate([d.s[d.measured] for d in data])


@dataclass(frozen=True)
class NodeCandidate:
    """One structure of the lag-temperature family: one effective node with a cubic in it
    (`nodes` of length 1) or two with a quadratic form of them (length 2). `ks` index the
    grid front end's filters (1-based, as in s)."""

    nodes: tuple[tuple[float, float], ...]
    ks: tuple[int, ...]

    def design(self, s: np.ndarray) -> np.ndarray:
        if len(self.ks) == 1:
            return _node_design(s, self.ks[0], self.nodes[0][1])
        return _two_node_design(s, self.ks[0], self.nodes[0][1], self.ks[1], self.nodes[1][1])

    def max_node_slope(self, coef: np.ndarray, s: np.ndarray) -> float:
        """The largest |d SF / d node temperature| (ppm/C) of the fit `coef` over the rows of
        s: the sensitivity of the SF to any one node's temperature that the fit implies."""
        a = _t_eff(s, self.ks[0], self.nodes[0][1])
        if len(self.ks) == 1:
            slopes = [coef[1] + 2 * coef[2] * a + 3 * coef[3] * a * a]
        else:
            b = _t_eff(s, self.ks[1], self.nodes[1][1])
            slopes = [coef[1] + 2 * coef[3] * a + coef[4] * b,
                      coef[2] + coef[4] * a + 2 * coef[5] * b]
        return max(float(np.max(np.abs(g))) for g in slopes) / T_EFF_SCALE_C


def node_candidates(n_nodes: int, grid: tuple[float, ...] = TAU_GRID_S,
                    leads: tuple[float, ...] = LEAD_GRID_S) -> list[NodeCandidate]:
    """Every structure with `n_nodes` effective nodes over the (tau, lead) grid."""
    def weights(k: int) -> list[float]:
        return sorted({node_weight(lead, grid[k - 1]) for lead in leads})

    out: list[NodeCandidate] = []
    for ks in itertools.combinations(range(1, len(grid) + 1), n_nodes):
        for ws in itertools.product(*(weights(k) for k in ks)):
            out.append(NodeCandidate(tuple((grid[k - 1], w) for k, w in zip(ks, ws, strict=True)),
                                     ks))
    return out


@dataclass
class CandidateFit:
    cand: NodeCandidate
    coef: np.ndarray
    sse: float  # sum of squared residuals over the fitted rows
    plausible: bool  # no node sensitivity above MAX_NODE_SLOPE_PPM_PER_C on those rows


def fit_candidates(candidates: list[NodeCandidate], rows: np.ndarray, y: np.ndarray
                   ) -> list[CandidateFit]:
    """Every candidate fitted by least squares to the grid front end's `rows` and targets."""
    out: list[CandidateFit] = []
    for cand in candidates:
        x = cand.design(rows)
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        out.append(CandidateFit(cand, coef, float(np.sum((x @ coef - y) ** 2)),
                                cand.max_node_slope(coef, rows) <= MAX_NODE_SLOPE_PPM_PER_C))
    return out


def _profile(logs: list, fe: FrontEnd, latitude_deg: float | None,
             candidates: list[NodeCandidate], grid: tuple[float, ...]
             ) -> tuple[NodeCandidate, float]:
    """Profile likelihood over the grid: every candidate (all of one family have the same
    number of coefficients) fitted by least squares to every step of the logs, the one with
    the smallest residual (RMS per model step, ppm) kept, among the physically plausible
    ones (no node sensitivity above MAX_NODE_SLOPE_PPM_PER_C on the data; if none is, among
    all).

    The whole logs, not a held-out chunk: the middle of a ramp is its steady part, where
    the lag structures differ least, so a held-out middle chunk picks structures that fit
    it by chance (benchmarks/probes/README.md, "The default model's structure")."""
    data, y = grid_data(logs, fe, grid, latitude_deg)
    fits = fit_candidates(candidates, measured_rows(data), y)
    pool = [f for f in fits if f.plausible] or fits
    best = min(pool, key=lambda f: f.sse)  # the first of equals, in candidate order
    return best.cand, math.sqrt(best.sse / y.size)


def profile_effective_node(logs: list, fe: FrontEnd, latitude_deg: float | None = None,
                           grid: tuple[float, ...] = TAU_GRID_S,
                           leads: tuple[float, ...] = LEAD_GRID_S
                           ) -> tuple[tuple[float, float], float]:
    """The effective sensing temperature T_eff = w T + (1 - w) lag(T, tau) that best explains
    the SF error: (tau, w) profiled over a grid, with a cubic in T_eff fitted by least squares
    inside (see `_profile`). Returns ((tau_s, w), in-sample RMS per model step in ppm).

    One effective node is what a single ramp rate can identify: on a constant ramp every lag
    temperature is T minus a constant, so freer models (several lags, their squares and
    products) fit the training run as well and extrapolate wildly to another rate
    (`fogsf.training.interval.transfer` measures how wildly).
    """
    best, score = _profile(logs, fe, latitude_deg,
                           node_candidates(1, grid, leads), grid)
    return best.nodes[0], score


def profile_two_nodes(logs: list, fe: FrontEnd, latitude_deg: float | None = None,
                      grid: tuple[float, ...] = TAU_GRID_S,
                      leads: tuple[float, ...] = LEAD_GRID_S
                      ) -> tuple[list[tuple[float, float]], float]:
    """Two effective nodes [(tau_1, w_1), (tau_2, w_2)] (tau_1 < tau_2) with a quadratic form
    of them, profiled like `profile_effective_node`. Identifiable only from logs at two or
    more ramp rates: on one constant ramp the two nodes are collinear."""
    best, score = _profile(logs, fe, latitude_deg,
                           node_candidates(2, grid, leads), grid)
    return list(best.nodes), score
