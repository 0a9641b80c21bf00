"""Physics nodes: the gyro's own structure as a compensation model.

Each internal temperature of a gyro is a linear filter of the board temperature T (a
thermal network), and its SF error a polynomial of a few of them. The model: N nodes, each a
first-order lag of T with its own time constant (a star: every node behind the board), and
the SF error a quadratic of T and the nodes with every cross term (a parallel Wiener model:
a factor of the SF law that depends on a weighted mean of two parts' temperatures gives
their product), plus a cube of T (the static law's curvature). The time constants are
identified by variable projection (`models.structures.node_fit.varpro`, the fit diagnose profiles
with), the coefficients by ridge regression with a small penalty: node temperatures are
nearly collinear, and without it their quadratic form fits with huge cancelling
coefficients that extrapolate wildly.

A chain (a node behind another node) is a lag of a lag: the firmware's front end filters T
only, so it would need an extension of the stream contract; a star of lags with T itself
among the features carries a lead-lag node (w T + (1 - w) lag(T, tau)) exactly.

In the firmware contract the model is the polynomial head over 1 + N features (T and the N
lags, in one physical unit, (T - 20 C) / 50 C): linear terms in skip_w, the quadratic with
its cross terms in the full quad_w [F, F] (upper triangle), the cube of T in cube_w (and,
in the fleet's structure, the nodes' cubes: `node_design(cube_nodes=True)`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from fogsf.models.features import PHYSICAL_SCALE_C, FeatureSpec
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import RidgeFit, discrete_lag, lag_alpha, ridge_fit, varpro

MAX_NODES = 3
# The ridge penalty of the node model's coefficients (a multiple of the centred design's mean
# diagonal): small, only to keep collinear node temperatures from cancelling. Chosen on
# development gyros (docs/decisions.md).
NODE_LAMBDA = 1e-4
TAU_MIN_S, TAU_MAX_S = 20.0, 14400.0  # the time constants' search range
START_GRID_S = TAU_GRID_S  # the grid the variable projection starts from


def node_spec(taus_s: tuple[float, ...]) -> FeatureSpec:
    """Features T and lag(T, tau) for each node: the rows of an identity."""
    k = len(taus_s)
    rows = tuple(tuple(1.0 if j == i else 0.0 for j in range(k + 1)) for i in range(k + 1))
    names = ("T",) + tuple(f"node(T,{t:.0f}s)" for t in taus_s)
    return FeatureSpec(tuple(float(t) for t in taus_s), rows, names)


def pairs(f: int) -> list[tuple[int, int]]:
    return [(i, j) for i in range(f) for j in range(i, f)]


CUBE_T = True  # the cube of T in the law (the static law's curvature)


# Nodes slower than this enter linearly only (no squares, no cross terms), as in the lag
# bank (`lag_bank.CURVED_MAX_TAU_S`): a down-ramp after up-ramp training takes slow node
# temperatures far beyond their training range, where their curvature extrapolates worst.
# None: every node curved.
CURVED_MAX_TAU_S: float | None = None


def curved(taus_s: tuple[float, ...] | np.ndarray) -> list[int]:
    """The features (0 = T, then the nodes) that enter the products."""
    return [0] + [1 + k for k, t in enumerate(taus_s)
                  if CURVED_MAX_TAU_S is None or t <= CURVED_MAX_TAU_S]


def product_pairs(taus_s: tuple[float, ...] | np.ndarray) -> list[tuple[int, int]]:
    c = curved(taus_s)
    return [(i, j) for a, i in enumerate(c) for j in c[a:]]


def node_design(z: np.ndarray, taus_s: tuple[float, ...] | np.ndarray | None = None,
                cube_t: bool | None = None, cube_nodes: bool = False) -> np.ndarray:
    """Columns z, the products z_i z_j (i <= j) of T and the curved nodes (every node when
    taus_s is None), then z_0^3 (z_0 = T) with `cube_t`, then the cubes of the curved nodes
    with `cube_nodes` (each part's law a cubic of its own temperature: the fleet's
    structure, `prior.unit_fit`)."""
    x = np.asarray(z, dtype=np.float64)
    pr = pairs(x.shape[1]) if taus_s is None else product_pairs(taus_s)
    cols = [x] + [(x[:, i] * x[:, j])[:, None] for i, j in pr]
    if CUBE_T if cube_t is None else cube_t:
        cols.append((x[:, 0] ** 3)[:, None])
    if cube_nodes:
        c = list(range(x.shape[1])) if taus_s is None else curved(taus_s)
        cols += [(x[:, i] ** 3)[:, None] for i in c[1:]]
    return np.hstack(cols)


@dataclass
class NodeFit:
    """A fitted node model in normalised units: y = intercept + lin.z + z^T quad z +
    cube.z^3, z = [T, node_1, ..., node_N] / 50 C (y the normalised target)."""

    taus_s: tuple[float, ...]
    intercept: float
    lin: np.ndarray  # [F]
    quad: np.ndarray  # [F, F], upper triangle
    cube: np.ndarray  # [F]
    lam: float
    dof: float

    def predict(self, z: np.ndarray) -> np.ndarray:
        x = np.asarray(z, dtype=np.float64)
        return (self.intercept + x @ self.lin + np.einsum("ni,ij,nj->n", x, self.quad, x)
                + (x * x * x) @ self.cube)


def head_from_ridge(f: RidgeFit, n_features: int, taus_s: tuple[float, ...],
                    lam: float, cube_nodes: bool = False) -> NodeFit:
    """The head of a ridge fit on `node_design(z, taus_s, cube_nodes=cube_nodes)`."""
    lin = f.coef[:n_features]
    quad = np.zeros((n_features, n_features))
    pr = product_pairs(taus_s)
    for k, (i, j) in enumerate(pr):
        quad[i, j] = f.coef[n_features + k]
    cube = np.zeros(n_features)
    if f.coef.size > n_features + len(pr):
        cube[0] = f.coef[n_features + len(pr)]
    if cube_nodes:  # the curved nodes' cubes follow T's
        nodes = curved(taus_s)[1:]
        if f.coef.size != n_features + len(pr) + 1 + len(nodes):
            raise ValueError(f"{f.coef.size} coefficients: not a law with the nodes' cubes")
        cube[nodes] = f.coef[n_features + len(pr) + 1:]
    return NodeFit(taus_s, f.intercept, lin, quad, cube, lam, f.dof)


def fit_coefficients(z: np.ndarray, y: np.ndarray, taus_s: tuple[float, ...],
                     lam: float | None = None) -> NodeFit:
    """The coefficients for fixed time constants: ridge on node_design(z)."""
    lam = NODE_LAMBDA if lam is None else lam
    return head_from_ridge(ridge_fit(node_design(z, taus_s), y, lam), z.shape[1], taus_s,
                           lam)


class NodeTemperatures:
    """Node temperatures (normalised) at any time constant from the block means of T per
    model step, one array per log (lags run within each log, from its first step), cached."""

    def __init__(self, t_rel: list[np.ndarray], step_s: float) -> None:
        self.t_rel = [np.asarray(t, dtype=np.float64) for t in t_rel]  # Tm - t_ref per step
        self.step_s = step_s
        self._cache: dict[float, np.ndarray] = {}

    def lag(self, tau_s: float) -> np.ndarray:
        key = round(float(tau_s), 9)
        if key not in self._cache:
            a = lag_alpha(tau_s, self.step_s)
            self._cache[key] = np.concatenate([discrete_lag(t, a) for t in self.t_rel]) \
                / PHYSICAL_SCALE_C
            if len(self._cache) > 256:
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]

    def z(self, taus_s: tuple[float, ...] | np.ndarray) -> np.ndarray:
        """[T, node_1, ...], normalised."""
        t = np.concatenate(self.t_rel) / PHYSICAL_SCALE_C
        return np.column_stack([t] + [self.lag(float(tau)) for tau in taus_s])


def identify_taus(nodes: NodeTemperatures, y: np.ndarray, n_nodes: int,
                  rows: np.ndarray | None = None, lam: float | None = None
                  ) -> tuple[float, ...]:
    """The nodes' time constants (ascending): the best combination of START_GRID_S by the
    profile of the ridge fit, refined by variable projection on log tau. `rows` (a mask or
    index over the stacked steps): the rows fitted (default all)."""
    lam = NODE_LAMBDA if lam is None else lam
    sel = np.arange(y.size) if rows is None else np.asarray(rows)
    ys = np.asarray(y, dtype=np.float64)[sel]

    def design(log_tau: np.ndarray) -> np.ndarray:
        taus = np.exp(log_tau)
        return node_design(nodes.z(taus)[sel], taus)

    best: tuple[float, tuple[float, ...]] | None = None
    for combo in itertools.combinations(START_GRID_S, n_nodes):
        sse = ridge_fit(design(np.log(combo)), ys, lam).sse
        if best is None or sse < best[0]:
            best = (sse, combo)
    assert best is not None
    lo = np.full(n_nodes, math.log(TAU_MIN_S))
    hi = np.full(n_nodes, math.log(TAU_MAX_S))
    vp = varpro(design, ys, np.log(best[1]), lo, hi, lam)
    return tuple(sorted(float(t) for t in np.exp(vp.theta)))
