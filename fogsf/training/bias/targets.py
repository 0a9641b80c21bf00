"""The bias model's targets: the bias each training log measures (`logs.measure.bias`), a
stationary log's model steps (mean of output - earth rate over each step) or a +/- pair's
bias at the step under its centre (`step_targets`), with the SF model's prediction taken off
the pairs' plateaus (`measured_windows`); what a target averages over (`target_kernel`) and
the columns averaged there as the pair averages its plateaus (`at_targets`); and the rule
that stationary logs train a bias-only model alone (`check_mixed`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, is_stationary
from fogsf.logs.measure.bias import BiasWindows, bias_windows
from fogsf.logs.measure.model_steps import step_means
from fogsf.logs.measure.plateaus import DPS_TO_DPH
from fogsf.logs.read.columns import Column

# A stationary log's step with fewer valid samples than this share of a step (the log's
# last, partial step; one cut by invalid rows) is no target: the fit weighs every step
# alike, and a mean of a few samples holds the angle random walk of a few samples (one
# sample at 10 Hz: 12 deg/h off, which alone set a held-out score)
MIN_STEP_SHARE = 0.5


def step_targets(log: ChamberLog, w: BiasWindows, decimation: int,
                 latitude_deg: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(step index, bias deg/h) the log gives: every step of a stationary log with at least
    MIN_STEP_SHARE of its samples valid, or each +/- pair at the step under its centre."""
    if w.source == "stationary":
        keep = np.ones(len(log), dtype=bool) if log.valid is None else log.valid
        y = step_means((log.gyro_dps - log.earth(latitude_deg)) * DPS_TO_DPH, decimation, keep)
        length = np.minimum(decimation, len(log) - np.arange(y.size) * decimation)
        count = (length if log.valid is None
                 else step_means(log.valid, decimation) * length)
        idx = np.flatnonzero(np.isfinite(y) & (count >= MIN_STEP_SHARE * decimation))
        return idx, y[idx]
    return w.step_index(decimation), w.bias_dph


def target_kernel(w: BiasWindows | None, step_s: float) -> np.ndarray | None:
    """What a target averages over, as weights on the model steps about it: a +/- pair's bias
    is (m0 + 3 m1 + 3 m2 + m3) / 8 of its four plateaus (`logs.measure.pairs`), each half the pairs'
    span; a stationary log's target is its own step (None)."""
    if w is None or w.source != "pairs":
        return None
    p = max(1, int(round(0.5 * w.window_s / step_s)))
    k = np.repeat([1.0, 3.0, 3.0, 1.0], p)
    return k / k.sum()


def at_targets(x: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """x (steps[, columns]) averaged as the targets average (`target_kernel`), the ends
    held: the design a pair's bias is fitted to (linear features exactly; their squares and
    cubes to within their spread over a few minutes)."""
    if kernel is None:
        return x
    a = np.asarray(x, dtype=np.float64)
    flat = a.reshape(a.shape[0], -1)
    lo, hi = kernel.size // 2, kernel.size - 1 - kernel.size // 2
    out = np.column_stack([np.convolve(np.pad(flat[:, j], (lo, hi), mode="edge"), kernel[::-1],
                                       "valid") for j in range(flat.shape[1])])
    return out.reshape(a.shape).astype(a.dtype)


SFOf = Callable[[ChamberLog], Column]  # a log -> the SF model's prediction, ppm per sample


def measured_windows(log: ChamberLog, window_s: float, latitude_deg: float | None,
                     settle_s: float, sf_of: SFOf | None = None) -> BiasWindows | None:
    """The bias windows a log measures (`logs.measure.bias.bias_windows`); with `sf_of`, the SF
    model's prediction taken off the pairs' plateaus first (`PlateauPairs.minus_sf`: the SF
    drifting between a staircase pair's two plateaus would read as bias)."""
    return bias_windows(log, window_s, latitude_deg, settle_s, sf_ppm=_sf_for(log, sf_of))


def _sf_for(log: ChamberLog, sf_of: SFOf | None) -> Column | None:
    """The SF series to take off a log's pairs: none for a stationary log (no pairs)."""
    return None if sf_of is None or is_stationary(log) else sf_of(log)


def check_mixed(logs: list[ChamberLog]) -> bool:
    """True when every training log is stationary (a bias-only model); refused when some
    are and some are not."""
    flags = [is_stationary(lg) for lg in logs]
    if any(flags) and not all(flags):
        still = ", ".join(lg.path for lg, f in zip(logs, flags, strict=True) if f)
        raise UserError(f"{still}: stationary (the table stopped throughout): such logs "
                        "train a bias-only model, given alone; the SF model with its bias "
                        "head trains on logs with the table turning (+/- pairs give the bias)")
    return all(flags)
