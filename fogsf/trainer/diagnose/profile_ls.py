"""Weighted linear least squares profiled over grids of nonlinear parameters.

A model is the base columns (which depend on the base time constants) plus, optionally, one
candidate column (which may depend on its own grid parameter). Every admissible combination
of grid values gives one design matrix; all are stacked into one (G, n, p) array and solved
at once (batched normal equations on scaled columns, a whisker of ridge for columns that
are collinear on a given set of logs; `models.node_fit`, the fit the trainer's physics-node
model uses too), and the combination with the least weighted squared
error wins. The same stack serves every cross-validation fold (only the rows change).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.trainer.diagnose import design
from fogsf.trainer.diagnose.catalogue import Candidate, GridValue
from fogsf.trainer.diagnose.design import RunContext
from fogsf.trainer.models.node_fit import PROFILE_RIDGE, ProfileFit, profile_solve

RIDGE = PROFILE_RIDGE  # on scaled columns: keeps nearly collinear node terms from cancelling


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


Fit = ProfileFit  # one profile over the grid (the shared physics fit's record)


def solve(stack: Stack, y: np.ndarray, w: np.ndarray, rows: np.ndarray) -> Fit:
    """Fit on `rows` (index array) with weights w (1/sigma^2): the shared physics fit's
    profile over every stacked combination (`models.node_fit.profile_solve`)."""
    return profile_solve(stack.x, y, w, rows, RIDGE)


def predict(stack: Stack, fit: Fit, rows: np.ndarray | None = None) -> np.ndarray:
    x = stack.x[fit.index]
    if rows is not None:
        x = x[rows]
    return x @ fit.beta
