"""The reference SF: the apparent SF ratio at the reference board temperature (20 C, or
--ref-temp-c), fitted to the SF windows near it, interpolated between set points either side
of it, or taken at the nearest temperature a log holds (said once per command); over several
logs together, whose SF ratios must agree in units."""

from __future__ import annotations

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import SETTLE_S, T_REF_C
from fogsf.logs.measure.units import INVERTED_FIX, UNITS_FIX, UNITS_TOL, units_factor
from fogsf.logs.measure.windows import SFWindows, sf_windows

REF_BAND_C = 5.0  # windows within this of T_REF_C are fitted to find the SF at T_REF_C
REF_BRACKET_C = 15.0  # set points this far each side of T_REF_C still give its SF


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
    within = np.abs(w.temp_c - t_ref_c) <= REF_BAND_C
    near: np.ndarray | None = within
    deg = 2 if within.sum() >= 6 else 1
    if within.sum() < 2 or np.ptp(w.temp_c[within]) < 0.5:
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
    def cat(f: str) -> np.ndarray:
        return np.concatenate([getattr(w, f) for w in ws])

    merged = SFWindows(cat("t_s"), cat("temp_c"), cat("rate_dps"), cat("sf_ratio"),
                       cat("noise_ppm"), cat("start"), cat("stop"), window_s=float(window_s))
    return reference_sf(merged, logs[0].ref_temp_c if t_ref_c is None else t_ref_c)


def same_units(logs: list[ChamberLog], ws: list[SFWindows]) -> None:
    """Refuse logs (trained together) whose SF ratios differ by more than UNITS_TOL of the
    smaller in size, or differ in sign: one gyro's SF moves by parts per thousand at most;
    more is another unit or scaling, a sign is an inverted axis."""
    meds = [(float(np.median(w.sf_ratio)), lg.path) for w, lg in zip(ws, logs, strict=True)
            if w.sf_ratio.size]
    if len(meds) < 2:
        return
    lo, hi = min(meds), max(meds)
    if lo[0] < 0.0 < hi[0] or lo[0] == 0.0 or hi[0] == 0.0:
        raise UserError(f"units: the logs' SF ratios differ in sign: {lo[1]} {lo[0]:.6g}, "
                        f"{hi[1]} {hi[0]:.6g}: one axis is inverted ({INVERTED_FIX})")
    if hi[0] - lo[0] > UNITS_TOL * min(abs(lo[0]), abs(hi[0])):
        factor = units_factor(hi[0] / lo[0])
        why = (f" ({factor}: one in rad/s, the other in deg/s; {UNITS_FIX})" if factor
               else ": another unit or scaling in one of them (check the column maps)")
        raise UserError(f"units: the logs' SF ratios differ by more than 1 %: {lo[1]} "
                        f"{lo[0]:.6g}, {hi[1]} {hi[0]:.6g}{why}")
