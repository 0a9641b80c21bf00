"""The units check of the SF windows: a gyro that reads 180/pi (or pi/180) times its table
rate has one of gyro_dps and table_rate_dps in rad/s and the other in deg/s, and is refused;
so is a log whose windows jump by such a factor mid-log (the units switched), at the line
where they switch."""

from __future__ import annotations

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, LogError

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
