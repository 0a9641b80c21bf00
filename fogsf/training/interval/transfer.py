"""Rate transfer: does the training data determine the SF error at another ramp rate?

On one constant ramp every lag temperature is the board temperature minus a constant, so
lag structures that differ only in how they extrapolate to other ramp rates fit the
training run equally well. This module measures that, from the training data alone plus
the board temperatures of a target log (its gyro output is not used):

1. the ramp rates each log holds (`ramp_rate_c_per_min`), and whether the target's lies
   within the training logs' range;
2. the family of lag-temperature models (one effective node with a cubic, two with a
   quadratic form; `models.structures.least_squares.node_candidates`) fitted to the training logs;
   the physically plausible ones (no node's temperature moves the SF by more than
   50 ppm/C anywhere on the training data; the default gyro's largest is 13 ppm/C: without
   such a bound, quadratic forms of nearly collinear nodes fit with huge cancelling
   coefficients and amplify even thermometer noise) whose training fit is as good as the
   best plausible one (sum of squares within a chi-square allowance of it, the noise
   variance estimated from that fit and widened by its residual's long-run variance ratio,
   so that structure no lag model explains loosens the allowance instead of pinning one
   misspecified model) are "consistent with the training data";
3. how far their predictions on the target log spread: the windowed RMS difference of each
   consistent model's prediction from the best one's, reported as the median and maximum.
   The windows are the SF windows of every metric (`logs.measure.model_steps.step_windows`:
   the user's --window-s and --settle-s, short plateaus one window each), and so is the noise floor.

A small spread says the training data pins the compensation down on the target's
temperature history; a spread far above the noise floor says it does not, and whatever a
model does there rests on its structural assumption, not on the data.

`training.interval.rate_transfer` runs the check (`rate_transfer`) and adds the interval for the
error the trained model leaves on the target.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.model_steps import step_means, step_windows, windows_rms
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.read.columns import searchsorted
from fogsf.models.features import common_sample_dt, front_end_for
from fogsf.models.structures.least_squares import (
    MAX_NODE_SLOPE_PPM_PER_C,
    TAU_GRID_S,
    fit_candidates,
    grid_data,
    measured_rows,
    node_candidates,
)

SLOPE_WINDOW_S = 300.0  # ramp rate: temperature change over 5 min windows
MIN_RAMP_C_PER_MIN = 0.05  # slower than this is a soak
RATE_TOLERANCE = 0.15  # a target rate within 15 % of the training range is covered
CHI2_ALLOWANCE = 6.0  # ~95 % of chi-square with 2 degrees of freedom
STEP_S = 5.0  # the model step of the lag models compared (default: the trained model's)
LONG_RUN_S = 100.0  # the residual's long-run variance over 100 s windows
INTERVAL_LO = 0.8  # the RMS of noise alone over a run's windows falls this far below its floor
EXCURSION_NOTE_C = 5.0  # lag states this far beyond the training range are worth a note


def ramp_rate_c_per_min(log: ChamberLog) -> float:
    """The log's typical ramp rate: the median |dT/dt| of the board temperature over 5-minute
    windows on its ramps (the faster half of the windows moving faster than 0.05 C/min, so
    that the bends at a ramp's ends do not count); 0 for a log with no ramp."""
    t, temp = log.time_s, log.temp_c
    n = searchsorted(t, float(t[0]) + SLOPE_WINDOW_S)
    if n < 1 or n >= t.size:
        return 0.0
    starts = np.arange(0, t.size - n, max(1, n // 5))
    slope = np.abs(temp[starts + n] - temp[starts]) / (t[starts + n] - t[starts]) * 60.0
    moving = slope[slope > MIN_RAMP_C_PER_MIN]
    if moving.size == 0:
        return 0.0
    return float(np.median(moving[moving >= np.median(moving)]))


@dataclass(frozen=True)
class RampSegment:
    """One ramp of a log: where it runs (s) and its signed rate (C/min, board thermometer)."""

    start_s: float
    stop_s: float
    rate_c_per_min: float


SEGMENT_MIN_S = 900.0  # a ramp shorter than 15 min is a bend, not a ramp


@dataclass(frozen=True)
class WindowRuns:
    """The log's SLOPE_WINDOW_S windows (a hop of a fifth of one): their ends' times and
    board temperatures, slopes (C/min), and the runs [a, b) of windows moving faster than
    MIN_RAMP_C_PER_MIN in one direction."""

    ta: np.ndarray
    tb: np.ndarray
    ca: np.ndarray
    cb: np.ndarray
    slope: np.ndarray
    runs: list[tuple[int, int]]


def window_runs(log: ChamberLog) -> WindowRuns | None:
    """The windows of `log` (None when it is shorter than one); the windows' ends only are
    read, so a log on disk stays there."""
    t = log.time_s
    size = len(t)
    n = searchsorted(t, float(t[0]) + SLOPE_WINDOW_S) if size else 0
    if n < 1 or n >= size:
        return None
    starts = np.arange(0, size - n, max(1, n // 5))
    ta = np.asarray(t[starts], dtype=np.float64)
    tb = np.asarray(t[starts + n], dtype=np.float64)
    ca = np.asarray(log.temp_c[starts], dtype=np.float64)
    cb = np.asarray(log.temp_c[starts + n], dtype=np.float64)
    slope = (cb - ca) / (tb - ta) * 60.0
    sign = np.where(np.abs(slope) > MIN_RAMP_C_PER_MIN, np.sign(slope), 0.0)
    edges = np.flatnonzero(np.diff(sign) != 0) + 1
    runs = [(int(a), int(b)) for a, b in zip(np.r_[0, edges], np.r_[edges, sign.size],
                                              strict=True) if sign[a] != 0]
    return WindowRuns(ta, tb, ca, cb, slope, runs)


def ramp_segments(log: ChamberLog) -> list[RampSegment]:
    """The log's ramps, each with its own rate: runs of 5-minute windows whose board
    temperature moves faster than 0.05 C/min in one direction, at least 15 min long; a
    segment's rate is the median of its faster half of windows (the board lags the chamber
    at a ramp's start, so its slope rises towards the chamber's).
    Up- and down-ramps, and ramps at different rates in one log, come out separately."""
    w = window_runs(log)
    if w is None:
        return []
    out = [RampSegment(float(w.ta[a]), float(w.tb[b - 1]), _steady_rate(w.slope[a:b]))
           for a, b in w.runs if float(w.tb[b - 1] - w.ta[a]) >= SEGMENT_MIN_S]
    # one ramp at a rate that changes (e.g. 1 then 2 C/min) splits where the rate jumps
    return _split_rate_changes(out, log.time_s, log.temp_c)


SHORT_RAMP_MIN_C = 2.0  # a move of the temperature smaller than this is a bend, not a ramp


@dataclass(frozen=True)
class ShortRamp:
    """A run of the board temperature in one direction too short to count as a ramp."""

    start_s: float  # from the log's first row
    minutes: float
    from_c: float
    to_c: float
    rate_c_per_min: float  # its fastest 5-minute window
    min_minutes: float  # what a ramp needs

    def text(self) -> str:
        return (f"the board temperature ramps {self.from_c:.1f} -> {self.to_c:.1f} C (up to "
                f"{self.rate_c_per_min:+.2f} C/min) for {self.minutes:.1f} min of 5-minute "
                f"windows from t0+{self.start_s:.0f} s: "
                f"shorter than the {self.min_minutes:g} min a ramp needs, so it does not count "
                "as a ramp (its ramp rate, a held-out ramp); its samples still train")


def short_ramps(log: ChamberLog) -> list[ShortRamp]:
    """The runs of `ramp_segments`' windows that move the board temperature SHORT_RAMP_MIN_C
    or more but are shorter than the SEGMENT_MIN_S a ramp needs."""
    w = window_runs(log)
    out: list[ShortRamp] = []
    for a, b in w.runs if w is not None else []:
        span_s = float(w.tb[b - 1] - w.ta[a]) if w is not None else 0.0
        if w is None or span_s >= SEGMENT_MIN_S or abs(w.cb[b - 1] - w.ca[a]) < SHORT_RAMP_MIN_C:
            continue
        fastest = w.slope[a:b][np.argmax(np.abs(w.slope[a:b]))]
        out.append(ShortRamp(float(w.ta[a] - w.ta[0]), span_s / 60.0, float(w.ca[a]),
                             float(w.cb[b - 1]), float(fastest), SEGMENT_MIN_S / 60.0))
    return out


def _steady_rate(slopes: np.ndarray) -> float:
    """The median of the faster half of signed window slopes (all of one sign)."""
    mag = np.abs(slopes)
    fast = slopes[mag >= np.median(mag)]
    return float(np.median(fast))


def _split_rate_changes(segs: list[RampSegment], t: np.ndarray, temp: np.ndarray
                        ) -> list[RampSegment]:
    """Split a segment in two where a two-level fit of its 5-minute slopes explains most of
    their spread, the levels differ by more than 30 % and each part is a ramp of its own
    (SEGMENT_MIN_S): the board's slow start on a single ramp is a bend, not a second rate."""
    out: list[RampSegment] = []
    step = max(1, searchsorted(t, float(t[0]) + SLOPE_WINDOW_S))
    for sg in segs:
        i0, i1 = searchsorted(t, sg.start_s), searchsorted(t, sg.stop_s)
        hop = max(1, step // 5)  # windows overlap: five per window length
        idx = np.arange(i0, max(i0 + 1, i1 - step), hop)
        if idx.size < 30:
            out.append(sg)
            continue
        sl = (temp[idx + step] - temp[idx]) / (t[idx + step] - t[idx]) * 60.0
        total = float(np.sum((sl - sl.mean()) ** 2))
        best = None
        for cut in range(10, sl.size - 10):
            sse = float(np.sum((sl[:cut] - np.median(sl[:cut])) ** 2)
                        + np.sum((sl[cut:] - np.median(sl[cut:])) ** 2))
            if best is None or sse < best[0]:
                best = (sse, cut)
        assert best is not None
        sse, cut = best
        left, right = sl[:cut - 5], sl[cut + 5:]  # a window's length from the bend
        lv, rv = _steady_rate(left), _steady_rate(right)
        tc = float(t[idx[cut]])
        long_enough = min(tc - sg.start_s, sg.stop_s - tc) >= SEGMENT_MIN_S
        if sse < 0.2 * total and abs(rv - lv) > 0.3 * min(abs(lv), abs(rv)) and long_enough:
            out += [RampSegment(sg.start_s, tc, lv), RampSegment(tc, sg.stop_s, rv)]
        else:
            out.append(sg)
    return out


def ramp_rates(log: ChamberLog, tolerance: float = RATE_TOLERANCE) -> list[float]:
    """The distinct |ramp rates| (C/min) of a log's segments, rates within `tolerance` of
    each other merged; empty for a log with no ramp."""
    rates = sorted(abs(sg.rate_c_per_min) for sg in ramp_segments(log))
    merged: list[list[float]] = []
    for r in rates:
        if merged and r <= merged[-1][0] * (1 + tolerance):
            merged[-1].append(r)
        else:
            merged.append([r])
    return [float(np.median(m)) for m in merged]


def training_ramp_rates(logs: list[ChamberLog]) -> list[float]:
    """The distinct |ramp rates| over every segment of every log (merged within
    RATE_TOLERANCE), ascending."""
    rates = sorted(r for lg in logs for r in ramp_rates(lg))
    merged: list[float] = []
    for r in rates:
        if not merged or r > merged[-1] * (1 + RATE_TOLERANCE):
            merged.append(r)
    return merged


def spans_ramp_rates(rates_c_per_min: list[float], factor: float = 1.5) -> bool:
    """Whether ramp rates (of logs; 0 for a log without a ramp) differ by at least `factor`."""
    moving = [r for r in rates_c_per_min if r > 0]
    return len(moving) >= 2 and max(moving) >= factor * min(moving)


@dataclass
class RateTransfer:
    train_rates_c_per_min: list[float]
    target_rate_c_per_min: float
    covered: bool  # the target's ramp rate lies within the training logs' range
    candidates: int  # plausible lag models (node sensitivities within the bound)
    consistent: int  # models that fit the training data as well as the best
    spread_median_ppm: float
    spread_max_ppm: float
    # long-run variance of the best fit's residual / white noise's (1: the lag family explains
    # the training data to its noise; more: structure is left, and the allowance widens)
    residual_long_run_ratio: float = 1.0
    noise_floor_ppm: float = 0.0  # the target log's (SF windows of --window-s)
    # the largest windowed RMS difference between a consistent lag model and the model being
    # judged (the trained model's prediction on the target); spread_max_ppm without one
    model_spread_max_ppm: float = 0.0
    # how far (C) the target drives any lag-filter state (60 s .. 2 h) beyond the range the
    # training logs gave it: the compensation there extrapolates in temperature
    lag_excursion_c: float = 0.0
    # where the RMS error (SF windows) left on the target should fall
    # (`rate_transfer.rms_interval`)
    rms_interval_ppm: tuple[float, float] = (0.0, 0.0)
    # the windowed RMS distance on the target from the judged model to each structure
    # candidate fitted to the training logs (`training.structure.choice`), what the
    # interval's upper end scales; and whether the training logs hold one ramp
    structure_spread_ppm: dict[str, float] = field(default_factory=dict)
    one_segment: bool = False

    def as_dict(self) -> dict:
        return asdict(self)

    def message(self) -> str:
        rates = ", ".join(f"{r:.2g}" for r in self.train_rates_c_per_min)
        head = (f"rate transfer: trained at {rates} C/min, target at "
                f"{self.target_rate_c_per_min:.2g} C/min")
        spread = (f"{self.consistent} of {self.candidates} plausible lag models fit the "
                  "training data as well as the best; on the target they differ by "
                  f"{self.spread_median_ppm:.1f} ppm RMS (median), up to "
                  f"{self.spread_max_ppm:.1f}")
        if self.residual_long_run_ratio > 2.0:
            spread += (f" (the best fit leaves structure, long-run variance "
                       f"{self.residual_long_run_ratio:.0f} x white: no lag model of this family "
                       "explains the training data to its noise)")
        lo, hi = self.rms_interval_ppm
        if self.structure_spread_ppm:
            far = max(self.structure_spread_ppm, key=self.structure_spread_ppm.__getitem__)
            spread += (f"; the structures fitted to the same logs differ from this model by up "
                       f"to {self.structure_spread_ppm[far]:.1f} ppm RMS there ({far})")
        if hi > 0 and self.noise_floor_ppm > 0:
            spread += (f". Expected RMS error on the target: {lo:.1f}-{hi:.1f} ppm "
                       f"({lo / self.noise_floor_ppm:.1f}-{hi / self.noise_floor_ppm:.1f} x its "
                       f"noise floor {self.noise_floor_ppm:.1f} ppm)")
        if self.lag_excursion_c > EXCURSION_NOTE_C:
            spread += (f"; the target takes slow internal temperatures up to "
                       f"{self.lag_excursion_c:.0f} C beyond anything the training logs show "
                       "(add a soak at the ends of the training ramps)")
        if self.covered:
            return f"{head} (within the training range): {spread}"
        return (f"{head}: OUTSIDE the training range, the compensation there is an "
                f"extrapolation; {spread}")


@dataclass
class TargetSpreads:
    """The consistent lag models on a target log (`rate_transfer`'s step 3): each one's
    windowed RMS distance from the best one (`spread`) and from the judged model
    (`model_spread`), the training fit's long-run ratio, and the target's steps and windows."""

    candidates: int
    spread: np.ndarray  # ppm, one per consistent model
    model_spread: np.ndarray  # ppm, one per consistent model
    inflation: float
    excursion_c: float
    decimation: int
    n_steps: int
    windows: np.ndarray  # the target's SF windows as step ranges
    every: np.ndarray  # the target's measured steps
    judged: np.ndarray  # the judged model's prediction per step (ppm; the best lag model's)

    def steps(self, per_sample_ppm: np.ndarray) -> np.ndarray:
        """A per-sample prediction on the target as the means of its model steps."""
        return step_means(per_sample_ppm, self.decimation)[:self.n_steps]

    def distance(self, per_sample_ppm: np.ndarray) -> float:
        """Windowed RMS (ppm) of a per-sample prediction's distance from the judged model."""
        return windows_rms(self.steps(per_sample_ppm) - self.judged, self.windows, self.every)


def target_spreads(train_logs: list[ChamberLog], target: ChamberLog,
                   latitude_deg: float | None = None,
                   prediction_ppm: np.ndarray | None = None, step_s: float = STEP_S,
                   window_s: float = 100.0, settle_s: float = SETTLE_S) -> TargetSpreads:
    """Steps 2 and 3 of the module docstring (`rate_transfer`'s arguments)."""
    fe = front_end_for([*train_logs, target], step_s, (),
                       sample_dt_s=common_sample_dt(train_logs))
    data, y = grid_data(train_logs, fe, TAU_GRID_S, latitude_deg)
    (tdata,), _ = grid_data([target], fe, TAU_GRID_S, latitude_deg)
    s = measured_rows(data)
    fits = [f for f in fit_candidates(node_candidates(1) + node_candidates(2), s, y)
            if f.plausible]
    if not fits:
        raise UserError("rate transfer: no lag model fits the training logs with node "
                        f"sensitivities under {MAX_NODE_SLOPE_PPM_PER_C:g} ppm/C")
    sse = np.array([f.sse for f in fits])
    best = int(np.argmin(sse))
    resid = y - fits[best].cand.design(s) @ fits[best].coef
    inflation = long_run_ratio(resid, [int(d.measured.sum()) for d in data],
                               max(1, int(round(LONG_RUN_S / step_s))))
    noise_var = sse[best] / max(1, y.size - 6)
    ok = np.flatnonzero(sse <= sse[best] + CHI2_ALLOWANCE * noise_var * inflation).tolist()
    preds = {i: fits[i].cand.design(tdata.s) @ fits[i].coef for i in ok}
    every = tdata.measured
    windows = step_windows(target, tdata.decimation, window_s, settle_s)
    spread = np.array([windows_rms(preds[i] - preds[best], windows, every) for i in ok])
    model_spread, ref = spread, preds[best]
    if prediction_ppm is not None:
        ref = step_means(prediction_ppm, tdata.decimation)[:tdata.n_steps]
        model_spread = np.array([windows_rms(preds[i] - ref, windows, every) for i in ok])
    return TargetSpreads(len(fits), spread, model_spread, inflation,
                         lag_excursion_c(s, tdata.s), tdata.decimation, tdata.n_steps,
                         windows, every, ref)


def lag_excursion_c(train_s: np.ndarray, target_s: np.ndarray) -> float:
    """How far (C) any lag-filter state of the target (columns 1.. of the grid front end's s)
    leaves the range the training rows gave it."""
    lo, hi = train_s[:, 1:].min(axis=0), train_s[:, 1:].max(axis=0)
    t_lo, t_hi = target_s[:, 1:].min(axis=0), target_s[:, 1:].max(axis=0)
    return float(max(0.0, np.max(t_hi - hi), np.max(lo - t_lo)))


def long_run_ratio(resid: np.ndarray, lengths: list[int], window: int = 20
                   ) -> float:
    """How much more the residual varies over `window`-step means than white noise would:
    window * mean(window mean^2) / mean(resid^2), windows within each log, at least 1."""
    means: list[float] = []
    for part in np.split(resid, np.cumsum(lengths)[:-1]):
        n = part.size // window
        if n:
            means += list(part[:n * window].reshape(n, window).mean(axis=1))
    if not means:
        return 1.0
    return max(1.0, window * float(np.mean(np.square(means))) / float(np.mean(resid**2)))
