"""The `[join.NAME]` tables of a column map, read and checked (what a join is; reading
and applying them: `logs.mapping.joins`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from fogsf.errors import UserError
from fogsf.logs.mapping.time_zone import parse_tz

HOW = ("interpolate", "hold")
JOIN_KEYS = ("file", "stream", "time_s", "how", "max_gap_s", "tz")


@dataclass(frozen=True)
class Join:
    """One `[join.NAME]` table: the file (with {stem}), its time and columns, how they are
    put on the main clock."""

    name: str
    file: str  # "" for a stream of a field-format log (`stream`)
    time_s: str
    columns: tuple[tuple[str, str], ...]
    how: str = "interpolate"
    max_gap_s: float | None = None
    origin: str = ""
    stream: str | None = None  # a topic, message or group of the same field-format file
    tz: str | None = None  # its time_s is local time in this zone (logs/mapping/time_zone.py)


def joins_of(table: object, origin: str, is_ours) -> tuple[Join, ...]:  # noqa: ANN001
    """The `join` table of a column map file, checked: each NAME a table with file, time_s,
    our names to the file's columns, how and max_gap_s."""
    if not isinstance(table, dict) or not table:
        raise UserError(f"{origin}: [join.NAME] tables expected under join")
    out = []
    for name, t in table.items():
        where = f"{origin}: [join.{name}]"
        if not isinstance(t, dict):
            raise UserError(f"{where}: expected a table (file = ..., time_s = ..., ...)")
        stream = t.get("stream")
        if stream is not None and (not isinstance(stream, str) or not stream.strip()):
            raise UserError(f"{where}: stream = {stream!r}: a topic, message or group name")
        if stream is None and (not isinstance(t.get("file"), str) or not t["file"].strip()):
            raise UserError(f"{where}: file = \"...\" is required (or stream = \"...\" for "
                            "a stream of the same bag, ULog or TDMS file)")
        if not isinstance(t.get("time_s"), str) or not t["time_s"].strip():
            raise UserError(f"{where}: time_s = \"...\" is required")
        how = t.get("how", "interpolate")
        if how not in HOW:
            raise UserError(f"{where}: how = {how!r}; allowed: {', '.join(HOW)}")
        gap = t.get("max_gap_s")
        if gap is not None and (isinstance(gap, bool) or not isinstance(gap, int | float)
                                or not math.isfinite(gap) or gap <= 0):
            raise UserError(f"{where}: max_gap_s = {gap!r}; expected seconds > 0")
        tz = t.get("tz")
        if tz is not None:
            parse_tz(tz, where)
        cols = []
        for ours, theirs in t.items():
            if ours in JOIN_KEYS:
                continue
            if ours == "time_s" or ours in ("gyro_dps",) or not is_ours(ours):
                raise UserError(f"{where}: {ours!r} is not a name a join may give (the "
                                "format's names but time_s and gyro_dps)")
            if isinstance(theirs, bool) or not isinstance(theirs, str | int | float):
                raise UserError(f"{where}: {ours} = {theirs!r}: a column or an expression")
            cols.append((ours, theirs if isinstance(theirs, str) else repr(theirs)))
        if not cols:
            raise UserError(f"{where}: names no column to join (e.g. temp_c = \"board_T\")")
        out.append(Join(str(name), t.get("file", ""), t["time_s"], tuple(cols), how,
                        None if gap is None else float(gap), origin, stream, tz))
    return tuple(out)


def join_names(joins: tuple[Join, ...]) -> list[str]:
    return [ours for j in joins for ours, _ in j.columns]
