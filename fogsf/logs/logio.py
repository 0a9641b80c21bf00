"""Reading and writing chamber logs (docs/logs.md), with every refusal it lists.

A log is one gyro run in the chamber at a constant sample rate between 1 Hz and 4 kHz (the
paper's rigs log at 10 Hz; gyro firmware runs at its output rate). The nominal rate is the
median step of time_s, or `--sample-rate-hz` when given; every step must lie within
DT_TOLERANCE (20 %) of it. Reading never fixes or drops anything: a bad file is refused
with one `LogError` that names the file, the line, the rule and, where one exists, the
option that fixes it. How the file writes the format (delimiter, column names, quotes,
decimal commas) is its `Dialect` (logs/dialect.py); every column of the file is parsed as
numbers, then ours are built from them by the column map (logs/column_map.py: renames,
numbers, expressions of logs/expressions.py; --gyro-column / --axis); the log in memory is
a `ChamberLog` (logs/chamber_log.py). The fast path parses a file with pyarrow's CSV reader
straight from disk (logs/arrow_csv.py: any delimiter, quoted cells, decimal commas); a file
it cannot read as numbers takes the general path, which names the offending line. Both
apply the same column map.
"""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path

import numpy as np

from fogsf.logs.arrow_csv import NotFast, read_numbers
from fogsf.logs.cell_kinds import numeric_cells, row_kinds
from fogsf.logs.chamber_log import (
    DT_TOLERANCE,
    EPOCH_S,
    NOMINAL_DT_S,
    RATE_RANGE_HZ,
    RATE_SLACK,
    REQUIRED,
    TEMP_RANGE_C,
    ChamberLog,
    LogError,
    check_rate_hz,
    epoch_text,
    is_temperature,
    nominal_step_s,
    rate_text,
    time_text,
)
from fogsf.logs.column_map import ColumnPlan, with_kinds
from fogsf.logs.columns import Column, blocks, col_max, col_min, derived, is_lazy
from fogsf.logs.dialect import (
    Dialect,
    checked_names,
    find_delimiter,
    log_axes,
    map_plan,
    mapping_beside,
    names_plan,
    raw_header,
    read_header,
    unquote_lines,
)
from fogsf.logs.field_formats import as_table, format_of, main_stream
from fogsf.logs.joins import apply_joins
from fogsf.logs.line_scan import bad_cell_in, first_bad_line
from fogsf.logs.parquet_log import (
    in_rows,
    is_parquet,
    parquet_names,
    read_parquet_log,
    write_columns,
)
from fogsf.logs.sampling import default_max_gap_s, mend_segments, survey


def read_log(path: str | Path, dialect: Dialect | None = None) -> ChamberLog:
    """Read and validate a chamber log; raise LogError on the first broken rule. Without
    --columns in `dialect`, a mapping file beside the log (MAPPING_FILES) applies."""
    p = str(path)
    dialect = with_mapping_beside(path, dialect or Dialect())
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
    """A field-format file's main stream (logs/field_formats.py) read as a log: its columns
    through the column map, as a CSV's."""
    p = str(path)
    name, stream = main_stream(path, dialect.stream, dialect.columns_from)
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
                   joins=Dialect.mapping_joins(beside), stream=Dialect.mapping_stream(beside))


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


def parse_log(text: str, path: str = "<memory>", dialect: Dialect | None = None
              ) -> ChamberLog:
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
    plan = with_kinds(plan, row_kinds(lines[1].split(delim)), path, notes)
    if plan.kinds:
        kinds = plan.kinds
        lines = [lines[0], *((numeric_cells(line, delim, kinds) or line) for line in lines[1:])]
    data = _parse_numbers(lines, list(plan.raw), path, delim)
    return _log_of(data, plan, path, dialect, notes)


def _read_plain(path: str | Path, dialect: Dialect) -> ChamberLog | None:
    """The fast path for large logs: the header line, then pyarrow's CSV reader straight from
    the file, block by block (logs/arrow_csv.py). None when the file needs the general path,
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
    """What each column of the first data row holds (logs/cell_kinds.py); None when there
    is no such row or it cannot be read."""
    try:
        with open(path, encoding="utf-8-sig") as f:
            f.readline()
            line = f.readline().rstrip("\r\n")
    except (OSError, UnicodeDecodeError):
        return None
    if not line.strip():
        return None
    if quoted:
        try:
            line = unquote_lines([line], delim, str(path))[0]
        except LogError:
            return None
    if decimal_comma:
        line = line.replace(",", ".")
    return row_kinds(line.split(delim))


def refuse_bad_line(path: str | Path, head: PlainHeader, dialect: Dialect, rows_ok: int
                    ) -> None:
    """After the fast reader failed: the refusal of the first bad row, named reading line by
    line (no copy of the text); returns when the general path must decide."""
    delim, quoted, plan, _ = head
    bad = first_bad_line(path, list(plan.raw), delim, dialect.decimal_comma, rows_ok, quoted,
                         plan.kinds)
    if bad is not None:
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


def _log_of(data: np.ndarray, plan: ColumnPlan, path: str, dialect: Dialect,
            notes: list[str]) -> ChamberLog:
    """The parsed cells (every column of the log) as a validated ChamberLog: our columns
    built by the plan, then checked."""
    return log_from_columns(plan.apply(data, path), path, dialect, notes)


def log_from_columns(cols: dict[str, Column], path: str, dialect: Dialect, notes: list[str]
                     ) -> ChamberLog:
    """Our columns (in memory or on disk) as a validated ChamberLog: exact duplicate rows
    dropped, other files joined on its clock, its gaps and resets mended into segments
    (logs/sampling.py), then checked."""
    cols = without_duplicates(cols, notes)
    cols, _ = apply_joins(cols, dialect.joins, path, notes)
    if dialect.sample_rate_hz is not None:
        check_rate_hz(dialect.sample_rate_hz)
    t = cols["time_s"]
    nominal = (1.0 / dialect.sample_rate_hz if dialect.sample_rate_hz is not None
               else nominal_step_s(t))
    max_gap = (dialect.max_gap_s if dialect.max_gap_s is not None
               else default_max_gap_s(nominal))
    if dialect.sample_rate_hz is None:
        check_rate_range(nominal, path)
    sampling = survey(t, nominal, max_gap)
    if dialect.sample_rate_hz is None and sampling.jittered > 0.01 * sampling.steps:
        # a jittered clock: its period is the mean step (each counted in samples), not the
        # median of jittered steps
        nominal = 1.0 / float(f"{1.0 / sampling.mean_step_s:.6g}")
        sampling = survey(t, nominal, max_gap)
    cols = mend_segments(cols, sampling, dialect.gap_states)
    dt = validate(cols, path, dialect.sample_rate_hz, nominal)
    if abs(dt - NOMINAL_DT_S) > 1e-9 * NOMINAL_DT_S:
        notes.append(f"sample rate {1.0 / dt:.6g} Hz ("
                     f"{'--sample-rate-hz' if dialect.sample_rate_hz else 'from time_s'})")
    if sampling.irregular:
        notes.append(sampling.text())
    extra = {k: v for k, v in cols.items()
             if k not in REQUIRED and k not in ("earth_rate_dps", "valid")}
    valid = cols.get("valid")
    if valid is not None:
        v = valid
        valid = derived(len(v), np.dtype(bool), lambda s: v[s] != 0.0) if is_lazy(v) \
            else v != 0.0
    return ChamberLog(
        time_s=cols["time_s"],
        temp_c=cols["temp_c"],
        table_rate_dps=cols["table_rate_dps"],
        gyro_dps=cols["gyro_dps"],
        earth_rate_dps=cols.get("earth_rate_dps"),
        valid=valid,
        extra=extra,
        path=path,
        read_notes=tuple(notes),
        nominal_dt_s=dt,
        sampling=sampling,
    )


def without_duplicates(cols: dict[str, Column], notes: list[str]) -> dict[str, Column]:
    """`cols` without the rows that repeat the row before them exactly (a logger that wrote a
    sample twice), counted in `notes`; a row at the same time with other values stays (and
    is refused as time not increasing). A log with such rows is then held in memory."""
    t = cols["time_s"]
    same: list[np.ndarray] = []
    for a in range(0, max(len(t) - 1, 0), VALIDATE_BLOCK):
        dt = np.diff(np.asarray(t[a:a + VALIDATE_BLOCK + 1]))
        same.append(a + 1 + np.flatnonzero(dt == 0.0))
    rows = np.concatenate(same) if same else np.zeros(0, dtype=np.int64)
    if not rows.size:
        return cols
    for v in cols.values():
        rows = rows[np.asarray(v[rows]) == np.asarray(v[rows - 1])]
    if not rows.size:
        return cols
    notes.append(f"{rows.size} exact duplicate row{'s' if rows.size > 1 else ''} dropped "
                 f"(the first at line {int(rows[0]) + 2})")
    return {k: np.delete(np.asarray(v[:]), rows) for k, v in cols.items()}


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
                       f"column {header[c]!r} is {lines[r + 1].split(delim)[c].strip()!r}")
    return data


def _find_bad_cell(lines: list[str], header: list[str], path: str, delim: str = ","
                   ) -> None:
    """The slow path: walk rows to name the first one that does not parse."""
    for i, line in enumerate(lines[1:], start=2):
        err = bad_cell_in(line, i, header, path, delim)
        if err is not None:
            raise err


def validate(cols: dict[str, np.ndarray], path: str, rate_hz: float | None = None,
             nominal: float | None = None) -> float:
    """Refuse a broken log (the rules of docs/logs.md); return its nominal sample period (s):
    1 / rate_hz, else `nominal` (the reader's, logs/sampling.py), else time_s's median step."""
    t = cols["time_s"]
    if rate_hz is not None:
        check_rate_hz(rate_hz)
        nominal = 1.0 / rate_hz
    elif nominal is None:
        nominal = nominal_step_s(t)
    if t.shape[0] >= 2:
        first_off: tuple[int, float] | None = None  # (index, step) of the first step off
        for a in range(0, t.shape[0] - 1, VALIDATE_BLOCK):  # no log-long temporaries
            dt = np.diff(t[a:a + VALIDATE_BLOCK + 1])
            nonincr = np.flatnonzero(dt <= 0)
            if nonincr.size:
                i = a + int(nonincr[0])
                raise LogError(path, i + 3, "time not increasing",
                               f"time_s {time_text(t, i + 1)} after {time_text(t, i)}"
                               f"{epoch_text(t)}")
            if first_off is None:
                off = np.flatnonzero(np.abs(dt - nominal) > DT_TOLERANCE * nominal)
                if off.size:
                    first_off = (a + int(off[0]), float(dt[off[0]]))
        if rate_hz is None:
            check_rate_range(nominal, path)
        if rate_hz is not None and first_off is not None:
            median_step = nominal_step_s(t)
            if abs(median_step - nominal) > DT_TOLERANCE * nominal:
                raise LogError(path, None, "sample rate",
                               f"the median step of time_s is {median_step:.4g} s "
                               f"({rate_text(median_step)}), not {nominal:.4g} s +/- "
                               f"{DT_TOLERANCE:.0%} (--sample-rate-hz {rate_hz:g})"
                               f"{epoch_text(t)}")
    # a log with the table stopped on every row is stationary: it measures the bias (the
    # SF figures refuse it, logs.bias); a log whose every row is invalid measures nothing
    turning = kept = measures = False
    valid = cols.get("valid")
    for a, tab in blocks(cols["table_rate_dps"], size=VALIDATE_BLOCK):  # no log-long copies
        turn = tab != 0.0
        keep = np.ones(turn.shape[0], dtype=bool) if valid is None else \
            np.asarray(valid[a:a + turn.shape[0]]) != 0.0
        turning, kept = turning or bool(turn.any()), kept or bool(keep.any())
        measures = measures or bool((turn & keep).any())
    stationary = kept and not turning
    if not measures and not stationary:
        raise LogError(path, None, "no row measures",
                       "every row has a zero table rate or valid = 0: the SF is measured "
                       "while the table turns, the bias on a log with the table stopped "
                       "throughout")
    lo, hi = TEMP_RANGE_C
    for name, v in cols.items():
        if not is_temperature(name):
            continue
        for a, x in blocks(v, size=VALIDATE_BLOCK):
            out = np.flatnonzero((x < lo) | (x > hi))
            if out.size:
                i = int(out[0])
                raise LogError(path, a + i + 2, "temperature out of range",
                               f"{name} = {x[i]:g} C, allowed {lo:g}..{hi:g} C"
                               + temperature_unit_hint(v))
    return nominal


def temperature_unit_hint(v: np.ndarray) -> str:
    """What a temperature column outside TEMP_RANGE_C is likely in, by its range: Kelvin
    (every value 173 .. 400), Fahrenheit (every value -76 .. 212 and more than 1 % of them
    above 100: one spike is not a unit)."""
    lo, hi = col_min(v), col_max(v)
    if 173.0 <= lo and hi <= 400.0:
        return (f" (the column spans {lo:g} .. {hi:g}: Kelvin? map it as "
                "`NAME - 273.15`)")
    hot = sum(int(np.count_nonzero(x > TEMP_RANGE_C[1])) for _, x in blocks(v))
    if -76.0 <= lo and hi <= 212.0 and hot > 0.01 * len(v):
        return (f" (the column spans {lo:g} .. {hi:g}: Fahrenheit? map it as "
                "`(NAME - 32) / 1.8`)")
    return ""


VALIDATE_BLOCK = 1 << 20  # time steps checked at a time


def check_rate_range(nominal: float, path: str) -> None:
    """Refuse a median step outside RATE_RANGE_HZ (+/- RATE_SLACK): time_s not in seconds."""
    lo_hz, hi_hz = RATE_RANGE_HZ
    slack = 1.0 + RATE_SLACK  # a device clock a little off its nominal rate
    if not 1.0 / (hi_hz * slack) <= nominal <= slack / lo_hz:
        raise LogError(path, None, "sample rate out of range",
                       f"the median step of time_s is {nominal:.6g} s "
                       f"({1.0 / nominal:.6g} Hz); allowed {lo_hz:g} Hz .. "
                       f"{hi_hz / 1000:g} kHz, +/- {RATE_SLACK:.0%} (time_s in seconds?)")


def write_log(path: str | Path, log: ChamberLog) -> None:
    """Write a log as CSV, or as Parquet when `path` ends in .parquet (every column float64);
    the same log gives the same bytes."""
    cols = log.columns()
    if is_parquet(path):
        write_columns(path, {k: np.asarray(v, dtype=np.float64) for k, v in cols.items()})
        return
    names = list(cols)
    data = np.column_stack([np.asarray(cols[n], dtype=np.float64) for n in names])
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(names) + "\n")
        t_fmt = time_format(log.time_s)
        write_rows(f, data, [t_fmt if n == "time_s" else "%d" if n == "valid" else "%.10g"
                             for n in names])


def time_format(time_s: np.ndarray) -> str:
    """The printf format of a time column: 12 digits keep a 4 kHz step (0.25 ms) exact past
    10^5 s; an epoch time base (1.7e9 s) takes 17, float64's every digit."""
    return "%.17g" if time_s.size and np.abs(time_s).max() >= EPOCH_S else "%.12g"


def write_rows(f: io.TextIOBase, data: np.ndarray, fmts: list[str], chunk: int = 50_000
               ) -> None:
    """Rows of `data` as CSV lines, one printf format per column: the bytes np.savetxt
    writes, about 4x faster (a 24 h 100 Hz log is 8.6 million rows)."""
    line = ",".join(fmts) + "\n"
    for a in range(0, data.shape[0], chunk):
        block = data[a:a + chunk]
        f.write((line * block.shape[0]) % tuple(block.ravel().tolist()))
