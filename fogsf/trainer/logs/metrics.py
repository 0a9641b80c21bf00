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

from fogsf.trainer.errors import UserError
from fogsf.trainer.logs.chamber_log import ChamberLog, rate_text

SUB_WINDOWS = 10
MIN_SUB_WINDOWS = 3  # a line and a spread need three
T_REF_C = 20.0
REF_BAND_C = 5.0  # windows within this of T_REF_C are fitted to find the SF at T_REF_C
REF_BRACKET_C = 15.0  # set points this far each side of T_REF_C still give its SF
SETTLE_S = 2.0  # left out after each change of commanded rate (covers a ~1 s table slew)
MIN_PLATEAU_S = 5.0  # a settled plateau shorter than this measures nothing
PAIR_RATE_TOL = 0.01  # |r1| and |r2| within 1 % (and 1e-6 deg/s) make a +/- pair
MIN_RATE_LEVELS = 2  # |rates| (each in both directions) that nonlinearity and asymmetry need
DPS_TO_DPH = 3600.0
START_SPAN_S = 300.0  # the start of a log: its first 5 minutes
START_MOVING_C_PER_MIN = 0.05  # faster than this at the start is "moving" (a soak is slower)
# per-sample work is done this many samples at a time (2 MB a float64 column): memory beyond
# the log's own columns does not grow with its length; every result is the same bits
BLOCK_SAMPLES = 1 << 18


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


def plateaus(table_rate_dps: np.ndarray, measures: np.ndarray | None = None
             ) -> list[tuple[int, int]]:
    """[start, stop) index ranges over which the table rate does not change; with `measures`
    (`ChamberLog.measures`), only the measuring runs inside them."""
    r = np.asarray(table_rate_dps)
    if r.size == 0:
        return []
    found = [np.zeros(1, dtype=np.int64)]
    for a in range(0, r.size - 1, BLOCK_SAMPLES):  # no log-long temporaries
        x = r[a:a + BLOCK_SAMPLES + 1]
        change = np.abs(np.diff(x)) > 1e-9 * np.maximum(np.abs(x[1:]), 1.0)
        if measures is not None:
            m = measures[a:a + BLOCK_SAMPLES + 1]
            change |= m[1:] != m[:-1]
        found.append(a + np.flatnonzero(change) + 1)
    edges = np.concatenate([*found, [r.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)
            if measures is None or measures[a]]


def _samples(seconds: float, dt: float) -> int:
    return int(np.ceil(seconds / dt - 1e-6)) if seconds > 0 else 0


def _plateau_starts(log: ChamberLog, settle_s: float, skip_s: float
                    ) -> list[tuple[int, int, int]]:
    """(commanded start, first counted sample, stop) of every measuring plateau: the first
    counted sample is `settle_s` after the start (but on the log's first plateau, which
    follows no change) and not before the log's first `skip_s` seconds."""
    if settle_s < 0 or skip_s < 0:
        raise UserError("--settle-s and --skip-s must be >= 0")
    settle = _samples(settle_s, log.sample_dt_s)
    first = 0
    if skip_s > 0 and len(log):
        first = int(np.searchsorted(log.time_s, log.time_s[0] + skip_s - 1e-9))
    return [(a, max(a + settle if a > 0 or _spins_up(log, b, settle) else a, first), b)
            for a, b in plateaus(log.table_rate_dps, log.measures)]


SPIN_UP_TOL = 1e-3  # the log's first seconds read the table this far (0.1 %) off: a spin-up


def _spins_up(log: ChamberLog, stop: int, settle: int) -> bool:
    """Whether the log's first plateau [0, stop) begins with the table still spinning up (a
    log that starts with its table command): the gyro's mean over the first `settle`
    samples differs from the next ten margins' by more than SPIN_UP_TOL of the rate. A table
    already turning when the log starts reads the same there (noise and thermal SF change
    are ppm), so such a log keeps its first samples, as it always did."""
    if settle == 0 or stop < 2 * settle:
        return settle > 0
    head = float(log.gyro_dps[:settle].mean())
    rest = float(log.gyro_dps[settle:min(stop, 11 * settle)].mean())
    return abs(head - rest) > SPIN_UP_TOL * abs(float(log.table_rate_dps[0]))


def settled_plateaus(log: ChamberLog, settle_s: float = SETTLE_S, skip_s: float = 0.0
                     ) -> list[tuple[int, int]]:
    """The measuring plateaus without their first `settle_s` seconds (but the log's first
    plateau, which follows no change), without the log's first `skip_s` seconds, and at least
    MIN_PLATEAU_S long."""
    shortest = max(1, _samples(MIN_PLATEAU_S, log.sample_dt_s))
    return [(a, b) for _, a, b in _plateau_starts(log, settle_s, skip_s) if b - a >= shortest]


def measuring_mask(log: ChamberLog, settle_s: float = SETTLE_S, skip_s: float = 0.0
                   ) -> np.ndarray:
    """Per sample, True inside a settled plateau: the samples SF and targets come from."""
    m = np.zeros(len(log), dtype=bool)
    for a, b in settled_plateaus(log, settle_s, skip_s):
        m[a:b] = True
    return m


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
        from fogsf.trainer.logs.chamber_log import is_stationary, stationary_refusal

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
    x = np.arange(k) - (k - 1) / 2.0
    slope = (sub * x).sum(axis=1) / (x * x).sum()
    resid = sub - sub.mean(axis=1, keepdims=True) - slope[:, None] * x[None, :]
    noise = np.sqrt((resid**2).sum(axis=1) / (k - 2) / k)
    return ratio, noise * 1e6


SignalParts = tuple[np.ndarray | None, np.ndarray | None, np.ndarray]


def _signal_parts(log: ChamberLog, latitude_deg: float | None,
                  correction_ppm: np.ndarray | None, settle_s: float, remove_bias: bool
                  ) -> SignalParts:
    """(the pairs' bias or None, the correction (ppm) or None, the earth rate): what
    `sf_signal` is made of, per sample."""
    b = bias_track(log, latitude_deg, settle_s) if remove_bias else None
    corr = None
    if correction_ppm is not None:
        corr = np.asarray(correction_ppm)  # float64 where it is used (float32 from a kernel)
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
    return SFWindows(start=spans[:, 0].copy(), stop=spans[:, 1].copy(),
                     window_s=float(window_s), **out)


def reference_sf(w: SFWindows, t_ref_c: float = T_REF_C) -> float:
    """The apparent SF ratio at `t_ref_c` board temperature: a quadratic in temperature
    fitted to the windows within REF_BAND_C of it (a line where they are few). A log held at
    set points (none within the band) takes the nearest set points on both sides of
    `t_ref_c`, up to REF_BRACKET_C away, and interpolates."""
    near = np.abs(w.temp_c - t_ref_c) <= REF_BAND_C
    deg = 2 if near.sum() >= 6 else 1
    if near.sum() < 2 or np.ptp(w.temp_c[near]) < 0.5:
        near, deg = _bracket(w.temp_c, t_ref_c), 1  # a line between two set points
    if near is None:
        raise UserError(
            f"the board temperature never spans {t_ref_c:g} +/- {REF_BAND_C:g} C (range "
            f"{w.temp_c.min():.1f}..{w.temp_c.max():.1f} C), nor lies on both sides of it "
            f"within {REF_BRACKET_C:g} C: the SF at {t_ref_c:g} C, the reference of the SF "
            "error, cannot be measured on this log: give it with --ref-sf RATIO "
            "(ref_sf_ratio of `fogsf inspect --json` on a run of the same gyro that spans "
            "20 C), or use logs whose board temperature spans it")
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
                         latitude_deg: float | None = None, t_ref_c: float = T_REF_C,
                         settle_s: float = SETTLE_S) -> float:
    """The SF at `t_ref_c` over several logs (e.g. all training runs) together."""
    ws = [sf_windows(lg, window_s, latitude_deg, settle_s=settle_s) for lg in logs]
    merged = SFWindows(*(np.concatenate([getattr(w, f) for w in ws]) for f in
                         ("t_s", "temp_c", "rate_dps", "sf_ratio", "noise_ppm", "start",
                          "stop")), window_s=float(window_s))
    return reference_sf(merged, t_ref_c)


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
        ref = reference_sf(w)
    return metrics_block(sf_error_ppm(w, ref), window_s, noise_floor_ppm(w))


# --- +/- pairs and rate steps ---------------------------------------------------------------

@dataclass
class PlateauPairs:
    """SF and bias separated by adjacent +/- rate plateaus (one entry per pair)."""

    t_s: np.ndarray
    temp_c: np.ndarray
    sf_ratio: np.ndarray
    bias_dps: np.ndarray
    rate_dps: np.ndarray  # |rate| of the pair

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def bias_drift_dph_per_c(self) -> float | None:
        """Slope of the pairs' bias over their board temperature (deg/h per C); None when
        the temperature spans less than 1 C or there are fewer than 3 pairs."""
        if len(self) < 3 or np.ptp(self.temp_c) < 1.0:
            return None
        return float(np.polyfit(self.temp_c, self.bias_dps * DPS_TO_DPH, 1)[0])


@dataclass
class _Plateau:
    start: int
    stop: int
    rate: float  # mean commanded rate
    mean: float  # mean of gyro - earth
    t_s: float
    temp_c: float
    n: int  # samples averaged (a plateau cut by a stall: both pieces)


def _plateau_means(log: ChamberLog, latitude_deg: float | None, settle_s: float
                   ) -> list[_Plateau]:
    """The settled plateaus' means; the pieces of one commanded plateau that rows measuring
    nothing (a stall, a disabled row) cut apart are one plateau again: a pair's fit needs
    its +/- neighbours at the usual distance, and two pieces close in time would read the SF
    drift from noise. gyro - earth is taken plateau by plateau (no log-long temporary)."""
    earth = log.earth(latitude_deg)
    out: list[_Plateau] = []
    for a, b in settled_plateaus(log, settle_s):
        rate = log.table_rate_dps[a:b]
        signal = log.gyro_dps[a:b] - earth[a:b]
        if out and np.all(log.table_rate_dps[out[-1].stop - 1:a + 1] == rate[0]):
            prev, n = out[-1], b - a  # same command all through the gap: merge
            tot = prev.n + n
            out[-1] = _Plateau(
                prev.start, b, prev.rate,
                (prev.mean * prev.n + float(signal.sum())) / tot,
                (prev.t_s * prev.n + float(log.time_s[a:b].sum())) / tot,
                (prev.temp_c * prev.n + float(log.temp_c[a:b].sum())) / tot, tot)
            continue
        out.append(_Plateau(a, b, float(rate.mean()), float(signal.mean()),
                            float(log.time_s[a:b].mean()), float(log.temp_c[a:b].mean()),
                            b - a))
    return out


def _is_pair(p: _Plateau, q: _Plateau) -> bool:
    if np.sign(p.rate) == np.sign(q.rate) or p.rate == 0 or q.rate == 0:
        return False
    big = max(abs(p.rate), abs(q.rate))
    return abs(abs(p.rate) - abs(q.rate)) <= PAIR_RATE_TOL * big + 1e-6


def _pair_fit(group: list[_Plateau], tc: float) -> tuple[float, float]:
    """(SF ratio, bias) at time `tc` from a pair and its +/- neighbours: a least-squares fit
    of m = r (s0 + s1 tau) + b0 + b1 tau (tau = t - tc; with three plateaus no b1, with two
    neither s1 nor b1), each plateau weighted by its length (a stall shortens one). With
    both neighbours at +/-r and equal lengths this is the bias (m0 + 3 m1 + 3 m2 + m3) / 8
    (signs alternating), which cancels an SF that drifts linearly, even
    quadratically, in time (the SF moving between the two plateaus of a pair on a ramp
    would otherwise read as bias: 5 ppm at 100 deg/s is 0.9 deg/h) and a linear bias drift."""
    r = np.array([p.rate for p in group])
    m = np.array([p.mean for p in group])
    tau = np.array([p.t_s for p in group]) - tc
    cols = [r, np.ones_like(r)]
    if len(group) >= 3:
        cols.append(r * tau)
    if len(group) >= 4:
        cols.append(tau)
    w = np.sqrt([p.n for p in group])  # a plateau's noise goes as 1/sqrt(n)
    coef, *_ = np.linalg.lstsq(np.column_stack(cols) * w[:, None], m * w, rcond=None)
    return float(coef[0]), float(coef[1])


def find_pairs(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> PlateauPairs | None:
    """The log's +/- pairs: adjacent settled plateaus of opposite sign and equal |rate|
    (PAIR_RATE_TOL), no plateau in two pairs; None without any. Each pair's SF and bias are
    at its centre time, from the pair and the +/- plateaus next to it (`_pair_fit`)."""
    pl = _plateau_means(log, latitude_deg, settle_s)
    out: list[tuple[float, float, float, float, float]] = []
    i = 0
    while i + 1 < len(pl):
        p, q = pl[i], pl[i + 1]
        if not _is_pair(p, q):
            i += 1
            continue
        group = [p, q]
        if i > 0 and _is_pair(pl[i - 1], p):
            group.insert(0, pl[i - 1])
        if i + 2 < len(pl) and _is_pair(q, pl[i + 2]):
            group.append(pl[i + 2])
        i += 2
        tc = 0.5 * (p.t_s + q.t_s)
        sf, bias = _pair_fit(group, tc)
        out.append((tc, 0.5 * (p.temp_c + q.temp_c), sf, bias,
                    0.5 * (abs(p.rate) + abs(q.rate))))
    if not out:
        return None
    a = np.asarray(out)
    return PlateauPairs(t_s=a[:, 0], temp_c=a[:, 1], sf_ratio=a[:, 2], bias_dps=a[:, 3],
                        rate_dps=a[:, 4])


def plateau_pairs(log: ChamberLog, latitude_deg: float | None = None,
                  settle_s: float = SETTLE_S) -> PlateauPairs:
    """`find_pairs`, refused when the log has none."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        raise UserError(f"{log.path}: no adjacent +/- table-rate plateaus of equal |rate| "
                        f"to pair (each at least {MIN_PLATEAU_S:g} s after the {settle_s:g} s "
                        "settle margin, --settle-s)")
    return pp


def bias_track(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> np.ndarray | None:
    """Per sample, the bias (deg/s) of the pairs at the sample's |table rate|, interpolated
    in time between their centres (held before the first and after the last); 0 at a |rate|
    without pairs (a pair's bias holds asymmetry x rate / 2: it is not moved to another
    rate). None for a log without pairs."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        return None
    out = np.zeros(len(log))
    for r in np.unique(pp.rate_dps):
        at = np.abs(pp.rate_dps - r) <= PAIR_RATE_TOL * r + 1e-6
        for a in range(0, len(log), BLOCK_SAMPLES):  # no log-long temporaries
            s = slice(a, a + BLOCK_SAMPLES)
            here = np.abs(np.abs(log.table_rate_dps[s]) - r) <= PAIR_RATE_TOL * r + 1e-6
            out[s][here] = np.interp(log.time_s[s][here], pp.t_s[at], pp.bias_dps[at])
    return out


@dataclass
class RateSteps:
    """SF per rate step of a staircase and IEEE Std 952's nonlinearity and asymmetry.

    A least-squares fit over every settled plateau's mean output m = (SF + a(T)) r + b + c(T)
    gives the line: a(T) and c(T), the SF's and the bias's thermal change, are polynomials
    in the plateau's board temperature T about `temp_c` (20 C when the plateaus span it,
    else their mean) of a degree the span allows (none under 1 C, a line under 5 C, a
    quadratic under 20 C, a cubic beyond: a staircase at several heater set points). SF+
    and SF- come from the same fit with a slope for each sign; the SF per step is at
    `temp_c`."""

    rates_dps: np.ndarray  # |rate| levels
    sf_pos_ppm: np.ndarray  # SF at +rate vs nominal, ppm (NaN: no plateau there)
    sf_neg_ppm: np.ndarray
    sf_ppm: float  # the line's slope vs nominal, ppm (at the log's mean temperature)
    bias_dps: float  # the separate-slope fit's intercept (the line's holds asymmetry too)
    nonlinearity_ppm: float  # max |level mean - line| / full-scale output, ppm
    asymmetry_ppm: float  # (SF+ - SF-) / mean SF, ppm (the separate-slope fit)
    temp_c: float = T_REF_C  # the board temperature the SF per step is at

    def as_dict(self) -> dict:
        return {"rates_dps": self.rates_dps.tolist(),
                "sf_pos_ppm": _nan_none(self.sf_pos_ppm), "sf_neg_ppm": _nan_none(self.sf_neg_ppm),
                "sf_ppm": self.sf_ppm, "bias_dph": self.bias_dps * DPS_TO_DPH,
                "sf_nonlinearity_ppm_fs": self.nonlinearity_ppm,
                "sf_asymmetry_ppm": self.asymmetry_ppm, "temp_c": self.temp_c}


def _nan_none(a: np.ndarray) -> list[float | None]:
    return [None if not np.isfinite(x) else float(x) for x in a]


def _rate_levels(rates: np.ndarray) -> np.ndarray:
    """Per plateau, the index of its |rate| level (levels within PAIR_RATE_TOL merged)."""
    mag = np.abs(rates)
    order = np.argsort(mag)
    level = np.empty(mag.size, dtype=int)
    k, base = -1, -np.inf
    for i in order:
        if mag[i] > base * (1 + PAIR_RATE_TOL) + 1e-6:
            k, base = k + 1, mag[i]
        level[i] = k
    return level


def rate_steps(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> RateSteps | None:
    """The staircase figures (`RateSteps`); None for a log with fewer than MIN_RATE_LEVELS
    |rates| or without both signs."""
    pl = _plateau_means(log, latitude_deg, settle_s)
    if not pl:
        return None
    r = np.array([p.rate for p in pl])
    m = np.array([p.mean for p in pl])
    temp = np.array([p.temp_c for p in pl])
    level = _rate_levels(r)
    if level.max() + 1 < MIN_RATE_LEVELS or not ((r > 0).any() and (r < 0).any()):
        return None
    t0, thermal = _thermal_columns(r, temp)
    one = np.ones_like(r)
    line_x = np.column_stack([r, one, *thermal])
    line, *_ = np.linalg.lstsq(line_x, m, rcond=None)
    split_x = np.column_stack([np.where(r > 0, r, 0.0), np.where(r < 0, r, 0.0), one, *thermal])
    split, *_ = np.linalg.lstsq(split_x, m, rcond=None)
    resid = m - line_x @ line
    sign = np.sign(r)
    groups = [(level == k) & (sign == s) for k in range(level.max() + 1) for s in (-1, 1)]
    dev = max(abs(float(resid[g].mean())) for g in groups if g.any())
    # per plateau: SF with the split fit's bias and thermal terms taken off (the split fit's
    # intercept is the bias whatever the asymmetry; the line's holds asymmetry x rate / 2)
    bias = float(split[2])
    per = m - bias - (np.column_stack(thermal) @ split[3:] if thermal else 0.0)
    per_sf = (per / r - 1.0) * 1e6
    levels = range(level.max() + 1)
    rates = np.array([np.abs(r[level == k]).mean() for k in levels])

    def side(k: int, positive: bool) -> float:
        sel = (level == k) & ((r > 0) if positive else (r < 0))
        return float(per_sf[sel].mean()) if sel.any() else float("nan")

    pos = np.array([side(k, True) for k in levels])
    neg = np.array([side(k, False) for k in levels])
    sf = float(line[0])
    full_scale = abs(sf) * float(np.abs(r).max())
    asym = float((split[0] - split[1]) / (0.5 * (split[0] + split[1]))) * 1e6
    return RateSteps(rates, pos, neg, (sf - 1.0) * 1e6, bias, dev / full_scale * 1e6, asym, t0)


def _thermal_columns(r: np.ndarray, temp: np.ndarray) -> tuple[float, list[np.ndarray]]:
    """(T0, columns r u^k and u^k for k = 1..degree), u = (T - T0) / the largest |T - T0|:
    the SF's and the bias's change with board temperature in `rate_steps` (degree by span:
    0 under 1 C, 1 under 5 C, 2 under 20 C, else 3)."""
    span = float(np.ptp(temp))
    t0 = T_REF_C if temp.min() <= T_REF_C <= temp.max() else float(temp.mean())
    degree = 0 if span < 1.0 else 1 if span < 5.0 else 2 if span < 20.0 else 3
    if degree == 0:
        return t0, []
    u = (temp - t0) / max(float(np.max(np.abs(temp - t0))), 1e-9)
    powers = [u**k for k in range(1, degree + 1)]
    return t0, [r * p for p in powers] + powers


# --- model steps ------------------------------------------------------------------------------

def step_means(x: np.ndarray, decimation: int, mask: np.ndarray | None = None) -> np.ndarray:
    """Mean of a per-sample series over each model step's samples (the masked ones; NaN for a
    step with none)."""
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
    k = int(np.searchsorted(t, t[0] + span_s))
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
