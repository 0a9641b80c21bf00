"""Linear least-squares models: the industry's polynomials and the lag-temperature profile.

- `poly`: SF error as a polynomial in the board temperature.
- `polyrate`: polynomial in T plus a filtered dT/dt and its products with T (the industry
  standard for hysteresis).
- `profile_effective_node`: identifies the effective sensing temperature
  T_eff = w T + (1 - w) lag(T, tau) (the physics: the sensing parts lag the board) by
  profiling a grid of (tau, w), with least squares inside, scored on the held-out part.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from trainer.features import SeqData, prepare
from trainer.fit import validation_rms
from trainer.stream import FrontEnd, filter_alpha


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


def node_weight(lead_s: float, tau_s: float) -> float:
    """w in T_eff = w T + (1 - w) lag(T, tau) for a node with time constant tau behind a
    common driver that the board follows with time constant lead_s: the node's transfer from
    the board is (1 + lead s) / (1 + tau s) = w + (1 - w) / (1 + tau s), w = lead / tau."""
    return min(lead_s / tau_s, 1.0)


def _t_eff(s: np.ndarray, k: int, w: float) -> np.ndarray:
    return (w * s[:, 0].astype(np.float64) + (1.0 - w) * s[:, k].astype(np.float64)) / 50.0


def _node_design(s: np.ndarray, k: int, w: float, degree: int = NODE_DEGREE) -> np.ndarray:
    t_eff = _t_eff(s, k, w)
    return np.column_stack([t_eff**p for p in range(degree + 1)])


def _two_node_design(s: np.ndarray, k1: int, w1: float, k2: int, w2: float) -> np.ndarray:
    """The SF as a quadratic form of two nodes (the simulator's physics: each factor is a
    quadratic in a weighted mean of node temperatures)."""
    a, b = _t_eff(s, k1, w1), _t_eff(s, k2, w2)
    return np.column_stack([np.ones_like(a), a, b, a * a, a * b, b * b])


def _grid_data(logs: list, fe: FrontEnd, grid: tuple[float, ...],
               val_chunk: tuple[float, float], latitude_deg: float | None
               ) -> tuple[list[SeqData], np.ndarray]:
    """Every log through a front end with one lag filter per grid time constant, and the
    training targets stacked."""
    full = FrontEnd(fe.t_ref_c, fe.t_min_c, fe.t_max_c, fe.decimation, fe.stuck_samples,
                    filter_alpha(list(grid), fe.decimation))
    data = [prepare(lg, full, val_chunk, latitude_deg) for lg in logs]
    return data, np.concatenate([d.target_ppm[d.train_mask] for d in data])


def profile_effective_node(logs: list, fe: FrontEnd, val_chunk: tuple[float, float],
                           latitude_deg: float | None = None,
                           grid: tuple[float, ...] = TAU_GRID_S,
                           leads: tuple[float, ...] = LEAD_GRID_S
                           ) -> tuple[tuple[float, float], float]:
    """The effective sensing temperature T_eff = w T + (1 - w) lag(T, tau) that best explains
    the SF error: (tau, w) profiled over a grid, with a cubic in T_eff fitted by least squares
    inside, scored by the held-out windowed RMS. Returns ((tau_s, w), score_ppm).

    One effective node is what a single ramp rate can identify: on a constant ramp every lag
    temperature is T minus a constant, so freer models (several lags, their squares and
    products) fit the training run as well and extrapolate wildly to another rate.
    """
    data, y = _grid_data(logs, fe, grid, val_chunk, latitude_deg)
    best, best_score = (grid[0], 0.0), math.inf
    for k, tau in enumerate(grid, start=1):
        for w in sorted({node_weight(lead, tau) for lead in leads}):
            x = np.concatenate([_node_design(d.s[d.train_mask], k, w) for d in data])
            coef, *_ = np.linalg.lstsq(x, y, rcond=None)
            score = validation_rms([_node_design(d.s, k, w) @ coef for d in data], data)
            if score < best_score:
                best, best_score = (tau, w), score
    return best, best_score


def profile_two_nodes(logs: list, fe: FrontEnd, val_chunk: tuple[float, float],
                      latitude_deg: float | None = None,
                      grid: tuple[float, ...] = TAU_GRID_S,
                      leads: tuple[float, ...] = LEAD_GRID_S
                      ) -> tuple[list[tuple[float, float]], float]:
    """Two effective nodes [(tau_1, w_1), (tau_2, w_2)] (tau_1 < tau_2) with a quadratic form
    of them, profiled like `profile_effective_node`. Identifiable only from logs at two or
    more ramp rates: on one constant ramp the two nodes are collinear."""
    data, y = _grid_data(logs, fe, grid, val_chunk, latitude_deg)
    best: list[tuple[float, float]] = [(grid[0], 0.0), (grid[-1], 0.0)]
    best_score = math.inf
    for k1, k2 in itertools.combinations(range(1, len(grid) + 1), 2):
        for w1 in sorted({node_weight(lead, grid[k1 - 1]) for lead in leads}):
            for w2 in sorted({node_weight(lead, grid[k2 - 1]) for lead in leads}):
                x = np.concatenate([_two_node_design(d.s[d.train_mask], k1, w1, k2, w2)
                                    for d in data])
                coef, *_ = np.linalg.lstsq(x, y, rcond=None)
                score = validation_rms(
                    [_two_node_design(d.s, k1, w1, k2, w2) @ coef for d in data], data)
                if score < best_score:
                    best = [(grid[k1 - 1], w1), (grid[k2 - 1], w2)]
                    best_score = score
    return best, best_score
