"""Weighted linear least squares profiled over grids of nonlinear parameters.

A model is the base columns (which depend on the base time constants) plus, optionally, one
candidate column (which may depend on its own grid parameter). Every admissible combination
of grid values gives one design matrix; all are stacked into one (G, n, p) array and solved
at once (batched normal equations on scaled columns, a whisker of ridge for columns that
are collinear on a given set of logs; `models.structures.node_fit`, the fit the trainer's
physics-node model uses too), and the combination with the least weighted squared
error wins. The same stack serves every cross-validation fold (only the rows change).
"""

from __future__ import annotations

from typing import cast

import numpy as np

from fogsf.diagnose import design
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects.catalogue import Candidate, GridValue
from fogsf.models.structures.node_fit import PROFILE_RIDGE, ProfileFit, profile_solve

KEEP_NUMBERS = 1 << 23  # a stack up to this many numbers (64 MB) is kept whole
RIDGE = PROFILE_RIDGE  # on scaled columns: keeps nearly collinear node terms from cancelling


Combo = tuple[tuple[float, float], GridValue]


class Stack:
    """Design matrices of one model for every admissible grid combination: x (G, n, p).
    Long logs have many windows, and every candidate keeps its model: a stack built from
    runs holds x only while it is small (KEEP_NUMBERS), else `x` stacks the combinations
    asked for (x[g], x[a:b], x[mask]) from the runs' cached window columns, the same bits;
    `release` drops a kept x."""

    def __init__(self, combos: list[Combo], x: np.ndarray | None, names: list[str],
                 candidate: Candidate | None, ctxs: list[RunContext] | None = None) -> None:
        self.combos, self.names, self.candidate = combos, names, candidate
        self._x, self._ctxs = x, ctxs
        self._designs: Designs | None = None

    @property
    def x(self) -> np.ndarray | Designs:
        if self._x is not None:
            return self._x
        assert self._ctxs is not None
        if self._designs is None:
            self._designs = Designs(self._ctxs, self.candidate, self.combos)
        if self._designs.numbers <= KEEP_NUMBERS:
            self._x = self._designs[:]
            return self._x
        return self._designs

    def release(self) -> None:
        if self._ctxs is not None:
            self._x = None


class Designs:
    """The stacked designs of `combos`, made when indexed (a combination, a slice of them
    or a mask over them); shape (G, n, p) as the array would have."""

    def __init__(self, ctxs: list[RunContext], cand: Candidate | None, combos: list[Combo]
                 ) -> None:
        self.ctxs, self.cand, self.combos = ctxs, cand, combos
        first = _stacked(ctxs, cand, combos[:1])  # the columns one combination has
        self.shape = (len(combos), first.shape[1], first.shape[2])
        self.numbers = self.shape[0] * self.shape[1] * self.shape[2]

    def __getitem__(self, at: int | slice | np.ndarray) -> np.ndarray:
        if isinstance(at, (int, np.integer)):
            return self._made([self.combos[int(at)]])[0]
        if isinstance(at, slice):
            return self._made(self.combos[at])
        idx = np.flatnonzero(at) if np.asarray(at).dtype == bool else np.asarray(at)
        return self._made([self.combos[int(i)] for i in idx])

    def _made(self, combos: list[Combo]) -> np.ndarray:
        if not combos:
            return np.empty((0, *self.shape[1:]))
        x = _stacked(self.ctxs, self.cand, combos)
        assert x.shape[1:] == self.shape[1:], (x.shape, self.shape)
        return x


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
    names = design.base_names(any_on, ctxs[0].bias_on)
    if cand is not None:
        names = names + cand.names()
    return Stack(combos, None, names, cand, ctxs)


def _stacked(ctxs: list[RunContext], cand: Candidate | None, combos: list[Combo]
             ) -> np.ndarray:
    any_on = any(c.power_on for c in ctxs)
    mats = []
    for bt, g in combos:
        per_run = []
        for ctx in ctxs:
            cols = design.base_columns(ctx, bt, any_on)
            if cand is not None:
                cols = np.column_stack([cols, cand.column(ctx, bt, g)])
            per_run.append(cols)
        mats.append(np.vstack(per_run))
    return np.stack(mats)


Fit = ProfileFit  # one profile over the grid (the shared physics fit's record)


def solve(stack: Stack, y: np.ndarray, w: np.ndarray, rows: np.ndarray) -> Fit:
    """Fit on `rows` (index array) with weights w (1/sigma^2): the shared physics fit's
    profile over every stacked combination (`models.structures.node_fit.profile_solve`)."""
    # Designs are indexed as the stacked array is
    return profile_solve(cast(np.ndarray, stack.x), y, w, rows, RIDGE)


def predict(stack: Stack, fit: Fit, rows: np.ndarray | None = None) -> np.ndarray:
    x = stack.x[fit.index]
    if rows is not None:
        x = x[rows]
    return x @ fit.beta
