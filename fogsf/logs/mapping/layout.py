"""The layout keys of a column map file (docs/logs.md, "Plateau tables"): `layout =
"plateaus"` says the log's rows are plateau means, not samples; `time_is` ("start" or
"middle") says which instant a `time_s` column gives; `plateau_s` is every plateau's length
when the table has neither `time_s` nor `duration_s`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from fogsf.errors import UserError

LAYOUT_KEYS = ("layout", "time_is", "plateau_s")
LAYOUTS = ("samples", "plateaus")
TIME_IS = ("start", "middle")
# the names a plateau table's map may give beyond a sample log's: a plateau's length
PLATEAU_NAMES = ("duration_s",)
# a plateau table needs no time column (duration_s or plateau_s may stand for it)
PLATEAU_REQUIRED = ("temp_c", "table_rate_dps", "gyro_dps")
SUPPORTED = ("`fogsf inspect`, `train`, `replay`, `diagnose` and `fleet add` read plateau "
             "tables; plan takes sample logs (docs/logs.md, \"Plateau tables\")")


@dataclass(frozen=True)
class PlateauLayout:
    """A plateau table's layout keys, from the map file `origin`."""

    origin: str
    time_is: str | None = None  # what a time_s column gives: a plateau's "start" or "middle"
    plateau_s: float | None = None  # every plateau's length (s), for a table without times


def layout_of(m: dict, origin: str) -> PlateauLayout | None:
    """The layout keys of a map file's table `m`; None for a sample log (no `layout`, or
    "samples"). A key that only a plateau table takes, on a sample log, is refused: it would
    be silently ignored."""
    layout = m.get("layout", "samples")
    if layout not in LAYOUTS:
        raise UserError(f"{origin}: layout = {layout!r}: \"samples\" (the default: a row per "
                        "sample) or \"plateaus\" (a row per rate plateau)")
    given = [k for k in ("time_is", "plateau_s") if k in m]
    if layout == "samples":
        if given:
            raise UserError(f"{origin}: {given[0]} is a plateau table's key: add "
                            "layout = \"plateaus\" (docs/logs.md, \"Plateau tables\")")
        return None
    time_is = m.get("time_is")
    if time_is is not None and time_is not in TIME_IS:
        raise UserError(f"{origin}: time_is = {time_is!r}: \"start\" or \"middle\" (the "
                        "instant of its plateau a row's time_s gives)")
    plateau_s = m.get("plateau_s")
    if plateau_s is not None and (isinstance(plateau_s, bool)
                                  or not isinstance(plateau_s, int | float)
                                  or not math.isfinite(plateau_s) or plateau_s <= 0):
        raise UserError(f"{origin}: plateau_s = {plateau_s!r}: a plateau's length in seconds, "
                        "a positive number")
    return PlateauLayout(origin, time_is, None if plateau_s is None else float(plateau_s))
