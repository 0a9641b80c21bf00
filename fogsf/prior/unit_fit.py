"""One unit's physics-node fit, and its step series: what the design's prior is made of.

A unit's training logs at the model rate are a step series (`StepSeries`: the board
temperature's block means minus 20 C per log, the measured SF target per step, ppm). At a
node count K the unit's parameters are theta = [log tau_1..K (ascending), intercept, the
linear, quadratic-with-cross-terms and cube coefficients of `models.structures.physics_nodes`, the
cubes of T and of every node] (the law on z = [T, node_1..K] / 50 C, ppm: each part's law a
cubic of its own temperature; with the cube of T only, a slow node's cube is carried by T's
on the fleet's programs and missed on a run whose slow nodes see another range, as a 2 h
loop's do). `fit_unit` finds them by variable projection (as
`fogsf train --structure physics` does, optionally started from given time constants: the
design's, so every unit's nodes are the same nodes), with their estimation covariance
sigma^2 (J^T J)^-1, J the Jacobian of the model in theta. sigma2 is the residual variance
times the residuals' correlation over WINDOW_S windows (model steps are not
independent: a structure's misfit is slow) for the weight of the unit's data, the residual
variance alone for the estimation covariance (the misfit of the design's structure is
common to its units: it moves every unit's fit alike, not one unit's).

A design may carry a hysteresis term (`Play`, chosen on the fleet by `prior.choose_play`):
one more column in the law, the play of T or of one of the law's nodes, its coefficient
after the nodes' linear ones (`play_index`); every function here takes it as `play` (None:
the law without it).
"""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import MODEL_STEP_S, front_end_for, prepare
from fogsf.models.structures.hysteresis import HystTerm, column, ridge_fit_free
from fogsf.models.structures.node_fit import discrete_lag, lag_alpha, ridge_fit, varpro
from fogsf.models.structures.physics_nodes import (
    NODE_LAMBDA,
    TAU_MAX_S,
    TAU_MIN_S,
    NodeTemperatures,
    identify_taus,
    node_design,
)

WINDOW_S = 100.0  # the residuals' correlation is measured over windows this long


@dataclass
class StepSeries:
    """A unit's training logs at the model rate (measured steps only in `y` and `rows`)."""

    t_rel: list[np.ndarray]  # per log: block means of T minus 20 C, every step
    y: np.ndarray  # measured steps' SF target, ppm, stacked over the logs
    rows: np.ndarray  # index of the measured steps in the stacked steps
    step_s: float

    @property
    def nodes(self) -> NodeTemperatures:
        return NodeTemperatures(self.t_rel, self.step_s)

    @property
    def hours(self) -> float:
        return sum(t.size for t in self.t_rel) * self.step_s / 3600.0

    def as_dict(self) -> dict:
        """JSON-able: float32 arrays in base64 (a 12 h program at 5 s is about 70 kB)."""
        return {"step_s": self.step_s,
                "t_rel": [_pack(t) for t in self.t_rel],
                "y": _pack(self.y), "rows": _pack(self.rows.astype(np.float32))}

    @classmethod
    def from_dict(cls, d: dict) -> StepSeries:
        return cls([_unpack(t) for t in d["t_rel"]], _unpack(d["y"]),
                   _unpack(d["rows"]).astype(np.int64), float(d["step_s"]))


def _pack(a: np.ndarray) -> str:
    return base64.b64encode(np.asarray(a, dtype="<f4").tobytes()).decode("ascii")


def _unpack(s: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(s), dtype="<f4").astype(np.float64)


def step_series(logs: list[ChamberLog], step_s: float = MODEL_STEP_S,
                latitude_deg: float | None = None) -> StepSeries:
    fe = front_end_for(logs, step_s, ())
    t_rel, ys, rows = [], [], []
    base = 0
    for lg in logs:
        d = prepare(lg, fe, None, latitude_deg)
        t_rel.append(d.s[:, 0].astype(np.float64))
        ys.append(d.target_ppm[d.measured])
        rows.append(np.flatnonzero(d.measured) + base)
        base += d.n_steps
    return StepSeries(t_rel, np.concatenate(ys), np.concatenate(rows), fe.step_s)


@dataclass(frozen=True)
class Play:
    """The design's hysteresis term: the play, `width_c` wide, of T (`node` 0) or of the
    law's node `node` (its lag at the fit's own time constant, the nodes ascending), in the
    law linearly as (play(x) - x) / 50 C (`models.structures.hysteresis`; the firmware's front end
    runs it)."""

    node: int
    width_c: float

    def term(self, taus_s: np.ndarray) -> HystTerm:
        """The term at a fit's time constants (what the exported model's front end runs)."""
        tau = 0.0 if self.node == 0 else float(np.sort(taus_s)[self.node - 1])
        return HystTerm(tau, tau, 1.0, float(self.width_c))

    def source(self, series: StepSeries, taus_s: np.ndarray) -> list[np.ndarray]:
        """The temperature the play reads (C, relative), one array per log of `series`."""
        tau = self.term(taus_s).tau_a_s
        return list(series.t_rel) if tau == 0 else [
            discrete_lag(t, lag_alpha(tau, series.step_s)) for t in series.t_rel]

    def column(self, series: StepSeries, taus_s: np.ndarray) -> np.ndarray:
        """h over every stacked step of `series`."""
        return column(self.source(series, taus_s), self.width_c)

    def as_dict(self, taus_s: np.ndarray | None = None) -> dict:
        d: dict = {"node": self.node, "width_c": self.width_c}
        if taus_s is not None:
            d["form"] = self.term(taus_s).describe()
        return d


def play_index(k: int) -> int:
    """The play's coefficient in theta = [log taus (k), intercept, T, nodes (k), h, ...]."""
    return 2 * k + 2


def n_coef(k: int) -> int:
    """Coefficients of the K-node law: intercept, 1 + K linear, the pairs, the cubes of T
    and the K nodes."""
    f = k + 1
    return 1 + f + f * (f + 1) // 2 + f


def design_matrix(series: StepSeries, taus_s: np.ndarray, play: Play | None = None,
                  node_cubes: bool = True) -> np.ndarray:
    """[1, node_design(z)] on the measured steps, ppm per unit coefficient (z = [T, nodes,
    the play's h] with `play`: h enters linearly, its column k + 2); `node_cubes` False: the
    law without the nodes' cubes (the play is chosen against it, `prior.choose_play`)."""
    taus = np.asarray(taus_s, dtype=np.float64)
    z = series.nodes.z(taus)
    if play is not None:
        z = np.column_stack([z, play.column(series, taus)])
    x = node_design(z[series.rows], tuple(float(t) for t in taus), cube_nodes=node_cubes)
    return np.hstack([np.ones((x.shape[0], 1)), x])


def window_means(x: np.ndarray, step_s: float) -> tuple[np.ndarray, int]:
    """The means of `x` (one value a model step of `step_s`) over whole WINDOW_S windows,
    and the steps per window (a trailing part window left out)."""
    w = max(1, int(round(WINDOW_S / step_s)))
    n = x.size // w
    return np.asarray(x[:n * w], dtype=np.float64).reshape(n, w).mean(axis=1), w


def correlation_factor(resid: np.ndarray, step_s: float) -> float:
    """How much the residuals' slow part inflates a white-noise variance: the variance of
    WINDOW_S means times the steps per window over the variance (>= 1)."""
    means, w = window_means(resid, step_s)
    if means.size < 4:
        return 1.0
    v = float(np.var(resid))
    return max(1.0, w * float(np.var(means)) / v) if v > 0 else 1.0


@dataclass
class UnitFit:
    """theta = [log taus, coefficients]; cov its estimation covariance; sigma2 the residual
    variance per step (ppm^2) times the correlation factor."""

    k: int
    theta: np.ndarray
    cov: np.ndarray
    sigma2: float
    sse: float
    n: int

    @property
    def taus_s(self) -> np.ndarray:
        return np.exp(self.theta[:self.k])

    def as_dict(self) -> dict:
        return {"k": self.k, "theta": self.theta.tolist(), "cov": self.cov.tolist(),
                "sigma2": self.sigma2, "sse": self.sse, "n": self.n}

    @classmethod
    def from_dict(cls, d: dict) -> UnitFit:
        return cls(int(d["k"]), np.asarray(d["theta"], dtype=np.float64),
                   np.asarray(d["cov"], dtype=np.float64), float(d["sigma2"]),
                   float(d["sse"]), int(d["n"]))


def predict(series: StepSeries, theta: np.ndarray, k: int, play: Play | None = None
            ) -> np.ndarray:
    return design_matrix(series, np.exp(theta[:k]), play) @ theta[k:]


def jacobian(series: StepSeries, theta: np.ndarray, k: int, h: float = 1e-4,
             play: Play | None = None) -> np.ndarray:
    """d prediction / d theta on the measured steps (forward differences in log tau)."""
    x = design_matrix(series, np.exp(theta[:k]), play)
    base = x @ theta[k:]
    cols = []
    for j in range(k):
        t = theta.copy()
        t[j] += h
        cols.append((predict(series, t, k, play) - base) / h)
    return np.column_stack([*cols, x])


def _bounds(k: int) -> tuple[np.ndarray, np.ndarray]:
    return np.full(k, math.log(TAU_MIN_S)), np.full(k, math.log(TAU_MAX_S))


def fit_taus(series: StepSeries, k: int, start_taus_s: np.ndarray, play: Play | None = None,
             node_cubes: bool = True) -> np.ndarray:
    """The K nodes' time constants (ascending) by variable projection from `start_taus_s`
    (`node_cubes` False: for the law without the nodes' cubes, `design_matrix`)."""
    lo, hi = _bounds(k)

    def design(log_tau: np.ndarray) -> np.ndarray:
        return design_matrix(series, np.sort(np.exp(log_tau)), play, node_cubes)[:, 1:]

    vp = varpro(design, series.y, np.log(np.asarray(start_taus_s, dtype=np.float64)),
                lo, hi, NODE_LAMBDA)
    return np.sort(np.exp(vp.theta))


def fit_unit(series: StepSeries, k: int, start_taus_s: np.ndarray | None = None,
             play: Play | None = None) -> UnitFit:
    """The K-node physics fit by variable projection (from `start_taus_s`, or from the
    grid start `identify_taus` uses: without `start_taus_s` and `play` the time constants
    are the grid start's, refined on the law without the nodes' cubes), with its estimation
    covariance; with `play`, the law holds its column too (unpenalised), the time constants
    fitted with it."""
    grid = start_taus_s is None
    if grid:
        start_taus_s = np.asarray(identify_taus(series.nodes, _full(series), k, series.rows),
                                  dtype=np.float64)
    if grid and play is None:  # the grid's time constants are the fit's
        taus = np.sort(np.asarray(start_taus_s, dtype=np.float64))
    else:
        taus = fit_taus(series, k, np.asarray(start_taus_s, dtype=np.float64), play)
    return fit_at(series, k, taus, play)


def fit_at(series: StepSeries, k: int, taus_s: np.ndarray, play: Play | None = None
           ) -> UnitFit:
    """The law's coefficients, their estimation covariance and the noise at given time
    constants (no search): `fit_unit`'s last step, and a fit rebuilt where its time
    constants are known."""
    x = design_matrix(series, taus_s, play)
    f = ridge_fit(x[:, 1:], series.y, NODE_LAMBDA) if play is None else \
        ridge_fit_free(x[:, 1:], series.y, NODE_LAMBDA, [play_index(k) - k - 1])
    theta = np.concatenate([np.log(taus_s), [f.intercept], f.coef])
    resid = series.y - x @ theta[k:]
    sse = float(resid @ resid)
    n = series.y.size
    white = sse / max(1, n - theta.size)
    return UnitFit(k, theta, estimation_cov(series, theta, k, white, play),
                   white * correlation_factor(resid, series.step_s), sse, n)


def plain_refit(series: StepSeries, theta: np.ndarray, k: int, play: Play | None = None
                ) -> np.ndarray:
    """theta with its coefficients refitted by least squares without the ridge at its time
    constants: the unit's response as its data say it (the ridge shrinks collinear nodes
    toward each other, right for one unit's law, a bias shared by every unit's)."""
    x = design_matrix(series, np.exp(theta[:k]), play)
    coef = np.linalg.lstsq(x, series.y, rcond=None)[0]
    return np.concatenate([theta[:k], coef])


def estimation_cov(series: StepSeries, theta: np.ndarray, k: int, white: float,
                   play: Play | None = None) -> np.ndarray:
    """The ridge fit's estimation covariance, white (J^T J + P)^-1 J^T J (J^T J + P)^-1, P
    the ridge penalty on the law's coefficients (intercept and time constants free): the
    penalty pins the collinear nodes' directions, and the units' fits scatter as this."""
    jac = jacobian(series, theta, k, play=play)
    a = jac.T @ jac
    penalised = np.arange(k + 1, a.shape[0])
    if play is not None:  # the play's coefficient is free, as in the fit
        penalised = penalised[penalised != play_index(k)]
    x = jac[:, penalised]
    xc = x - x.mean(axis=0)
    pen = NODE_LAMBDA * float(np.trace(xc.T @ xc)) / max(1, x.shape[1])
    p = np.full(a.shape[0], 1e-9 * float(np.mean(np.diag(a))))
    p[penalised] = pen
    inv = np.linalg.inv(a + np.diag(p))
    cov = white * inv @ a @ inv
    return 0.5 * (cov + cov.T)


def all_steps(series: StepSeries) -> StepSeries:
    """`series` with every step as a row, the target zero: to predict on."""
    n = sum(t.size for t in series.t_rel)
    return StepSeries(series.t_rel, np.zeros(n), np.arange(n), series.step_s)


def _full(series: StepSeries) -> np.ndarray:
    """The target over every stacked step (zeros where not measured: `rows` selects)."""
    y = np.zeros(sum(t.size for t in series.t_rel))
    y[series.rows] = series.y
    return y
