"""Held-out residuals: every window predicted by a model fitted without it.

Each run is cut into contiguous blocks of a few windows; blocks are dealt round-robin to
`FOLDS` folds and one fold is left out at a time, so a held-out block is predicted by a fit
that never saw it, while its temperatures lie inside the range the fit saw (leaving out the
end of a monotone ramp would score extrapolation, not the model). Or whole runs are left
out (`--cv runs`). Residuals inside a block share slow model error, so significance is
judged per block (see `stats.sign_flip_p`), never per window.
"""

from __future__ import annotations

import numpy as np

from fogsf.diagnose import profile_ls
from fogsf.diagnose.profile_ls import Stack
from fogsf.errors import UserError

BLOCK_WINDOWS = 3
FOLDS = 8


def block_ids(run_lengths: list[int], block_windows: int = BLOCK_WINDOWS) -> np.ndarray:
    """A block id per window (windows of all runs concatenated in order)."""
    ids = []
    next_id = 0
    for n in run_lengths:
        k = max(1, n // block_windows)
        edges = np.linspace(0, n, k + 1).round().astype(int)
        per = np.empty(n, dtype=int)
        for j in range(k):
            per[edges[j]:edges[j + 1]] = next_id + j
        ids.append(per)
        next_id += k
    return np.concatenate(ids)


def fold_ids(blocks: np.ndarray, run_ids: np.ndarray, mode: str = "blocks",
             folds: int = FOLDS) -> np.ndarray:
    """A fold id per window: blocks dealt round-robin, or one fold per run."""
    if mode == "runs":
        if np.unique(run_ids).shape[0] < 2:
            raise UserError("--cv runs needs at least two logs (leave one run out)")
        return run_ids.copy()
    if mode != "blocks":
        raise UserError(f"unknown cross-validation mode {mode!r} (blocks or runs)")
    return blocks % folds


def heldout_residuals(stack: Stack, y: np.ndarray, w: np.ndarray, folds: np.ndarray
                      ) -> np.ndarray:
    """y minus the prediction of a fit on all other folds, per window."""
    e = np.empty_like(y)
    all_rows = np.arange(y.shape[0])
    for f in np.unique(folds):
        test = folds == f
        fit = profile_ls.solve(stack, y, w, all_rows[~test])
        e[test] = y[test] - profile_ls.predict(stack, fit, all_rows[test])
    return e
