"""`--bad-cells skip` (docs/logs.md, "What the reader refuses"): a cell that holds no number
(`ERR`, `NaN`, `inf`, an empty cell) makes its row measure nothing instead of refusing the
file. The cell is filled with the line between its column's good cells around it (before the
first or after the last: on from it by the column's median step per row, so that a time
stamp at the file's edge goes on increasing), so that the model runs over the row as
firmware would over a sample it could not use; the row gives no SF, no training target and
no metric (`valid` 0). A row of another length is still refused: its cells cannot be told
apart.
"""

from __future__ import annotations

import math

import numpy as np

from fogsf.logs.chamber_log import LogError
from fogsf.logs.read.line_scan import bad_cell_in

BAD_CELLS = ("refuse", "skip")
# the refusals --bad-cells skip turns into rows that measure nothing
SKIPPABLE = ("non-numeric cell", "non-finite cell")


def _number(cell: str) -> float:
    try:
        v = float(cell)
    except ValueError:
        return math.nan
    return v if math.isfinite(v) else math.nan


def numbers_skipping_bad(lines: list[str], header: list[str], path: str, delim: str
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(the data rows as float64 [rows, columns], True per row with a cell that held no
    number); each such cell filled by the line between its column's good cells. A row of
    another length, or a column without one number, is refused."""
    rows = []
    for i, line in enumerate(lines[1:], start=2):
        cells = line.split(delim)
        if len(cells) != len(header):
            bad = bad_cell_in(line, i, header, path, delim)
            assert bad is not None  # another number of cells is always refused
            raise bad
        rows.append([_number(c) for c in cells])
    data = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(header))
    bad_cell = np.isnan(data)
    at = np.arange(data.shape[0], dtype=np.float64)
    for c in np.flatnonzero(bad_cell.any(axis=0)):
        good = ~bad_cell[:, c]
        if not good.any():
            raise LogError(path, None, "non-numeric cell",
                           f"column {header[c]!r} holds no number on any row")
        data[~good, c] = _filled(at, good, data[:, c])[~good]
    return data, np.asarray(bad_cell.any(axis=1), dtype=bool)


def _filled(at: np.ndarray, good: np.ndarray, v: np.ndarray) -> np.ndarray:
    """`v` at rows `at` from its `good` cells: the line between them inside, the median step
    per row on from the first or last beyond them."""
    x, y = at[good], v[good]
    out = np.interp(at, x, y)
    slope = float(np.median(np.diff(y) / np.diff(x))) if x.size > 1 else 0.0
    ends = (at < x[0]) | (at > x[-1])
    edge = np.where(at < x[0], x[0], x[-1])
    out[ends] = np.where(at < x[0], y[0], y[-1])[ends] + slope * (at - edge)[ends]
    return out


def skipped_note(skipped: np.ndarray) -> str:
    """What --bad-cells skip did, for the notes on stderr."""
    rows = np.flatnonzero(skipped)
    one = rows.size == 1
    return (f"{rows.size} row{'' if one else 's'} with a cell that holds no number (the first "
            f"at line {int(rows[0]) + 2}) measure{'s' if one else ''} nothing (--bad-cells skip)")
