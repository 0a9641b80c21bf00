"""What each column of a CSV log holds, from its first data row: numbers, ISO-8601 time
stamps (read as epoch seconds, UTC) or text (docs/logs.md, "Raw logger output").

Loggers write more than numbers: a ROS export's `header.frame_id` (`base_link`), a chamber
logger's wall-clock stamp (`2026-03-04T09:15:02.123`). A column of text the column map does
not read is left out (said on stderr); one it reads is refused, naming it. A column of
ISO-8601 stamps is read as seconds since 1970-01-01 UTC (a stamp without a UTC offset is
taken as UTC), wherever a time is: `time_s = "wall"`, or in an expression.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime

import numpy as np

NUMBER, ISO_TIME, TEXT = "number", "iso", "text"
ISO = re.compile(r"^\s*\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d+)?)?"
                 r"(Z|[+-]\d{2}:?\d{2})?\s*$")


# a number with a decimal comma (20,5): a number, which the reader refuses without
# --decimal-comma, naming the option
_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d*,\d+([eE][-+]?\d+)?\s*$")


def cell_kind(cell: str) -> str:
    """NUMBER, ISO_TIME or TEXT: what one cell holds."""
    try:
        float(cell)
        return NUMBER
    except ValueError:
        pass
    if _DECIMAL_COMMA.match(cell):
        return NUMBER
    return ISO_TIME if ISO.match(cell) else TEXT


def row_kinds(cells: list[str]) -> tuple[str, ...]:
    """The kind of each column from its cell in the first data row (an empty cell or a
    number: NUMBER, which the reader then checks on every row)."""
    return tuple(NUMBER if not c.strip() else cell_kind(c) for c in cells)


def iso_seconds(cell: str) -> float | None:
    """An ISO-8601 stamp as epoch seconds (UTC; a stamp without an offset is UTC), None when
    the cell is not one."""
    text = cell.strip()
    if not ISO.match(text):
        return None
    try:
        t = datetime.fromisoformat(text)
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=UTC)
    whole = datetime(t.year, t.month, t.day, t.hour, t.minute, t.second, tzinfo=t.tzinfo)
    return float(int(whole.timestamp())) + t.microsecond * 1e-6


def epoch_seconds_ns(ns: np.ndarray) -> np.ndarray:
    """Epoch nanoseconds (int64) as float64 seconds, the whole seconds and the fraction
    added apart (the nearest float64, as `iso_seconds` gives)."""
    ns = np.asarray(ns, dtype=np.int64)
    whole = np.floor_divide(ns, 1_000_000_000)
    frac = ns - whole * 1_000_000_000
    return whole.astype(np.float64) + (frac // 1000).astype(np.float64) * 1e-6 \
        + (frac % 1000).astype(np.float64) * 1e-9


def numeric_cells(line: str, delim: str, kinds: tuple[str, ...]) -> str | None:
    """A data line with its ISO stamps written as epoch seconds and its text cells as 0, for
    the general path's number parser; None when a stamp does not parse (the line is then
    refused as it is)."""
    if all(k == NUMBER for k in kinds):
        return line
    cells = line.split(delim)
    if len(cells) != len(kinds):
        return line
    for i, k in enumerate(kinds):
        if k == TEXT:
            cells[i] = "0"
        elif k == ISO_TIME:
            s = iso_seconds(cells[i])
            if s is None:
                return None
            cells[i] = repr(s)
    return delim.join(cells)
