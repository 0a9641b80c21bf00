"""Scale-factor error from a chamber log: the one place SF is measured.

Plateaus. The table column gives the commanded rate; a plateau is a run of rows at one
commanded rate that measure (`ChamberLog.measures`). A table takes a moment to reach a newly
commanded rate, so the first `settle_s` seconds of every plateau but the log's first are
left out (SETTLE_S covers a table slewing about 1 s), and of the log's first plateau too
when its gyro shows the table spinning up there (`_spins_up`: a log that starts with its
table command); with `skip_s`, the log's first seconds too. What is left counts from
MIN_PLATEAU_S up.

Windows. A plateau at least `window_s` long is cut into whole non-overlapping windows from
its commanded start (its tail shorter than a window is not a window), and the settle margin
(and a skipped start) is trimmed off the windows it falls in, so that a plateau keeps its
number of windows; a shorter plateau is one window of its settled samples (from
MIN_PLATEAU_S up). On a log at one constant rate nothing is settled and every window is
`window_s` long, as it always was. The apparent SF ratio of a
window is mean(gyro - bias - earth) / mean(table) (nominal SF = 1). The SF error in ppm is
relative to the SF at 20 C (board thermometer) of the training data; after compensation
the residual is measured / predicted - 1, i.e. the window ratio of the corrected output.

+/- pairs. Adjacent plateaus of opposite sign and equal |rate| (`PAIR_RATE_TOL`) give SF
and bias separately (IEEE Std 952): SF = (m1 - m2) / (r1 - r2), bias = (m2 r1 - m1 r2) /
(r1 - r2), refined with the +/- plateaus next to the pair so that an SF drifting with
temperature between its two plateaus does not read as bias (`_pair_fit`). When a log has
pairs, their bias, interpolated in time between pair centres, is taken off the gyro before
any window, target or metric is measured, so that it does not leak into the SF at low rates
(a bias b reads as b / rate in SF). A pair's bias also holds half the SF asymmetry times
its rate (one pair cannot tell them apart), so it is taken off only at its own |rate|: there
each plateau then reads the mean of SF+ and SF- (what one SF correction can compensate);
a |rate| without pairs keeps its bias.

Rate steps. A log with plateaus at two or more |rates| in both directions (a staircase)
gives the SF per rate step, the SF nonlinearity (largest deviation of a rate level's mean
output from the least-squares straight line through all plateaus, ppm of the full-scale
output) and the SF asymmetry ((SF+ - SF-) / mean SF, ppm) as IEEE Std 952 defines them
(`rate_steps`).

The noise floor is the SF error that the gyro's own noise leaves in one window: each window
is cut into `SUB_WINDOWS` sub-windows (fewer in a short one, at least 3), a straight line is
fitted to their ratios (so thermal drift inside the window is not counted as noise), and the
residual spread over sqrt(n) is that window's noise; the floor is the RMS over windows.

Model steps. `step_windows` maps the windows onto model steps (a step belongs to the window
holding its middle sample) and `windows_rms` is the RMS of an error's window means there:
what training validates on and the rate-transfer check measures, so that every command uses
the same windows and the user's --window-s and --settle-s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError
from fogsf.logs import columns
from fogsf.logs.chamber_log import (
    ChamberLog,
    LogError,
    is_stationary,
    rate_text,
    stationary_refusal,
)
from fogsf.logs.columns import is_lazy, searchsorted
from fogsf.logs.pairs import (
    bias_track,
)
from fogsf.logs.plateaus import (
    BLOCK_SAMPLES,
    MIN_PLATEAU_S,
    SETTLE_S,
    T_REF_C,
    _plateau_starts,
    _samples,
)

SUB_WINDOWS = 10
MIN_SUB_WINDOWS = 3  # a line and a spread need three
REF_BAND_C = 5.0  # windows within this of T_REF_C are fitted to find the SF at T_REF_C
REF_BRACKET_C = 15.0  # set points this far each side of T_REF_C still give its SF
START_SPAN_S = 300.0  # the start of a log: its first 5 minutes
START_MOVING_C_PER_MIN = 0.05  # faster than this at the start is "moving" (a soak is slower)


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
    check_units(log, out["sf_ratio"], spans[:, 0])
    return SFWindows(start=spans[:, 0].copy(), stop=spans[:, 1].copy(),
                     window_s=float(window_s), **out)


RAD_TO_DEG = 180.0 / np.pi
UNITS_TOL = 0.01  # a ratio within 1 % of 180/pi (or pi/180) is a rad/s - deg/s mix-up


def units_factor(ratio: float) -> str | None:
    """'180/pi' or 'pi/180' when `ratio` lies within UNITS_TOL of it, else None."""
    for factor, text in ((RAD_TO_DEG, "180/pi"), (1.0 / RAD_TO_DEG, "pi/180")):
        if abs(ratio / factor - 1.0) <= UNITS_TOL:
            return text
    return None


UNITS_FIX = ("gyro_dps and table_rate_dps are in deg/s: a column in rad/s is mapped with "
             "`* 57.29577951308232` (a rad/s to deg/s factor), one already in deg/s without "
             "it; fix the column map (--columns or its file)")


def check_units(log: ChamberLog, sf_ratio: np.ndarray, starts: np.ndarray) -> None:
    """Refuse a log whose gyro reads 180/pi (or pi/180) times its table rate: one of them
    in rad/s, the other in deg/s; and one whose windows jump by such a factor mid-log (the
    units switched), at the line of the first window off."""
    if not sf_ratio.size:
        return
    med = float(np.median(sf_ratio))
    factor = units_factor(med)
    if factor is not None:
        raise UserError(f"{log.path}: units: the gyro reads {med:.6g} x the table rate "
                        f"(reference SF ratio within 1 % of {factor}): one of gyro_dps and "
                        f"table_rate_dps is in rad/s, the other in deg/s; {UNITS_FIX}")
    for i, r in enumerate(sf_ratio):
        factor = units_factor(float(r) / med) if med != 0 else None
        if factor is not None:
            normal = np.flatnonzero(np.abs(sf_ratio[:i] / med - 1.0) <= UNITS_TOL)
            lo = int(starts[normal[-1]]) if normal.size else 0  # the last window in the unit
            row = _switch_row(log, lo, int(starts[i]), med, factor)
            raise LogError(log.path, row + 2, "units switch",
                           f"the SF ratio jumps from {med:.6g} to {float(r):.6g} "
                           f"({factor}): the gyro or the table switched between rad/s and "
                           "deg/s mid-log; write the log in one unit")


def _switch_row(log: ChamberLog, lo: int, hi: int, med: float, factor: str) -> int:
    """The first row in [lo, hi] (the last window in the log's unit, to the first off) whose own
    gyro / table ratio reads the switched unit (within 5 %); `hi` when none does."""
    f = RAD_TO_DEG if factor == "180/pi" else 1.0 / RAD_TO_DEG
    tab = np.asarray(log.table_rate_dps[lo:hi + 1], dtype=np.float64)
    gyro = np.asarray(log.gyro_dps[lo:hi + 1], dtype=np.float64)
    with np.errstate(all="ignore"):
        off = (tab != 0) & (np.abs(gyro / tab / (med * f) - 1.0) <= 0.05)
    hits = np.flatnonzero(off)
    return lo + int(hits[0]) if hits.size else hi

def reference_sf(w: SFWindows, t_ref_c: float = T_REF_C) -> float:
    """The apparent SF ratio at `t_ref_c` board temperature: a quadratic in temperature
    fitted to the windows within REF_BAND_C of it (a line where they are few). A log held at
    set points (none within the band) takes the nearest set points on both sides of
    `t_ref_c`, up to REF_BRACKET_C away, and interpolates. A log that never comes near
    `t_ref_c` (a heated rig at 38-62 C) takes the nearest temperature it holds
    (`reference_temp_c`), said once on stderr."""
    t = reference_temp_c(w, t_ref_c)
    if t != t_ref_c:
        _say_once(f"fogsf: note: the board temperature never comes within {REF_BAND_C:g} C "
                  f"of {t_ref_c:g} C ({w.temp_c.min():.1f} .. {w.temp_c.max():.1f} C): the SF "
                  f"reference is the SF at {t:.2f} C, the nearest temperature the windows "
                  "hold (--ref-temp-c C sets it; --ref-sf RATIO gives the ratio)")
    return _reference_at(w, t)


def reference_temp_c(w: SFWindows, t_ref_c: float = T_REF_C) -> float:
    """The temperature the reference SF is taken at: `t_ref_c` when the windows span it
    (within REF_BAND_C, or set points on both sides within REF_BRACKET_C), else the
    windows' temperature nearest to it."""
    if not w.temp_c.size:
        return t_ref_c
    if np.any(np.abs(w.temp_c - t_ref_c) <= REF_BAND_C) or _bracket(w.temp_c, t_ref_c) \
            is not None:
        return t_ref_c
    return float(w.temp_c[np.argmin(np.abs(w.temp_c - t_ref_c))])


_SAID: set[str] = set()  # the notes said by this command (read_logs starts it afresh)


def forget_notes() -> None:
    """A new command: the notes of `_say_once` may be said again."""
    _SAID.clear()


def _say_once(text: str) -> None:
    import sys

    if text not in _SAID:
        _SAID.add(text)
        print(text, file=sys.stderr)


def _reference_at(w: SFWindows, t_ref_c: float) -> float:
    near = np.abs(w.temp_c - t_ref_c) <= REF_BAND_C
    deg = 2 if near.sum() >= 6 else 1
    if near.sum() < 2 or np.ptp(w.temp_c[near]) < 0.5:
        near, deg = _bracket(w.temp_c, t_ref_c), 1  # a line between two set points
    if near is None and np.any(np.abs(w.temp_c - t_ref_c) <= REF_BAND_C):
        near, deg = np.abs(w.temp_c - t_ref_c) <= REF_BAND_C, 0  # one set point: its mean
    if near is None:
        raise UserError(
            f"the log has no SF window (board temperature "
            f"{w.temp_c.min() if w.temp_c.size else float('nan'):.1f} C): the SF reference "
            "cannot be measured on it: give it with --ref-sf RATIO")
    coef = np.polyfit(w.temp_c[near] - t_ref_c, w.sf_ratio[near], deg)
    return float(coef[-1])


def _bracket(temp_c: np.ndarray, t_ref_c: float) -> np.ndarray | None:
    """The windows within REF_BAND_C of the nearest window below `t_ref_c` and of the nearest
    above it (a set point each side), when both lie within REF_BRACKET_C; else None."""
    below, above = temp_c[temp_c < t_ref_c], temp_c[temp_c > t_ref_c]
    if not below.size or not above.size:
        return None
    lo, hi = float(below.max()), float(above.min())
    if t_ref_c - lo > REF_BRACKET_C or hi - t_ref_c > REF_BRACKET_C:
        return None
    near = (np.abs(temp_c - lo) <= REF_BAND_C) | (np.abs(temp_c - hi) <= REF_BAND_C)
    return near if near.sum() >= 2 else None


def reference_sf_of_logs(logs: list[ChamberLog], window_s: float = 100.0,
                         latitude_deg: float | None = None, t_ref_c: float | None = None,
                         settle_s: float = SETTLE_S) -> float:
    """The SF at `t_ref_c` (None: the logs' `ref_temp_c`, --ref-temp-c) over several logs
    (e.g. all training runs) together."""
    ws = [sf_windows(lg, window_s, latitude_deg, settle_s=settle_s) for lg in logs]
    same_units(logs, ws)
    merged = SFWindows(*(np.concatenate([getattr(w, f) for w in ws]) for f in
                         ("t_s", "temp_c", "rate_dps", "sf_ratio", "noise_ppm", "start",
                          "stop")), window_s=float(window_s))
    return reference_sf(merged, logs[0].ref_temp_c if t_ref_c is None else t_ref_c)


def same_units(logs: list[ChamberLog], ws: list[SFWindows]) -> None:
    """Refuse logs (trained together) whose SF ratios differ by more than UNITS_TOL: one
    gyro's SF moves by parts per thousand at most; more is another unit or scaling."""
    meds = [(float(np.median(w.sf_ratio)), lg.path) for w, lg in zip(ws, logs, strict=True)
            if w.sf_ratio.size]
    if len(meds) < 2:
        return
    lo, hi = min(meds), max(meds)
    if hi[0] > lo[0] * (1.0 + UNITS_TOL):
        factor = units_factor(hi[0] / lo[0])
        why = (f" ({factor}: one in rad/s, the other in deg/s; {UNITS_FIX})" if factor
               else ": another unit or scaling in one of them (check the column maps)")
        raise UserError(f"units: the logs' SF ratios differ by more than 1 %: {lo[1]} "
                        f"{lo[0]:.6g}, {hi[1]} {hi[0]:.6g}{why}")


def sf_error_ppm(w: SFWindows, ref: float) -> np.ndarray:
    """Window SF error in ppm relative to the reference ratio `ref`."""
    return (w.sf_ratio / ref - 1.0) * 1e6


def noise_floor_ppm(w: SFWindows) -> float:
    """RMS of the windows' noise (windows too short for an estimate left out)."""
    ok = np.isfinite(w.noise_ppm)
    return float(np.sqrt(np.mean(w.noise_ppm[ok] ** 2))) if ok.any() else float("nan")


def metrics_block(err_ppm: np.ndarray, window_s: float, noise_floor: float) -> dict[str, float]:
    """The metrics block (docs/logs.md): max|e|, peak-to-peak, RMS about zero (the reference),
    STD about the mean, the window length and the noise floor, all in ppm (window in s)."""
    e = np.asarray(err_ppm, dtype=np.float64)
    return {
        "max_abs_ppm": float(np.max(np.abs(e))),
        "pp_ppm": float(np.ptp(e)),
        "rms_ppm": float(np.sqrt(np.mean(e**2))),
        "std_ppm": float(np.std(e)),
        "window_s": float(window_s),
        "noise_floor_ppm": float(noise_floor),
    }


def log_metrics(log: ChamberLog, window_s: float = 100.0, ref: float | None = None,
                latitude_deg: float | None = None,
                correction_ppm: np.ndarray | None = None, settle_s: float = SETTLE_S,
                skip_s: float = 0.0) -> dict[str, float]:
    """The metrics block of a log.

    Without a correction: SF error about `ref` (the apparent SF ratio at 20 C; measured on
    this log when not given). With `correction_ppm` (a model's per-sample prediction of the
    SF error vs nominal): the residual measured / predicted - 1 (no reference is used).
    `skip_s`: the log's first seconds are left out (the model still ran over them).
    """
    w = sf_windows(log, window_s, latitude_deg, correction_ppm, settle_s, skip_s)
    if correction_ppm is not None:
        ref = 1.0
    elif ref is None:
        ref = reference_sf(w, log.ref_temp_c)
    return metrics_block(sf_error_ppm(w, ref), window_s, noise_floor_ppm(w))


# --- model steps ------------------------------------------------------------------------------

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


# --- the start of a log -----------------------------------------------------------------------

def start_ramp_c_per_min(log: ChamberLog, span_s: float = START_SPAN_S) -> float:
    """|dT/dt| of the board temperature over the log's first `span_s` seconds (a straight
    line fitted; the whole log when shorter), C/min."""
    t = log.time_s
    k = searchsorted(t, t[0] + span_s)
    k = max(k, min(len(log), 3))
    if k < 3 or t[k - 1] <= t[0]:
        return 0.0
    return abs(float(np.polyfit(t[:k] - t[0], log.temp_c[:k], 1)[0])) * 60.0


def start_note(log: ChamberLog, skip_s: float = 0.0) -> str | None:
    """One line when the log starts while its board temperature moves; None otherwise."""
    rate = start_ramp_c_per_min(log)
    if rate <= START_MOVING_C_PER_MIN:
        return None
    done = (f"the first {skip_s:g} s are left out of the metrics (--skip-s)" if skip_s > 0
            else "--skip-s S leaves the first S seconds out of the metrics")
    return (f"note: {log.path} starts while the board temperature moves ({rate:.2f} C/min over "
            f"its first {min(START_SPAN_S, log.duration_s):.0f} s): a model's lag states start "
            "at the first sample's temperature, as if the gyro had soaked there, so its output "
            f"is wrong until they catch up; {done}")
