"""The first bad row of a log, found line by line: what the general path refuses in the
cells of a file, without holding the file's text.

When the fast reader (logs/read/arrow_csv.py) cannot read a file whose header is good, this scan
walks its data lines with the general path's rules (logio's `_find_bad_cell`, then the first
non-finite cell) and gives the same one-line refusal, naming the same line, in bounded
memory. It gives None where it cannot be sure of that refusal (the file is not UTF-8, a
cell that Python's float() reads but numpy's parser does not, a quote anywhere): the
general path then reads the file and decides.
"""

from __future__ import annotations

import math
from pathlib import Path

from fogsf.logs.chamber_log import LogError
from fogsf.logs.read.cell_kinds import numeric_cells
from fogsf.logs.read.dialect import DECIMAL_COMMA, delimiter_in_cell

SKIP_HINT = "; --bad-cells skip makes such a row measure nothing"


def _ascii_number(cell: str) -> bool:
    """A cell float() and numpy's parser both read (float() also takes 1_000 and
    non-ASCII digits, which numpy refuses)."""
    return cell.isascii() and "_" not in cell


def first_bad_line(path: str | Path, header: list[str], delim: str, decimal_comma: bool,
                   rows_ok: int = 0, quoted: bool = False, kinds: tuple[str, ...] = ()
                   ) -> LogError | None:
    """The refusal the general path gives for the data lines of a file whose header is
    `header`, or None (no bad cell found, or not sure: see the module). The first
    `rows_ok` lines that are not blank are known to hold finite numbers of the header's
    length (the fast reader read them): only blank lines among them are looked for. A
    `quoted` file is read twice: its quoting first (the general path checks every line's
    before any cell), then its cells, each row unquoted as the general path unquotes it."""
    p = str(path)
    try:
        if quoted:
            bad_quote = _first_bad_quoting(p, delim)
            if bad_quote is not None:
                return bad_quote
            with open(path, encoding="utf-8") as f:
                return _scan(_unquoted_rows(f, delim), p, header, delim, decimal_comma,
                             rows_ok, quoted, kinds)
        with open(path, encoding="utf-8") as f:
            f.readline()  # the header
            return _scan(_plain_rows(f), p, header, delim, decimal_comma, rows_ok, quoted,
                         kinds)
    except (OSError, UnicodeDecodeError):
        return None


def _first_bad_quoting(path: str, delim: str) -> LogError | None:
    """dialect.unquote_lines' refusal over the whole file, read row by row; None if none."""
    import csv

    with open(path, encoding="utf-8-sig") as f:
        reader = csv.reader((line.rstrip("\n") for line in f), delimiter=delim, strict=True)
        try:
            for i, row in enumerate(reader, start=1):
                bad = delimiter_in_cell(row, i, delim, path)
                if bad is not None:
                    return bad
        except csv.Error as e:
            return LogError(path, reader.line_num, "bad quoting", str(e))
    return None


def _unquoted_rows(f, delim: str):  # noqa: ANN001, ANN202 - a text file; (row, line, blank)
    """The data rows unquoted; a row is blank when its line in the file is (`"  "` is not:
    the general path drops blank lines at the end before it unquotes)."""
    import csv

    raw: list[str] = []

    def lines():  # noqa: ANN202
        for line in f:
            raw.append(line)
            yield line.rstrip("\n")

    reader = csv.reader(lines(), delimiter=delim, strict=True)
    next(reader, None)  # the header
    for i, row in enumerate(reader, start=2):
        yield i, delim.join(row) + "\n", not raw[-1].strip()
        raw.clear()


def _plain_rows(f):  # noqa: ANN001, ANN202 - a text file; (line number, line, blank)
    for i, line in enumerate(f, start=2):
        yield i, line, not line.strip()


def _scan(lines, p: str, header: list[str], delim: str,  # noqa: ANN001 - (number, line)
          decimal_comma: bool, rows_ok: int, quoted: bool, kinds: tuple[str, ...] = ()
          ) -> LogError | None:
    first_bad: LogError | None = None
    non_finite: LogError | None = None
    blank_run: list[int] = []  # blank lines not yet known to lie inside (not at the end)
    for i, raw, blank in lines:
        if not quoted and '"' in raw:  # quotes in the data only: the general path decides
            return None
        if first_bad is not None:
            continue  # read on: not UTF-8 or quoted, the general path decides
        line = raw.rstrip("\n")
        if blank:
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
        if kinds:
            line = numeric_cells(line, delim, kinds) or line
        first_bad = bad_cell_in(line, i, header, p, delim)
        if first_bad is not None:
            continue
        for name, cell in zip(header, line.split(delim), strict=True):
            if not _ascii_number(cell):
                return None
            if non_finite is None and not math.isfinite(float(cell)):
                non_finite = LogError(p, i, "non-finite cell",
                                      f"column {name!r} is {cell.strip()!r}{SKIP_HINT}")
    return first_bad or non_finite


def bad_cell_in(line: str, i: int, header: list[str], path: str, delim: str = ",",
                skip_hint: bool = True) -> LogError | None:
    """The refusal of data line `i` (`line`) when it has another number of cells than the
    header or a cell that is not a number (naming --bad-cells unless not `skip_hint`: a
    joined stream); None when it parses."""
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
                            f"column {name!r} is {shown!r}{hint}"
                            f"{SKIP_HINT if skip_hint and not hint else ''}")
    return None
