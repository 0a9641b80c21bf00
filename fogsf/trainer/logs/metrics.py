"""Scale-factor error from a chamber log: windows, the 20 C reference, the metrics block.

The apparent SF ratio of a window is mean(gyro - earth) / mean(table) (nominal SF = 1).
Windows are non-overlapping, `window_s` long, and never straddle a change of table rate:
each rate plateau is cut into whole windows from its start (a plateau's tail shorter than a
window is not a window). The SF error in ppm is relative to the SF at 20 C (board
thermometer) of the training data; after compensation the residual is measured / predicted
- 1, i.e. the window ratio of the corrected output.

The noise floor is the SF error that the gyro's own noise leaves in one window: each window
is cut into `SUB_WINDOWS` sub-windows, a straight line is fitted to their ratios (so thermal
drift inside the window is not counted as noise), and the residual spread over sqrt(n) is
that window's noise; the floor is the RMS over windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.trainer.errors import UserError
from fogsf.trainer.logs.chamber_log import ChamberLog, rate_text

SUB_WINDOWS = 10
T_REF_C = 20.0
REF_BAND_C = 5.0  # windows within this of T_REF_C are fitted to find the SF at T_REF_C


@dataclass
class SFWindows:
    """Per-window apparent SF. Arrays have one entry per window."""

    t_s: np.ndarray  # window centre time
    temp_c: np.ndarray  # mean board temperature
    rate_dps: np.ndarray  # mean table rate
    sf_ratio: np.ndarray  # apparent SF / nominal SF
    noise_ppm: np.ndarray  # noise of this window's ratio, ppm of nominal
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
    change = np.abs(np.diff(r)) > 1e-9 * np.maximum(np.abs(r[1:]), 1.0)
    if measures is not None:
        change |= measures[1:] != measures[:-1]
    edges = np.concatenate([[0], np.flatnonzero(change) + 1, [r.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)
            if measures is None or measures[a]]


def sf_windows(log: ChamberLog, window_s: float = 100.0, latitude_deg: float | None = None,
               correction_ppm: np.ndarray | None = None) -> SFWindows:
    """Apparent SF per window; with `correction_ppm` (per sample, vs nominal SF), of the
    corrected output gyro / (1 + correction * 1e-6)."""
    dt = log.sample_dt_s
    n = int(round(window_s / dt))
    if n < SUB_WINDOWS * 2:
        raise UserError(f"window of {window_s:g} s is too short: at least "
                        f"{SUB_WINDOWS * 2 * dt:g} s at {rate_text(dt)}")
    gyro = log.gyro_dps
    if correction_ppm is not None:
        corr = np.asarray(correction_ppm, dtype=np.float64)
        if corr.shape != gyro.shape:
            raise UserError(f"correction has {corr.shape[0]} samples, log has {gyro.shape[0]}")
        gyro = gyro / (1.0 + corr * 1e-6)
    signal = gyro - log.earth(latitude_deg)
    starts: list[int] = []
    for a, b in plateaus(log.table_rate_dps, log.measures):
        starts.extend(range(a, b - n + 1, n))
    if not starts:
        raise UserError(f"{log.path}: no complete {window_s:g} s window at a constant table "
                        "rate (the log or its rate plateaus are too short)")
    idx = np.asarray(starts)[:, None] + np.arange(n)[None, :]
    sig = signal[idx]
    tab = log.table_rate_dps[idx]
    ratio = sig.mean(axis=1) / tab.mean(axis=1)
    m = n // SUB_WINDOWS
    sub = (sig[:, : m * SUB_WINDOWS].reshape(len(starts), SUB_WINDOWS, m).mean(axis=2)
           / tab[:, : m * SUB_WINDOWS].reshape(len(starts), SUB_WINDOWS, m).mean(axis=2))
    x = np.arange(SUB_WINDOWS) - (SUB_WINDOWS - 1) / 2.0
    slope = (sub * x).sum(axis=1) / (x * x).sum()
    resid = sub - sub.mean(axis=1, keepdims=True) - slope[:, None] * x[None, :]
    noise = np.sqrt((resid**2).sum(axis=1) / (SUB_WINDOWS - 2) / SUB_WINDOWS)
    return SFWindows(
        t_s=log.time_s[idx].mean(axis=1),
        temp_c=log.temp_c[idx].mean(axis=1),
        rate_dps=tab.mean(axis=1),
        sf_ratio=ratio,
        noise_ppm=noise * 1e6,
        start=np.asarray(starts),
        stop=np.asarray(starts) + n,
        window_s=float(window_s),
    )


def reference_sf(w: SFWindows, t_ref_c: float = T_REF_C) -> float:
    """The apparent SF ratio at `t_ref_c` board temperature: a quadratic in temperature
    fitted to the windows within REF_BAND_C of it (a line where they are few)."""
    near = np.abs(w.temp_c - t_ref_c) <= REF_BAND_C
    if near.sum() < 2 or np.ptp(w.temp_c[near]) < 0.5:
        raise UserError(
            f"the board temperature never spans {t_ref_c:g} +/- {REF_BAND_C:g} C (range "
            f"{w.temp_c.min():.1f}..{w.temp_c.max():.1f} C): the SF at {t_ref_c:g} C, the "
            "reference of the SF error, cannot be measured on this log: give it with --ref-sf "
            "RATIO (ref_sf_ratio of `fogsf inspect --json` on a run of the same gyro that "
            "spans 20 C), or use logs whose board temperature spans it")
    deg = 2 if near.sum() >= 6 else 1
    coef = np.polyfit(w.temp_c[near] - t_ref_c, w.sf_ratio[near], deg)
    return float(coef[-1])


def reference_sf_of_logs(logs: list[ChamberLog], window_s: float = 100.0,
                         latitude_deg: float | None = None, t_ref_c: float = T_REF_C) -> float:
    """The SF at `t_ref_c` over several logs (e.g. all training runs) together."""
    ws = [sf_windows(lg, window_s, latitude_deg) for lg in logs]
    merged = SFWindows(*(np.concatenate([getattr(w, f) for w in ws]) for f in
                         ("t_s", "temp_c", "rate_dps", "sf_ratio", "noise_ppm", "start",
                          "stop")), window_s=float(window_s))
    return reference_sf(merged, t_ref_c)


def sf_error_ppm(w: SFWindows, ref: float) -> np.ndarray:
    """Window SF error in ppm relative to the reference ratio `ref`."""
    return (w.sf_ratio / ref - 1.0) * 1e6


def noise_floor_ppm(w: SFWindows) -> float:
    return float(np.sqrt(np.mean(w.noise_ppm**2)))


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
                correction_ppm: np.ndarray | None = None) -> dict[str, float]:
    """The metrics block of a log.

    Without a correction: SF error about `ref` (the apparent SF ratio at 20 C; measured on
    this log when not given). With `correction_ppm` (a model's per-sample prediction of the
    SF error vs nominal): the residual measured / predicted - 1 (no reference is used).
    """
    w = sf_windows(log, window_s, latitude_deg, correction_ppm)
    if correction_ppm is not None:
        ref = 1.0
    elif ref is None:
        ref = reference_sf(w)
    return metrics_block(sf_error_ppm(w, ref), window_s, noise_floor_ppm(w))


@dataclass
class PlateauPairs:
    """SF and bias separated by consecutive +/- rate plateaus (one entry per pair)."""

    t_s: np.ndarray
    temp_c: np.ndarray
    sf_ratio: np.ndarray
    bias_dps: np.ndarray


def plateau_pairs(log: ChamberLog, latitude_deg: float | None = None,
                  settle_s: float = 0.0) -> PlateauPairs:
    """For schedules that alternate the table rate's sign: each pair of consecutive plateaus
    of opposite sign gives SF = (m1 - m2) / (r1 - r2) and bias = (m2 r1 - m1 r2) / (r1 - r2)
    (for r2 = -r1: half the difference over r1, and half the sum)."""
    signal = log.gyro_dps - log.earth(latitude_deg)
    skip = int(round(settle_s / log.sample_dt_s))
    pl = [(a + skip, b) for a, b in plateaus(log.table_rate_dps, log.measures)
          if b - a > skip + 1]
    out: list[tuple[float, float, float, float]] = []
    i = 0
    while i + 1 < len(pl):  # pairs do not share a plateau
        (a1, b1), (a2, b2) = pl[i], pl[i + 1]
        r1, r2 = log.table_rate_dps[a1:b1].mean(), log.table_rate_dps[a2:b2].mean()
        if np.sign(r1) == np.sign(r2):
            i += 1
            continue
        i += 2
        m1, m2 = signal[a1:b1].mean(), signal[a2:b2].mean()
        sf = (m1 - m2) / (r1 - r2)
        bias = (m2 * r1 - m1 * r2) / (r1 - r2)
        t = 0.5 * (log.time_s[a1:b1].mean() + log.time_s[a2:b2].mean())
        temp = 0.5 * (log.temp_c[a1:b1].mean() + log.temp_c[a2:b2].mean())
        out.append((t, temp, sf, bias))
    if not out:
        raise UserError(f"{log.path}: no consecutive +/- table-rate plateaus to pair")
    a = np.asarray(out)
    return PlateauPairs(t_s=a[:, 0], temp_c=a[:, 1], sf_ratio=a[:, 2], bias_dps=a[:, 3])
