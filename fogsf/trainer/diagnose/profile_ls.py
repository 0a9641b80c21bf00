"""Weighted linear least squares profiled over grids of nonlinear parameters.

A model is the base columns (which depend on the base time constants) plus, optionally, one
candidate column (which may depend on its own grid parameter). Every admissible combination
of grid values gives one design matrix; all are stacked into one (G, n, p) array and solved
at once (batched normal equations on scaled columns, a whisker of ridge for columns that
are collinear on a given set of logs), and the combination with the least weighted squared
error wins. The same stack serves every cross-validation fold (only the rows change).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.trainer.diagnose import design
from fogsf.trainer.diagnose.catalogue import Candidate, GridValue
from fogsf.trainer.diagnose.design import RunContext

RIDGE = 1e-5  # on scaled columns: keeps nearly collinear node terms from cancelling wildly


@dataclass
class Stack:
    """Design matrices of one model for every admissible grid combination."""

    combos: list[tuple[tuple[float, float], GridValue]]
    x: np.ndarray  # (G, n, p)
    names: list[str]
    candidate: Candidate | None


Combo = tuple[tuple[float, float], GridValue]


def build(ctxs: list[RunContext], cand: Candidate | None,
          combos: list[Combo] | None = None) -> Stack:
    """Stack the design matrices of base (+ candidate) over the admissible grid, or over
    the given (base taus, candidate parameter) combinations."""
    any_on = any(c.power_on for c in ctxs)
    if combos is None:
        combos = []
        for bt in design.base_grid():
            grid = cand.grid if cand is not None else (None,)
            for g in grid:
                if cand is None or cand.admissible(bt, g):
                    combos.append((bt, g))
    mats = []
    for bt, g in combos:
        per_run = []
        for ctx in ctxs:
            cols = design.base_columns(ctx, bt, any_on)
            if cand is not None:
                cols = np.column_stack([cols, cand.column(ctx, bt, g)])
            per_run.append(cols)
        mats.append(np.vstack(per_run))
    names = design.base_names(any_on, ctxs[0].bias_on)
    if cand is not None:
        names = names + cand.names()
    return Stack(combos, np.stack(mats), names, cand)


@dataclass
class Fit:
    index: int  # best combination
    beta: np.ndarray  # (p,) coefficients of the best combination
    sse: np.ndarray  # (G,) weighted SSE of every combination on the fitting rows
    cov: np.ndarray  # (p, p) coefficient covariance (unit weights = 1/sigma^2)


def solve(stack: Stack, y: np.ndarray, w: np.ndarray, rows: np.ndarray) -> Fit:
    """Fit on `rows` (index array) with weights w (1/sigma^2)."""
    x = stack.x[:, rows, :]
    sw = np.sqrt(w[rows])
    xw = x * sw[None, :, None]
    yw = y[rows] * sw
    scale = np.sqrt(np.mean(xw * xw, axis=1))  # (G, p)
    scale = np.where(scale > 0, scale, 1.0)  # an all-zero column (e.g. warmup, no power-on)
    xs = xw / scale[:, None, :]
    a = np.einsum("gnp,gnq->gpq", xs, xs)
    p = a.shape[-1]
    a = a + RIDGE * rows.shape[0] * np.eye(p)[None]
    rhs = np.einsum("gnp,n->gp", xs, yw)
    bs = np.linalg.solve(a, rhs[..., None])[..., 0]
    resid = yw[None, :] - np.einsum("gnp,gp->gn", xs, bs)
    sse = np.sum(resid * resid, axis=1)
    k = int(np.argmin(sse))
    beta = bs[k] / scale[k]
    cov = np.linalg.inv(a[k]) / np.outer(scale[k], scale[k])
    return Fit(k, beta, sse, cov)


def predict(stack: Stack, fit: Fit, rows: np.ndarray | None = None) -> np.ndarray:
    x = stack.x[fit.index]
    if rows is not None:
        x = x[rows]
    return x @ fit.beta
