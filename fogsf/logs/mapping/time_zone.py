"""Local clocks: a join's `tz = "Europe/Berlin"` (or a fixed offset, "+01:00") says its time
stamps are local time there, not UTC (a chamber logger's wall clock); they are put on UTC
stamp by stamp (summer time included) before the join. A stream whose both ends lie the same
whole number of hours off the log's is a time zone read as UTC: refused, naming `tz`, unless
--allow-clock-offset."""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime, timedelta, timezone, tzinfo

import numpy as np

from fogsf.errors import UserError

OFFSET = re.compile(r"^(?:UTC)?([+-])(\d{1,2})(?::?(\d{2}))?$")
HOUR_S = 3600.0


def parse_tz(text: object, where: str) -> tzinfo:
    """`tz` of a join: an IANA zone name or an offset (+01:00, -0530, UTC+2), refused in
    one line otherwise."""
    if not isinstance(text, str) or not text.strip():
        raise UserError(f"{where}: tz = {text!r}: a time zone (\"Europe/Berlin\") or an offset "
                        "(\"+01:00\")")
    m = OFFSET.match(text.strip())
    if m:
        sign = -1 if m.group(1) == "-" else 1
        h, mins = int(m.group(2)), int(m.group(3) or 0)
        if h > 14 or mins >= 60:
            raise UserError(f"{where}: tz = {text!r}: an offset is -14:00 .. +14:00")
        return timezone(sign * timedelta(hours=h, minutes=mins))
    from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

    try:
        return ZoneInfo(text.strip())
    except (ZoneInfoNotFoundError, ValueError):
        raise UserError(f"{where}: tz = {text!r}: no such time zone (an IANA name such as "
                        "\"Europe/Berlin\", or an offset such as \"+01:00\")") from None


def local_to_utc(t_s: np.ndarray, tz: tzinfo) -> np.ndarray:
    """Epoch seconds of local wall-clock stamps `t_s` (read as if UTC) in zone `tz`: each
    less its zone's UTC offset at that time. The offset is looked up once an hour of stamps
    (zones change offset on the hour or half hour, never between)."""
    if isinstance(tz, timezone):
        off: timedelta | None = tz.utcoffset(None)
        return t_s - (0.0 if off is None else off.total_seconds())
    half_hours = np.floor(t_s / 1800.0)
    keys, inverse = np.unique(half_hours, return_inverse=True)
    offsets = np.empty(keys.size)
    for i, k in enumerate(keys):
        wall = datetime.fromtimestamp(float(k) * 1800.0, UTC).replace(tzinfo=tz)
        off = wall.utcoffset()
        offsets[i] = 0.0 if off is None else off.total_seconds()
    return t_s - offsets[inverse]


def whole_hours_off(start_off_s: float, end_off_s: float, tol_s: float) -> int | None:
    """The number of hours both ends of a stream lie off the log's (the same, within
    `tol_s`), when it is not 0; else None."""
    h = round(start_off_s / HOUR_S)
    if h == 0 or not math.isfinite(start_off_s) or not math.isfinite(end_off_s):
        return None
    if abs(start_off_s - h * HOUR_S) <= tol_s and abs(end_off_s - h * HOUR_S) <= tol_s:
        return int(h)
    return None
