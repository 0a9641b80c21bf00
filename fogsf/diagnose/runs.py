"""Chamber logs as per-window observations for system identification.

A window is one of `logs.measure.windows.sf_windows` (whole windows on one settled table-rate
plateau, or a whole plateau shorter than a window), with the gyro's bias left in: the
catalogue models bias drift and asymmetry by what they do to the apparent SF (a bias b
reads as b / rate), so the +/- pairs' bias is not taken off here as other commands do.
Its observation is the apparent SF error vs nominal, y = (mean(gyro - earth) / mean(table)
- 1) in ppm. Every slower quantity a model needs (a lag-filtered temperature, an
exponential of time) is computed at 10 Hz and averaged over exactly the window's samples,
so the model and the data see the same averaging.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.exact_stats import median_step
from fogsf.logs.measure.windows import SFWindows, sf_windows
from fogsf.logs.read.columns import Column, blocks, cumsum_blocks_at, derived
from fogsf.sim.lag import STREAM_BLOCK, lag_blocks


@dataclass
class Run:
    """One log and its windows. Window arrays have one entry per window."""

    name: str
    log: ChamberLog
    win: SFWindows
    y_ppm: np.ndarray  # apparent SF error vs nominal
    sigma_ppm: np.ndarray  # noise of y per window (pooled per |rate| level)
    dt_s: float = 0.0  # the log's median sample step (np.median(np.diff(time_s)))
    cache: dict[tuple, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.win)

    def window_mean(self, x: Column) -> np.ndarray:
        """Mean of a per-sample series over each window's samples, summed a block at a time
        (numpy's cumulative sum's bits, for an array or a column on disk)."""
        return self.window_mean_blocks(blocks(x))

    def window_mean_blocks(self, parts: Iterable[tuple[int, np.ndarray]]) -> np.ndarray:
        """`window_mean` of a series given a block at a time, in order ((start, samples)):
        the same bits, and never the whole series in memory."""
        n = len(self.win.start)
        ends = cumsum_blocks_at(parts, np.concatenate([self.win.start, self.win.stop]))
        return (ends[n:] - ends[:n]) / (self.win.stop - self.win.start)

    def lagged_window_mean(self, u: Column, tau_s: float,
                           f: Callable[[int, np.ndarray], np.ndarray] | None = None
                           ) -> np.ndarray:
        """Window means of lag(u, tau_s) (u sampled every dt_s, started at u[0]), or of
        f(start, lag block) when f is given, made a block of STREAM_BLOCK samples at a time."""
        parts = lag_blocks(u, tau_s, self.dt_s, float(u[0]), STREAM_BLOCK)
        if f is not None:
            parts = ((a, f(a, y)) for a, y in parts)
        return self.window_mean_blocks(parts)

    @property
    def rate(self) -> np.ndarray:
        return self.win.rate_dps

    @property
    def t_s(self) -> np.ndarray:
        return self.win.t_s


def pooled_sigma(win: SFWindows) -> np.ndarray:
    """Per-window noise, pooled over the windows at the same |rate| (one window's own
    estimate has only a few degrees of freedom; the noise of a ratio scales with 1/|rate|)."""
    mag = np.round(np.abs(win.rate_dps), 6)
    out = np.full(len(win), np.nan)
    for m in np.unique(mag):
        sel = mag == m
        ok = np.isfinite(win.noise_ppm[sel])  # windows too short for an estimate: NaN
        if ok.any():
            out[sel] = np.sqrt(np.mean(win.noise_ppm[sel][ok] ** 2))
    return out


def load_run(log: ChamberLog, window_s: float, latitude_deg: float | None,
             min_windows: int = 12) -> Run:
    for col, x in (("time_s", log.time_s), ("temp_c", log.temp_c),
                   ("table_rate_dps", log.table_rate_dps), ("gyro_dps", log.gyro_dps),
                   *((k, v) for k, v in log.extra.items() if k == "chamber_c")):
        count, first = 0, -1
        for a, block in blocks(x):
            bad = np.flatnonzero(~np.isfinite(np.asarray(block, dtype=np.float64)))
            if bad.size and first < 0:
                first = a + int(bad[0])
            count += bad.size
        if count:
            raise UserError(f"{log.path}: column {col!r} has {count} NaN/Inf cells (first at "
                            f"sample {first}); diagnose needs every cell: cut the log "
                            "before them or fill them")
    win = sf_windows(log, window_s, latitude_deg, remove_bias=False)
    if len(win) < min_windows:
        raise UserError(f"{log.path}: only {len(win)} windows of {window_s:g} s; diagnose needs "
                        f"at least {min_windows} (a longer log or a shorter --window-s)")
    y = (win.sf_ratio - 1.0) * 1e6
    return Run(name=log.path, log=log, win=win, y_ppm=y,
               sigma_ppm=usable_sigma(pooled_sigma(win)), dt_s=median_step(log.time_s))


NOISELESS_SIGMA_PPM = 1e-3  # the weight of windows whose noise is zero (a noiseless simulation)


def usable_sigma(sigma: np.ndarray) -> np.ndarray:
    """Window noise for weights: a level whose noise cannot be measured (zero in a noiseless
    simulation; NaN for windows of fewer than 3 samples) takes the smallest measured one,
    or NOISELESS_SIGMA_PPM when none is measured (never an infinite weight)."""
    ok = np.isfinite(sigma) & (sigma > 0)
    if ok.all():
        return sigma
    fill = float(sigma[ok].min()) if ok.any() else NOISELESS_SIGMA_PPM
    return np.where(ok, sigma, fill)


def per_sample(x: Column, f: Callable[[np.ndarray], np.ndarray]) -> Column:
    """f of a per-sample series, elementwise, as a derived column (computed a block at a
    time when read, for an array or a column on disk)."""
    return derived(len(x), np.dtype(np.float64),
                   lambda s: f(np.asarray(x[s], dtype=np.float64)))
