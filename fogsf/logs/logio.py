"""Reading chamber logs (docs/logs.md), with every refusal it lists.

A log is one gyro run in the chamber at a constant sample rate between 1 Hz and 4 kHz (the
paper's rigs log at 10 Hz; gyro firmware runs at its output rate). The nominal rate is the
median step of time_s, or `--sample-rate-hz` when given; every step must lie within
DT_TOLERANCE (20 %) of it. Reading never fixes or drops anything: a bad file is refused
with one `LogError` that names the file, the line, the rule and, where one exists, the
option that fixes it. How the file writes the format (delimiter, column names, quotes,
decimal commas) is its `Dialect` (logs/read/dialect.py); every column of the file is parsed as
numbers, then ours are built from them by the column map (logs/mapping/column_map.py: renames,
numbers, expressions of logs/mapping/expressions.py; --gyro-column / --axis); the log in memory is
a `ChamberLog` (logs/chamber_log.py). The fast path parses a file with pyarrow's CSV reader
straight from disk (logs/read/arrow_csv.py: any delimiter, quoted cells, decimal commas); a file
it cannot read as numbers takes the general path, which names the offending line. Both
apply the same column map, and the columns become a validated log in logs/validation.py;
logs/writer.py writes a log.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.mapping.column_map import ColumnPlan, with_kinds
from fogsf.logs.mapping.layout import SUPPORTED
from fogsf.logs.read.arrow_csv import NotFast, read_numbers
from fogsf.logs.read.bad_cells import SKIPPABLE, numbers_skipping_bad, skipped_note
from fogsf.logs.read.cell_kinds import NUMBER, TEXT, numeric_cells, row_kinds
from fogsf.logs.read.dialect import (
    Dialect,
    checked_names,
    find_delimiter,
    log_axes,
    looked_in,
    map_plan,
    mapping_beside,
    names_plan,
    raw_header,
    read_header,
    unquote_lines,
)
from fogsf.logs.read.field_formats import as_table, format_of, main_stream
from fogsf.logs.read.line_scan import SKIP_HINT, bad_cell_in, first_bad_line
from fogsf.logs.read.parquet_log import in_rows, is_parquet, parquet_names, read_parquet_log
from fogsf.logs.validation import _log_of

# a plateau table's row is a measurement of its own: nothing to fill it from
TABLE_HINT = ("; a plateau table's row is one plateau's measurement: fix or delete "
              "that row (--bad-cells skip is for sample logs)")

# the data rows a column's kind is told from (logs/read/cell_kinds.py)
SNIFF_ROWS = 100


def read_log(path: str | Path, dialect: Dialect | None = None) -> ChamberLog:
    """Read and validate a chamber log; raise LogError on the first broken rule. Without
    --columns in `dialect`, a mapping file beside the log (MAPPING_FILES) applies."""
    p = str(path)
    dialect = with_mapping_beside(path, dialect or Dialect())
    refuse_plateaus(p, dialect)
    if is_parquet(path):
        return read_parquet_log(path, dialect, _log_of)
    if format_of(path) is not None:
        return read_field_log(path, dialect)
    fast = _read_plain(path, dialect)
    if fast is not None:
        return fast
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise cannot_read(p, e) from None
    return parse_log(text, p, dialect)


def read_field_log(path: str | Path, dialect: Dialect) -> ChamberLog:
    """A field-format file's main stream (logs/read/field_formats.py) read as a log: its columns
    through the column map, as a CSV's."""
    p = str(path)
    name, stream = main_stream(path, dialect.stream, dialect.columns_from,
                               "" if dialect.columns else looked_in(p))
    names, data = as_table(stream)
    notes = [f"{format_of(path)} stream {name}"]
    plan = names_plan(checked_names(names, p), p, dialect, notes)
    return _log_of(data, plan, p, dialect, notes)


def cannot_read(path: str, e: OSError | UnicodeDecodeError) -> LogError:
    """The one-line refusal of a log file that cannot be opened or decoded."""
    if isinstance(e, FileNotFoundError):
        return LogError(path, None, "cannot read", "no such file")
    if isinstance(e, UnicodeDecodeError):
        return LogError(path, None, "cannot read", f"not UTF-8 text ({e.reason})")
    return LogError(path, None, "cannot read", e.strerror or str(e))


def with_mapping_beside(path: str | Path, dialect: Dialect) -> Dialect:
    """`dialect`, with the mapping file beside the log (MAPPING_FILES) when it has no
    --columns."""
    if dialect.columns:
        return dialect
    beside = mapping_beside(path)
    if beside is None:
        return dialect
    return replace(dialect, columns=Dialect.mapping_file(beside), columns_from=str(beside),
                   joins=Dialect.mapping_joins(beside), stream=Dialect.mapping_stream(beside),
                   layout=Dialect.mapping_layout(beside))


def refuse_plateaus(path: str, dialect: Dialect) -> None:
    """A plateau table (`layout = "plateaus"` in its map) read as a sample log is refused in
    one line naming what reads it: its rows are means, not samples, and a sample log's rules
    (sample rate, windows) would refuse it obscurely or measure nonsense."""
    if dialect.layout is not None:
        raise LogError(path, None, "a plateau table",
                       f"layout = \"plateaus\" ({dialect.layout.origin}): {SUPPORTED}")


def log_axes_of(path: str | Path, dialect: Dialect) -> list[str]:
    """The axes A of a log (what `--axis all` runs over): its gyro_A_dps columns and those
    its column map gives (--columns, or the mapping file beside it), in header order, then
    the map's; [] for a log of one gyro (gyro_dps). Reads the header line only (a bad
    header or map is refused as read_log refuses it); --gyro-column and --axis are
    ignored."""
    p = str(path)
    dialect = with_mapping_beside(path, dialect)
    if is_parquet(path):
        return log_axes(in_rows(p, lambda: map_plan(parquet_names(path), dialect, p, [])).names)
    if format_of(path) is not None:
        names = list(main_stream(path, dialect.stream, dialect.columns_from)[1])
        return log_axes(map_plan(names, dialect, p, []).names)
    try:
        with open(path, encoding="utf-8-sig") as f:
            first = f.readline().rstrip("\r\n")
    except (OSError, UnicodeDecodeError) as e:
        raise cannot_read(p, e) from None
    if not first.strip():
        raise LogError(p, 1, "empty file", "no header row")
    notes: list[str] = []
    delim = find_delimiter(first, p, dialect, notes)
    if '"' in first:
        first = unquote_lines([first], delim, p)[0]
    return log_axes(map_plan(raw_header(first, delim, p), dialect, p, notes).names)


def parse_log(text: str, path: str = "<memory>", dialect: Dialect | None = None,
              build: Callable[..., object] = _log_of) -> ChamberLog:
    """A log's text read through `dialect`; `build` makes the result from the parsed cells,
    the plan, the path, the dialect and the notes (a plateau table's reader gives its own)."""
    dialect = dialect or Dialect()
    notes: list[str] = []
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark: encoding, not data
        text = text[1:]
        notes.append("UTF-8 byte-order mark skipped")
    # lines end at \n (as numpy's reader ends them; open() already turned \r\n and \r into it)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines or not lines[0].strip():
        raise LogError(path, 1 if lines else None, "empty file", "no header row")
    delim = find_delimiter(lines[0], path, dialect, notes)
    if '"' in text:
        lines = unquote_lines(lines, delim, path)
        notes.append('quoted cells read as CSV ("...")')
    plan = read_header(lines[0], delim, path, dialect, notes)
    if len(lines) < 2:
        raise LogError(path, 1, "empty file", "a header but no data rows")
    if dialect.decimal_comma:
        lines = [lines[0], *(line.replace(",", ".") for line in lines[1:])]
    first = [ln.split(delim) for ln in lines[1:1 + SNIFF_ROWS]]
    plan = with_kinds(plan, sniffed_kinds(first), path, notes)
    if plan.kinds:
        kinds = plan.kinds
        lines = [lines[0], *((numeric_cells(line, delim, kinds) or line) for line in lines[1:])]
    try:
        data = _parse_numbers(lines, list(plan.raw), path, delim)
    except LogError as e:
        if e.rule in SKIPPABLE and build is not _log_of:  # a table's row is one measurement
            raise LogError(e.path, e.line, e.rule, e.detail.replace(SKIP_HINT, TABLE_HINT)
                           ) from None
        if dialect.bad_cells != "skip" or e.rule not in SKIPPABLE:
            raise
        data, skipped = numbers_skipping_bad(lines, list(plan.raw), path, delim)
        notes.append(skipped_note(skipped))
        return _log_of(data, plan, path, dialect, notes, skipped)
    return build(data, plan, path, dialect, notes)  # type: ignore[return-value]


def _read_plain(path: str | Path, dialect: Dialect) -> ChamberLog | None:
    """The fast path for large logs: the header line, then pyarrow's CSV reader straight from
    the file, block by block (logs/read/arrow_csv.py). None when the file needs the general path,
    which names the line: a cell that is not a finite number, a row of another length, a
    blank line inside (blank lines at the end are dropped, as every reader does), quotes in
    the data rows of a file whose header has none, a quoted file whose header is refused
    (the general path checks the quoting of every line first)."""
    p = str(path)
    head = plain_header(path, dialect)
    if head is None:
        return None
    delim, quoted, plan, notes = head
    rows = _data_lines(path)
    if rows < 1:
        return None
    try:
        data = read_numbers(path, rows, delim, len(plan.raw), quoted, dialect.decimal_comma,
                            plan.kinds)
    except NotFast as e:
        refuse_bad_line(path, head, dialect, e.rows_ok)
        return None
    return _log_of(data, plan, p, dialect, notes)


PlainHeader = tuple[str, bool, ColumnPlan, list[str]]


def plain_header(path: str | Path, dialect: Dialect) -> PlainHeader | None:
    """(delimiter, quoted, plan, notes) from the header line of a log the fast path may
    read; None when the general path must read it (not UTF-8, no header, a quoted header it
    refuses)."""
    p = str(path)
    try:
        with open(path, encoding="utf-8") as f:
            first = f.readline()
    except (OSError, UnicodeDecodeError):
        return None
    notes: list[str] = []
    if first.startswith("\ufeff"):  # a UTF-8 byte-order mark: encoding, not data
        first = first[1:]
        notes.append("UTF-8 byte-order mark skipped")
    first = first.rstrip("\r\n")
    if not first.strip():
        return None
    delim = find_delimiter(first, p, dialect, notes)
    quoted = '"' in first
    if quoted:
        try:
            first = unquote_lines([first], delim, p)[0]
            notes.append('quoted cells read as CSV ("...")')
            plan = read_header(first, delim, p, dialect, notes)
        except LogError:
            return None
    else:
        plan = read_header(first, delim, p, dialect, notes)
    kinds = first_row_kinds(path, delim, quoted, dialect.decimal_comma)
    if kinds is not None and len(kinds) == len(plan.raw):
        plan = with_kinds(plan, kinds, p, notes)
    return delim, quoted, plan, notes


def first_row_kinds(path: str | Path, delim: str, quoted: bool, decimal_comma: bool
                    ) -> tuple[str, ...] | None:
    """What each column of the first data rows holds (`sniffed_kinds`); None when there is
    no such row or the first cannot be read."""
    rows: list[list[str]] = []
    try:
        with open(path, encoding="utf-8-sig") as f:
            f.readline()
            for _ in range(SNIFF_ROWS):
                line = f.readline().rstrip("\r\n")
                if not line.strip():
                    break
                if quoted:
                    line = unquote_lines([line], delim, str(path))[0]
                if decimal_comma:
                    line = line.replace(",", ".")
                rows.append(line.split(delim))
    except (OSError, UnicodeDecodeError, LogError):
        pass  # the rows read so far tell
    return sniffed_kinds(rows) if rows else None


def sniffed_kinds(rows: list[list[str]]) -> tuple[str, ...]:
    """What each column holds, from the first data rows `rows`: the kind of its first cell
    that holds a number or a time stamp, so that a bad cell (`ERR`) in the first row is a bad
    cell; TEXT when no cell does; rows of another length than the first are not read."""
    kinds = list(row_kinds(rows[0]))
    for c, k in enumerate(kinds):
        if k != TEXT and rows[0][c].strip():
            continue
        told = [row_kinds([r[c]])[0] for r in rows[1:]
                if len(r) == len(rows[0]) and r[c].strip()]
        kinds[c] = next((x for x in told if x != TEXT), TEXT if k == TEXT or told else NUMBER)
    return tuple(kinds)


def refuse_bad_line(path: str | Path, head: PlainHeader, dialect: Dialect, rows_ok: int
                    ) -> None:
    """After the fast reader failed: the refusal of the first bad row, named reading line by
    line (no copy of the text); returns when the general path must decide."""
    delim, quoted, plan, _ = head
    bad = first_bad_line(path, list(plan.raw), delim, dialect.decimal_comma, rows_ok, quoted,
                         plan.kinds)
    if bad is not None and not (dialect.bad_cells == "skip" and bad.rule in SKIPPABLE):
        raise bad from None


def _data_lines(path: str | Path) -> int:
    """Lines after the header, read in chunks: a last line without its newline counts, blank
    lines at the end (which every reader drops) do not."""
    n, tail = 0, b""
    with open(path, "rb") as f:
        while chunk := f.read(1 << 24):
            n += chunk.count(b"\n")
            tail = (tail + chunk)[-4096:]
    blank_end = tail[len(tail.rstrip(b" \t\r\n")):]
    return n - 1 - blank_end.count(b"\n") + 1


def _parse_numbers(lines: list[str], header: list[str], path: str, delim: str = ","
                   ) -> np.ndarray:
    ncol = len(header)
    try:
        data = np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=delim, dtype=np.float64,
                          ndmin=2, comments=None)
    except ValueError:
        data = None
    if data is None or data.shape[1] != ncol or data.shape[0] != len(lines) - 1:
        _find_bad_cell(lines, header, path, delim)
        raise LogError(path, None, "unreadable", "numbers could not be parsed")  # unreachable
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise LogError(path, int(r) + 2, "non-finite cell",
                       f"column {header[c]!r} is {lines[r + 1].split(delim)[c].strip()!r}"
                       f"{SKIP_HINT}")
    return data


def _find_bad_cell(lines: list[str], header: list[str], path: str, delim: str = ","
                   ) -> None:
    """The slow path: walk rows to name the first one that does not parse."""
    for i, line in enumerate(lines[1:], start=2):
        err = bad_cell_in(line, i, header, path, delim)
        if err is not None:
            raise err
