"""The SF windows on model steps: per-sample series averaged over each step's samples
(`step_means`), the windows as step ranges (`step_windows`: a step belongs to the window
holding its middle sample) and the RMS of an error's window means over them (`windows_rms`):
what training validates on and the rate-transfer check measures."""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.measure.windows import sf_spans
from fogsf.logs.read import columns
from fogsf.logs.read.columns import is_lazy


def step_means(x: np.ndarray, decimation: int, mask: np.ndarray | None = None) -> np.ndarray:
    """Mean of a per-sample series over each model step's samples (the masked ones; NaN for a
    step with none). A column on disk is read a block of whole steps at a time (each step's
    mean is made from its own samples alone: the same bits)."""
    if is_lazy(x) or is_lazy(mask):
        size = max(1, columns.READ_SAMPLES // decimation) * decimation
        return np.concatenate([step_means(
            np.asarray(x[a:a + size]), decimation,
            None if mask is None else np.asarray(mask[a:a + size]))
            for a in range(0, len(x), size)] or [np.empty(0)])
    x = np.asarray(x, dtype=np.float64)
    starts = np.arange((x.size - 1) // decimation + 1) * decimation
    if mask is None:
        return np.add.reduceat(x, starts) / np.diff(np.append(starts, x.size))
    sums = np.add.reduceat(np.where(mask, x, 0.0), starts)
    counts = np.add.reduceat(mask.astype(np.float64), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / counts, np.nan)


def step_windows(log: ChamberLog, decimation: int, window_s: float = 100.0,
                 settle_s: float = SETTLE_S, skip_s: float = 0.0) -> np.ndarray:
    """The SF windows (`sf_spans`) as [k, 2] model-step ranges: a step belongs to the window
    holding its middle sample; windows holding no step are dropped."""
    spans = sf_spans(log, window_s, settle_s, skip_s)
    n_steps = (len(log) - 1) // decimation + 1
    half = (decimation - 1) / 2.0
    lo = np.ceil((spans[:, 0] - half) / decimation).astype(np.int64)
    hi = np.ceil((spans[:, 1] - half) / decimation).astype(np.int64)
    lo, hi = np.clip(lo, 0, n_steps), np.clip(hi, 0, n_steps)
    keep = hi > lo
    return np.column_stack([lo[keep], hi[keep]])


def windows_rms(err: np.ndarray, windows: np.ndarray, mask: np.ndarray | None = None) -> float:
    """RMS over `windows` ([k, 2] step ranges) of the mean of `err` over each window's
    (masked, finite) steps. A window the mask cuts (e.g. at the edge of the validation part)
    counts when it keeps at least half its steps (all that keep any, when none does); NaN
    without any."""
    e = np.asarray(err, dtype=np.float64)
    ok = np.isfinite(e) if mask is None else np.isfinite(e) & mask
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, e, 0.0))])
    n = np.concatenate([[0], np.cumsum(ok)])
    a, b = windows[:, 0], windows[:, 1]
    cnt = n[b] - n[a]
    sel = 2 * cnt >= b - a
    if not sel.any():
        sel = cnt > 0
    if not sel.any():
        return float("nan")
    means = (c[b][sel] - c[a][sel]) / cnt[sel]
    return float(np.sqrt(np.mean(means**2)))
