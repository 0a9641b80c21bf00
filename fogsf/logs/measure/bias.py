"""The gyro's bias as a log measures it (deg/h), beside the SF.

Two ways a log measures the bias:

- `+/- pairs` (`pairs.find_pairs`): adjacent plateaus of opposite sign and equal |rate|;
  each pair's bias comes with its SF (the pair fit cancels a linear drift of both).
- `stationary`: the table stopped for the whole log (the autopilots' cold soak and warm-up):
  the output is bias + earth rate, so the bias of a window is mean(gyro - earth). Such a log
  measures no SF: every SF figure refuses it with `stationary_refusal`.

`bias_windows(log)` gives either as one series (`BiasWindows`): per window its time, board
temperature, bias and the model steps it spans, and the noise floor (1 sigma of one window).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, is_stationary
from fogsf.logs.measure.pairs import PlateauPairs, find_pairs
from fogsf.logs.measure.plateaus import DPS_TO_DPH, SETTLE_S
from fogsf.logs.measure.windows import (
    MIN_SUB_WINDOWS,
    SUB_WINDOWS,
    sub_window_noise,
    window_samples,
)
from fogsf.logs.read.columns import Column, searchsorted, span_means

SOURCES = ("pairs", "stationary")


@dataclass
class BiasWindows:
    """The bias a log measures, one entry per window (a +/- pair, or a window of a
    stationary log)."""

    source: str  # one of SOURCES
    t_s: np.ndarray  # window centre, s
    temp_c: np.ndarray  # mean board temperature
    bias_dph: np.ndarray  # measured bias, deg/h
    start: np.ndarray  # first sample of the window
    stop: np.ndarray  # one past its last sample
    noise_floor_dph: float  # 1 sigma of one window's bias (NaN: too few windows)
    window_s: float  # the window length (stationary) or the mean pair span (pairs)
    t0_s: float = 0.0  # the log's first time stamp (times are shown from it)

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def step_index(self, decimation: int) -> np.ndarray:
        """The model step whose held output covers each window's middle sample."""
        return ((self.start + self.stop - 1) // 2) // decimation

    def mean_of(self, x: np.ndarray) -> np.ndarray:
        """Each window's mean of a per-sample series (in memory or on disk), float64."""
        return span_means(x, self.start, self.stop)

    def drift_dph_per_c(self) -> float | None:
        """Slope of the bias over board temperature; None under 1 C of span or 3 windows."""
        if len(self) < 3 or np.ptp(self.temp_c) < 1.0:
            return None
        return float(np.polyfit(self.temp_c, self.bias_dph, 1)[0])


def stationary_windows(log: ChamberLog, window_s: float = 100.0,
                       latitude_deg: float | None = None, skip_s: float = 0.0
                       ) -> BiasWindows:
    """Windows of `window_s` of a stationary log (the valid rows; from `skip_s` on): bias =
    mean(gyro - earth). The noise floor is the RMS over windows of the spread of ten
    sub-window means about a line (as the SF windows' noise), i.e. what the gyro's noise
    leaves in one window."""
    n = window_samples(window_s, log.sample_dt_s)
    earth = log.earth(latitude_deg)
    t_skip = log.time_s[0] + skip_s - 1e-9 if skip_s > 0 else None
    parts: list[tuple[np.ndarray, ...]] = []
    # whole windows from the log's first row, and from each segment's of a log with gaps
    # (logs/read/sampling.py: a burst logger's bursts)
    segs = [0] if log.sampling is None else list(log.sampling.segment_starts)
    ends = [*segs[1:], len(log)]
    starts_all = np.concatenate([np.arange(a, b - n + 1, n) for a, b in zip(segs, ends,
                                                                             strict=True)])
    per = max(1, BLOCK_WINDOWS_SAMPLES // n)  # windows read at a time: memory stays bounded
    for j in range(0, starts_all.size, per):
        s0 = starts_all[j:j + per]
        a, b = int(s0[0]), int(s0[-1]) + n
        # the windows' rows within [a, b) (contiguous but for a segment's tail)
        idx = (s0 - a)[:, None] + np.arange(n)[None, :]
        keep = np.ones(b - a, dtype=bool) if log.valid is None else np.array(log.valid[a:b])
        t = np.asarray(log.time_s[a:b])
        if t_skip is not None:
            keep &= t >= t_skip
        ok = keep[idx].all(axis=1)
        if not ok.any():
            continue
        sig = ((np.asarray(log.gyro_dps[a:b]) - earth[a:b]) * DPS_TO_DPH)[idx][ok]
        m = n // SUB_WINDOWS
        noise = sub_window_noise(sig[:, :m * SUB_WINDOWS].reshape(-1, SUB_WINDOWS, m)
                                 .mean(axis=2))
        parts.append((t[idx][ok].mean(axis=1),
                      np.asarray(log.temp_c[a:b])[idx][ok].mean(axis=1),
                      sig.mean(axis=1), s0[ok], noise))
    if not parts:
        raise UserError(f"{log.path}: no complete {window_s:g} s bias window of valid rows "
                        "(--window-s, --skip-s)")
    t_s, temp_c, bias, starts, noise = (np.concatenate(x) for x in zip(*parts, strict=True))
    starts = starts.astype(np.int64)
    return BiasWindows("stationary", t_s, temp_c, bias, starts, starts + n,
                       float(np.sqrt(np.mean(noise**2))), float(window_s),
                       float(log.time_s[0]))


BLOCK_WINDOWS_SAMPLES = 1 << 18  # stationary windows are measured about this many samples at once


def pair_windows(log: ChamberLog, latitude_deg: float | None = None,
                 settle_s: float = SETTLE_S, sf_ppm: Column | None = None
                 ) -> BiasWindows | None:
    """The +/- pairs' bias (`find_pairs`; with `sf_ppm`, an SF series per sample such as the
    SF model's prediction, `PlateauPairs.minus_sf`) as windows; None without pairs. A
    pair's window is its centre +/- one plateau; the noise floor is the spread of second
    differences of successive pairs' bias (a linear drift cancels, what is left is noise, an
    upper bound where the bias curves fast), scaled to one pair's noise by `second_difference_ratio`
    (successive pairs share plateaus, so their noise is correlated)."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        return None
    if sf_ppm is not None:
        pp = pp.minus_sf(sf_ppm)
    centre = np.clip([searchsorted(log.time_s, float(x)) for x in pp.t_s], 0, len(log) - 1)
    span_s = float(np.median(np.diff(pp.t_s))) if len(pp) > 1 else 0.0
    half = max(1, int(round(0.5 * span_s / log.sample_dt_s)))
    start = np.clip(centre - half, 0, len(log) - 1)
    stop = np.clip(centre + half, 1, len(log))
    bias = pp.bias_dps * DPS_TO_DPH
    if len(pp) >= MIN_SUB_WINDOWS:
        d2 = bias[:-2] - 2.0 * bias[1:-1] + bias[2:]
        floor = float(np.std(d2) * np.sqrt(second_difference_ratio(pp)))
    else:
        floor = float("nan")
    return BiasWindows("pairs", pp.t_s.copy(), pp.temp_c.copy(), bias, start, stop, floor,
                       span_s, float(log.time_s[0]))


def second_difference_ratio(pp: PlateauPairs) -> float:
    """Var(one pair's bias) / Var(a second difference of successive pairs' bias) for white
    noise on the plateau means (a plateau's mean: variance 1/n of its n samples), from the
    weights each pair's bias puts on its plateaus: 1/6 for independent pairs, 20/72 for
    pairs of four equal plateaus that share two with each neighbour."""
    n = pp.plateau_n
    var_b = [float(np.sum(g * g / n[i])) for i, g in pp.bias_weights]
    var_d2 = []
    for k in range(len(pp.bias_weights) - 2):
        c: dict[int, float] = {}
        for (idx, g), f in zip(pp.bias_weights[k:k + 3], (1.0, -2.0, 1.0), strict=True):
            for i, v in zip(idx.tolist(), g.tolist(), strict=True):
                c[i] = c.get(i, 0.0) + f * v
        var_d2.append(sum(v * v / n[i] for i, v in c.items()))
    return float(np.mean(var_b) / np.mean(var_d2)) if var_d2 else 1.0 / 6.0


def bias_windows(log: ChamberLog, window_s: float = 100.0, latitude_deg: float | None = None,
                 settle_s: float = SETTLE_S, skip_s: float = 0.0,
                 sf_ppm: Column | None = None) -> BiasWindows | None:
    """The bias the log measures: a stationary log's windows, else its +/- pairs (`sf_ppm`:
    the SF series taken off their plateaus, `pair_windows`); None when it measures no bias
    (no pairs, the table turning)."""
    if is_stationary(log):
        return stationary_windows(log, window_s, latitude_deg, skip_s)
    w = pair_windows(log, latitude_deg, settle_s, sf_ppm)
    if w is not None and skip_s > 0:
        keep = w.t_s >= log.time_s[0] + skip_s
        w = BiasWindows(w.source, w.t_s[keep], w.temp_c[keep], w.bias_dph[keep],
                        w.start[keep], w.stop[keep], w.noise_floor_dph, w.window_s, w.t0_s)
    return w if w is not None and len(w) else None


def bias_metrics(err_dph: np.ndarray, noise_floor_dph: float) -> dict[str, float]:
    """The bias metrics block (deg/h): max|e|, peak-to-peak, RMS about zero, STD about the
    mean, and the noise floor of one window."""
    e = np.asarray(err_dph, dtype=np.float64)
    return {"max_abs_dph": float(np.max(np.abs(e))), "pp_dph": float(np.ptp(e)),
            "rms_dph": float(np.sqrt(np.mean(e**2))), "std_dph": float(np.std(e)),
            "noise_floor_dph": float(noise_floor_dph)}


def before_after(w: BiasWindows, predicted_dph: np.ndarray) -> dict:
    """Before (the measured bias, nothing taken off) and after (measured - predicted, the
    per-sample prediction averaged over each window's samples) over the bias windows."""
    p = w.mean_of(predicted_dph)
    return {"source": w.source, "windows": len(w),
            "before": bias_metrics(w.bias_dph, w.noise_floor_dph),
            "after": bias_metrics(w.bias_dph - p, w.noise_floor_dph)}


def bias_summary(w: BiasWindows, rows: int = 8) -> dict:
    """inspect's bias block: the series' figures and up to `rows` windows spread over the
    log (time from the log's first sample, board temperature, bias)."""
    pick = np.unique(np.linspace(0, len(w) - 1, min(rows, len(w))).round().astype(int))
    return {"source": w.source, "count": len(w), "window_s": w.window_s,
            "bias_dph": float(w.bias_dph.mean()), "std_dph": float(w.bias_dph.std()),
            "range_dph": [float(w.bias_dph.min()), float(w.bias_dph.max())],
            "drift_dph_per_c": w.drift_dph_per_c(), "noise_floor_dph": w.noise_floor_dph,
            "temp_range_c": [float(w.temp_c.min()), float(w.temp_c.max())],
            "series": [{"t_s": float(w.t_s[i] - w.t0_s), "temp_c": float(w.temp_c[i]),
                        "bias_dph": float(w.bias_dph[i])} for i in pick]}
