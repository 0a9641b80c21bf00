"""The first bad row of a log, found line by line: what the general path refuses in the
cells of a file, without holding the file's text.

When the fast reader (logs/arrow_csv.py) cannot read a file whose header is good, this scan
walks its data lines with the general path's rules (logio's `_find_bad_cell`, then the first
non-finite cell) and gives the same one-line refusal, naming the same line, in bounded
memory. It gives None where it cannot be sure of that refusal (the file is not UTF-8, a
cell that Python's float() reads but numpy's parser does not, a quote anywhere): the
general path then reads the file and decides.
"""

from __future__ import annotations

import math
from pathlib import Path

from fogsf.trainer.logs.chamber_log import LogError
from fogsf.trainer.logs.dialect import DECIMAL_COMMA


def _ascii_number(cell: str) -> bool:
    """A cell float() and numpy's parser both read (float() also takes 1_000 and
    non-ASCII digits, which numpy refuses)."""
    return cell.isascii() and "_" not in cell


def first_bad_line(path: str | Path, header: list[str], delim: str, decimal_comma: bool,
                   rows_ok: int = 0) -> LogError | None:
    """The refusal the general path gives for the data lines of an unquoted file whose
    header is `header`, or None (no bad cell found, or not sure: see the module). The first
    `rows_ok` lines that are not blank are known to hold finite numbers of the header's
    length (the fast reader read them): only blank lines among them are looked for."""

    p = str(path)
    first_bad: LogError | None = None
    non_finite: LogError | None = None
    blank_run: list[int] = []  # blank lines not yet known to lie inside (not at the end)
    try:
        with open(path, encoding="utf-8") as f:
            f.readline()  # the header
            for i, raw in enumerate(f, start=2):
                if '"' in raw:  # quoted cells: the general path reads every line as CSV
                    return None
                if first_bad is not None:
                    continue  # read on: not UTF-8 or quoted, the general path decides
                line = raw.rstrip("\n")
                if not line.strip():
                    blank_run.append(i)
                    continue
                if blank_run:  # a blank line inside the data: the first is refused
                    first_bad = bad_cell_in("", blank_run[0], header, p, delim)
                    if first_bad is not None:
                        continue
                    blank_run = []
                if rows_ok > 0:
                    rows_ok -= 1
                    continue
                if decimal_comma:
                    line = line.replace(",", ".")
                first_bad = bad_cell_in(line, i, header, p, delim)
                if first_bad is not None:
                    continue
                for name, cell in zip(header, line.split(delim), strict=True):
                    if not _ascii_number(cell):
                        return None
                    if non_finite is None and not math.isfinite(float(cell)):
                        non_finite = LogError(p, i, "non-finite cell",
                                              f"column {name!r} is {cell.strip()!r}")
    except (OSError, UnicodeDecodeError):
        return None
    return first_bad or non_finite


def bad_cell_in(line: str, i: int, header: list[str], path: str, delim: str = ","
                ) -> LogError | None:
    """The refusal of data line `i` (`line`) when it has another number of cells than the
    header or a cell that is not a number; None when it parses."""
    cells = line.split(delim)
    if len(cells) != len(header):
        hint = (" (decimal commas? then separate cells by ';' or tab and give "
                "--decimal-comma)" if delim == "," and len(cells) > len(header) else "")
        return LogError(path, i, "wrong number of cells",
                        f"{len(cells)} cells, header has {len(header)}{hint}")
    for name, cell in zip(header, cells, strict=True):
        try:
            float(cell)
        except ValueError:
            shown = cell.strip() or "(empty)"
            hint = (" (a decimal comma: give --decimal-comma)"
                    if DECIMAL_COMMA.match(cell) and delim != "," else "")
            return LogError(path, i, "non-numeric cell",
                            f"column {name!r} is {shown!r}{hint}")
    return None
