"""The SF windows of a log (the rules: logs/measure/metrics.py): the sample ranges of whole
windows on settled table-rate plateaus (`sf_spans`), the signal the SF multiplies (gyro - bias -
earth, optionally corrected: `sf_signal`), and per window its apparent SF ratio and the noise
of that ratio from its sub-windows (`sf_windows`, `SFWindows`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, is_stationary, rate_text, stationary_refusal
from fogsf.logs.measure.pairs import bias_track
from fogsf.logs.measure.plateaus import (
    BLOCK_SAMPLES,
    MIN_PLATEAU_S,
    SETTLE_S,
    _plateau_starts,
    _samples,
)
from fogsf.logs.measure.units import check_units
from fogsf.logs.read.columns import is_lazy

SUB_WINDOWS = 10
MIN_SUB_WINDOWS = 3  # a line and a spread need three


@dataclass
class SFWindows:
    """Per-window apparent SF. Arrays have one entry per window."""

    t_s: np.ndarray  # window centre time
    temp_c: np.ndarray  # mean board temperature
    rate_dps: np.ndarray  # mean table rate
    sf_ratio: np.ndarray  # apparent SF / nominal SF
    noise_ppm: np.ndarray  # noise of this window's ratio, ppm of nominal (NaN: too short)
    start: np.ndarray  # first sample index (int)
    stop: np.ndarray  # one past the last sample index (int)
    window_s: float

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


def window_samples(window_s: float, dt: float) -> int:
    """Samples per window; a window too short for the noise estimate is refused."""
    n = int(round(window_s / dt))
    if n < SUB_WINDOWS * 2:
        raise UserError(f"--window-s {window_s:g} is too short: at least "
                        f"{SUB_WINDOWS * 2 * dt:g} s at {rate_text(dt)}")
    return n


def sf_spans(log: ChamberLog, window_s: float = 100.0, settle_s: float = SETTLE_S,
             skip_s: float = 0.0) -> np.ndarray:
    """[k, 2] sample ranges [start, stop) of the SF windows: a plateau at least a window long
    is cut into whole windows from its commanded start, as on a log at one rate, and the
    samples that do not count (the settle margin, the skipped start) are trimmed off the
    windows they fall in (a window left shorter than MIN_PLATEAU_S is dropped); a plateau
    shorter than a window is one window of its counted samples from MIN_PLATEAU_S up. So a
    plateau of four windows keeps four windows, the first 2 s shorter."""
    n = window_samples(window_s, log.sample_dt_s)
    shortest = max(1, _samples(MIN_PLATEAU_S, log.sample_dt_s))
    spans: list[tuple[int, int]] = []
    for a0, a, b in _plateau_starts(log, settle_s, skip_s):
        if b - a0 < n:
            grid = [(a, b)]
        else:
            grid = [(max(s, a), s + n) for s in range(a0, b - n + 1, n)]
        spans.extend((x, y) for x, y in grid if y - x >= shortest)
    if not spans:

        if is_stationary(log):
            raise stationary_refusal(log)
        raise UserError(
            f"{log.path}: no complete SF window: no table-rate plateau of {MIN_PLATEAU_S:g} s "
            f"or more after the {settle_s:g} s settle margin (--settle-s)"
            + (f" and the first {skip_s:g} s (--skip-s)" if skip_s else "")
            + f", and none holds a {window_s:g} s window (--window-s)")
    return np.asarray(spans, dtype=np.int64).reshape(-1, 2)


def _span_stats(sig: np.ndarray, tab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ratio, noise ppm) of windows of one length: `sig` and `tab` [windows, samples]."""
    ratio = sig.mean(axis=1) / tab.mean(axis=1)
    rows, n = sig.shape
    k = min(SUB_WINDOWS, n)
    if k < MIN_SUB_WINDOWS:
        return ratio, np.full(rows, np.nan)
    m = n // k
    sub = (sig[:, : m * k].reshape(rows, k, m).mean(axis=2)
           / tab[:, : m * k].reshape(rows, k, m).mean(axis=2))
    return ratio, sub_window_noise(sub) * 1e6


def sub_window_noise(sub: np.ndarray) -> np.ndarray:
    """Per window, the noise of its mean from its k sub-window values `sub` [windows, k]:
    the spread about a fitted straight line (thermal drift inside a window is not noise)
    over sqrt(k), in the units of `sub`."""
    k = sub.shape[1]
    x = np.arange(k) - (k - 1) / 2.0
    slope = (sub * x).sum(axis=1) / (x * x).sum()
    resid = sub - sub.mean(axis=1, keepdims=True) - slope[:, None] * x[None, :]
    return np.sqrt((resid**2).sum(axis=1) / (k - 2) / k)


SignalParts = tuple[np.ndarray | None, np.ndarray | None, np.ndarray]


def _signal_parts(log: ChamberLog, latitude_deg: float | None,
                  correction_ppm: np.ndarray | None, settle_s: float, remove_bias: bool
                  ) -> SignalParts:
    """(the pairs' bias or None, the correction (ppm) or None, the earth rate): what
    `sf_signal` is made of, per sample."""
    b = bias_track(log, latitude_deg, settle_s) if remove_bias else None
    corr = None
    if correction_ppm is not None:
        # float64 where it is used (float32 from a kernel); on disk with a log on disk
        corr = correction_ppm if is_lazy(correction_ppm) else np.asarray(correction_ppm)
        if corr.shape != log.gyro_dps.shape:
            raise UserError(f"correction has {corr.shape[0]} samples, log has "
                            f"{log.gyro_dps.shape[0]}")
    return b, corr, log.earth(latitude_deg)


def _signal_at(log: ChamberLog, parts: SignalParts, at: slice | np.ndarray) -> np.ndarray:
    """`sf_signal` at the samples `at` (a slice, or an index array of any shape): the same
    arithmetic sample by sample, so the same bits however the samples are taken."""
    b, corr, earth = parts
    gyro = log.gyro_dps[at] if b is None else log.gyro_dps[at] - b[at]
    if corr is not None:
        gyro = gyro / (1.0 + corr[at].astype(np.float64) * 1e-6)
    return gyro - earth[at]


def sf_signal(log: ChamberLog, latitude_deg: float | None = None,
              correction_ppm: np.ndarray | None = None, settle_s: float = SETTLE_S,
              remove_bias: bool = True) -> np.ndarray:
    """Per sample, what the SF multiplies: gyro - bias - earth; with `correction_ppm` (per
    sample, vs nominal SF), (gyro - bias) / (1 + correction * 1e-6) - earth. The bias is the
    +/- pairs' (`bias_track`), none without pairs."""
    parts = _signal_parts(log, latitude_deg, correction_ppm, settle_s, remove_bias)
    out = np.empty(len(log))
    for a in range(0, len(log), BLOCK_SAMPLES):  # no log-long temporaries
        s = slice(a, a + BLOCK_SAMPLES)
        out[s] = _signal_at(log, parts, s)
    return out


def sf_windows(log: ChamberLog, window_s: float = 100.0, latitude_deg: float | None = None,
               correction_ppm: np.ndarray | None = None, settle_s: float = SETTLE_S,
               skip_s: float = 0.0, remove_bias: bool = True) -> SFWindows:
    """Apparent SF per window; with `correction_ppm` (per sample, vs nominal SF), of the
    corrected output (`sf_signal`; `remove_bias` False: the pairs' bias is left in). The
    signal is made window by window (no log-long copy of it)."""
    spans = sf_spans(log, window_s, settle_s, skip_s)
    parts = _signal_parts(log, latitude_deg, correction_ppm, settle_s, remove_bias)
    k = spans.shape[0]
    out = {f: np.empty(k) for f in ("t_s", "temp_c", "rate_dps", "sf_ratio", "noise_ppm")}
    earth_per_table = np.empty(k)  # for the units check: the earth's share of the ratio
    lengths = spans[:, 1] - spans[:, 0]
    for n in np.unique(lengths):  # windows of one length at a time (most are window_s)
        same = np.flatnonzero(lengths == n)
        per = max(1, BLOCK_SAMPLES // int(n))  # about BLOCK_SAMPLES samples gathered at once
        for j in range(0, same.size, per):
            sel = same[j:j + per]
            idx = spans[sel, 0][:, None] + np.arange(int(n))[None, :]
            tab = log.table_rate_dps[idx]
            out["sf_ratio"][sel], out["noise_ppm"][sel] = _span_stats(
                _signal_at(log, parts, idx), tab)
            out["t_s"][sel] = log.time_s[idx].mean(axis=1)
            out["temp_c"][sel] = log.temp_c[idx].mean(axis=1)
            out["rate_dps"][sel] = tab.mean(axis=1)
            earth_per_table[sel] = parts[2][idx].mean(axis=1) / out["rate_dps"][sel]
    check_units(log, out["sf_ratio"], spans[:, 0], earth_per_table, correction_ppm is None)
    return SFWindows(start=spans[:, 0].copy(), stop=spans[:, 1].copy(),
                     window_s=float(window_s), **out)
