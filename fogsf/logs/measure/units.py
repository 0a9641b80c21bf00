"""The units and sign check of the SF windows: a log whose SF ratio (gyro / table rate, the
median of its windows) lies outside SF_BAND cannot be a gyro scaled with its nominal SF read
against its table, and is refused, naming the likely cause (a column in rad/s, mrad/s, mdeg/s,
deg/h or rpm, an inverted axis) and the fix; so is a log whose windows jump by a rad/s -
deg/s factor mid-log (the units switched), at the line where they switch.

The earth rate is taken out in deg/s, but a gyro in another unit measured it in that unit: a
rad/s gyro at 10 deg/s and 34 deg latitude reads 1.35 % off pi/180. So each cause is tested
with the earth rate taken out in the gyro's own unit, which makes the check hold at any
latitude and table rate."""

from __future__ import annotations

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, LogError

RAD_TO_DEG = 180.0 / np.pi
UNITS_TOL = 0.01  # a ratio within 1 % of 180/pi (or pi/180) is a rad/s - deg/s mix-up
# The SF ratios a gyro scaled with its nominal SF can read: its SF is within parts per
# thousand of nominal, a nominal SF a little off is a few percent; 10 % is neither.
SF_BAND = (0.9, 1.1)
# Outside SF_BAND a ratio a named cause explains is refused; one no cause explains is
# refused only outside WIDE_BAND: a large bias over a slow table (a ratio that moves with
# 1/rate) reads tens of percent off without any unit being wrong.
WIDE_BAND = (0.5, 2.0)

# (gyro factor, table factor, cause, fix): a log with the gyro column read as g x deg/s and
# the table column as t x deg/s reads an SF ratio of g / t (plus the earth rate's share)
_RAD_FIX = "map it with `* 57.29577951308232` (rad/s to deg/s)"
CAUSES: tuple[tuple[float, float, str, str], ...] = (
    (1.0 / RAD_TO_DEG, 1.0, "gyro_dps is in rad/s (pi/180), the table in deg/s",
     f"the gyro: {_RAD_FIX}"),
    (1.0, 1.0 / RAD_TO_DEG, "table_rate_dps is in rad/s (180/pi), the gyro in deg/s",
     f"the table: {_RAD_FIX}"),
    (RAD_TO_DEG, 1.0, "gyro_dps is in deg/s but mapped as rad/s (180/pi)",
     "the gyro: drop its `* 57.29577951308232`"),
    (1.0, RAD_TO_DEG, "table_rate_dps is in deg/s but mapped as rad/s (pi/180)",
     "the table: drop its rad/s factor"),
    (1.0, 1.0 / 6.0, "table_rate_dps is in rpm (1 rpm = 6 deg/s)",
     "the table: map it with `* 6`"),
    (1.0 / 6.0, 1.0, "gyro_dps is in rpm (1 rpm = 6 deg/s)", "the gyro: map it with `* 6`"),
    (1000.0 / RAD_TO_DEG, 1.0, "gyro_dps is in mrad/s",
     "the gyro: map it with `* 0.05729577951308232` (mrad/s to deg/s)"),
    (1000.0, 1.0, "gyro_dps is in mdeg/s, or in mrad/s under a rad/s factor",
     "the gyro: map it with `* 0.001` (mdeg/s) or `* 0.05729577951308232` (mrad/s)"),
    (1.0, 1000.0, "table_rate_dps is in mdeg/s", "the table: map it with `* 0.001`"),
    (3600.0, 1.0, "gyro_dps is in deg/h", "the gyro: map it with `/ 3600`"),
    (1.0, 3600.0, "table_rate_dps is in deg/h", "the table: map it with `/ 3600`"),
)
INVERTED_FIX = ('the table\'s sign: `table_rate_dps = "-table_rate_dps"` in fogsf-columns.toml '
                "(the log's own table column after the minus); a gyro mounted upside down "
                "sees the earth rate negated too (--axis-cosine -1, or a negative "
                "earth_rate_dps)")
UNITS_FIX = ("gyro_dps and table_rate_dps are in deg/s: a column in rad/s is mapped with "
             "`* 57.29577951308232` (a rad/s to deg/s factor), one already in deg/s without "
             "it; fix the column map (--columns or its file)")


def units_factor(ratio: float) -> str | None:
    """'180/pi' or 'pi/180' when |`ratio`| lies within UNITS_TOL of it, else None."""
    for factor, text in ((RAD_TO_DEG, "180/pi"), (1.0 / RAD_TO_DEG, "pi/180")):
        if abs(abs(ratio) / factor - 1.0) <= UNITS_TOL:
            return text
    return None


def in_band(ratio: float) -> bool:
    return SF_BAND[0] <= ratio <= SF_BAND[1]


def likely_cause(sf_ratio: np.ndarray, earth_per_table: np.ndarray
                 ) -> tuple[float, str, str] | None:
    """(the SF ratio the cause leaves, cause, fix) of the cause (CAUSES, each also with the
    axis inverted) that explains the windows best, or None when none brings them into
    SF_BAND. `earth_per_table` per window: the earth rate taken out (deg/s) over the table
    rate; a gyro in g x deg/s read (g - 1) x that much too little of it."""
    best: tuple[float, str, str] | None = None
    for sign in (1.0, -1.0):
        for g0, t, cause, fix in ((1.0, 1.0, "", ""), *CAUSES):
            g = sign * g0
            with np.errstate(all="ignore"):
                sf = float(np.median((sf_ratio - (g - 1.0) * earth_per_table) * t / g))
            if not (np.isfinite(sf) and in_band(sf)):
                continue
            if sign < 0:
                cause = f"{cause + ', and ' if cause else ''}the axis is inverted (the gyro " \
                        "reads minus the table rate)"
                fix = f"{fix + '; ' if fix else ''}{INVERTED_FIX}"
            if best is None or abs(np.log(sf)) < abs(np.log(best[0])):
                best = (sf, cause, fix)
    return best


def check_units(log: ChamberLog, sf_ratio: np.ndarray, starts: np.ndarray,
                earth_per_table: np.ndarray | None = None, raw: bool = True) -> None:
    """Refuse a log (`raw`: its uncorrected windows) whose SF ratio lies outside SF_BAND,
    naming the likely cause; and one whose windows jump by a rad/s - deg/s factor mid-log
    (the units switched), at the line of the first window off. `earth_per_table` per window:
    the earth rate taken out over the table rate (None: 0)."""
    if not sf_ratio.size:
        return
    q = np.zeros_like(sf_ratio) if earth_per_table is None else earth_per_table
    med = float(np.median(sf_ratio))
    if raw and not in_band(med):
        cause = likely_cause(sf_ratio, q)
        if cause is not None or not WIDE_BAND[0] <= med <= WIDE_BAND[1]:
            raise UserError(units_refusal(log.path, med, cause))
    for i, r in enumerate(sf_ratio):
        factor = _switched(float(r), float(q[i]), med)
        if factor is not None:
            normal = np.flatnonzero(np.abs(sf_ratio[:i] / med - 1.0) <= UNITS_TOL)
            lo = int(starts[normal[-1]]) if normal.size else 0  # the last window in the unit
            row = _switch_row(log, lo, int(starts[i]), med, factor)
            raise LogError(log.path, row + 2, "units switch",
                           f"the SF ratio jumps from {med:.6g} to {float(r):.6g} "
                           f"({factor}): the gyro or the table switched between rad/s and "
                           "deg/s mid-log; write the log in one unit")


def units_refusal(path: str, med: float, cause: tuple[float, str, str] | None) -> str:
    """The one line that refuses an SF ratio `med` outside SF_BAND."""
    head = (f"{path}: units: the gyro reads {med:.6g} x the table rate (the median SF "
            f"ratio of its windows; a gyro scaled with its nominal SF reads "
            f"{SF_BAND[0]:g} .. {SF_BAND[1]:g})")
    if cause is None:
        return (f"{head}: another unit or scaling (not rad/s, mrad/s, mdeg/s, deg/h or rpm, "
                "nor an inverted axis): check gyro_dps and table_rate_dps in the column "
                "map (--columns or its file); both are deg/s")
    sf, why, fix = cause
    return f"{head}: {why} (that leaves an SF ratio of {sf:.6g}); fix {fix}"


def _switched(r: float, q: float, med: float) -> str | None:
    """'pi/180' when window ratio `r` is the gyro switched to rad/s (the earth rate taken
    out in rad/s: `q` its share per table rate), '180/pi' when the table switched (or the
    gyro from rad/s), from the log's `med`; else None."""
    if med == 0:
        return None
    k = 1.0 / RAD_TO_DEG
    if abs((r - (k - 1.0) * q) / k / med - 1.0) <= UNITS_TOL or abs(r / k / med - 1.0) \
            <= UNITS_TOL:
        return "pi/180"
    if abs(r / RAD_TO_DEG / med - 1.0) <= UNITS_TOL:
        return "180/pi"
    return None


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
