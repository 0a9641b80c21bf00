"""How a log file writes the format (a `Dialect`): the delimiter (given or sniffed), the
column names mapped to ours (`--columns`, a mapping file beside the log, `--gyro-column`),
quoted cells, decimal commas; and the header read through it, with a hint when a required
column is missing."""

from __future__ import annotations

import json
import math
import re
import shlex
import tomllib
from dataclasses import dataclass
from pathlib import Path

from fogsf.errors import UserError
from fogsf.logs.chamber_log import OPTIONAL, REQUIRED, LogError
from fogsf.logs.mapping.column_map import (
    ColumnPlan,
    is_our_name,
    map_reads,
    missing_required,
    moved_notes,
    pick_axis,
    plan_map,
)
from fogsf.logs.mapping.expressions import ExpressionError, parse_expression, split_top_level
from fogsf.logs.mapping.join_spec import Join, join_names, joins_of
from fogsf.logs.mapping.layout import (
    LAYOUT_KEYS,
    PLATEAU_NAMES,
    PLATEAU_REQUIRED,
    PlateauLayout,
    layout_of,
)

DELIMITERS = {",": ",", ";": ";", "tab": "\t"}
DELIMITER_NAMES = {",": "','", ";": "';'", "\t": "tab"}
# A column mapping in one of these files beside a log applies to it when --columns is not given
MAPPING_FILES = ("fogsf-columns.json", "fogsf-columns.toml")
COLUMNS_HINT = ("map the log's names with --columns time_s=NAME,temp_c=NAME,... or a "
                "fogsf-columns.toml beside the log (docs/logs.md)")
DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d*,\d+([eE][-+]?\d+)?\s*$")


@dataclass(frozen=True)
class Dialect:
    """How a log file writes the format: delimiter, column names, which gyro column."""

    delimiter: str | None = None  # None: sniffed from the header among , ; and tab
    # (our name, the log's column / a number / an expression over the log's columns)
    columns: tuple[tuple[str, str], ...] = ()
    gyro_column: str | None = None  # the log's column read as gyro_dps
    decimal_comma: bool = False  # cells written 20,5 (then separated by ; or tab)
    columns_from: str = "--columns"  # where `columns` came from, for messages
    sample_rate_hz: float | None = None  # stated (--sample-rate-hz); None: from time_s
    # --axis A: gyro_A_dps read as gyro_dps, table_rate_A_dps and earth_rate_A_dps (when
    # the log or the map has them) as table_rate_dps and earth_rate_dps
    axis: str | None = None
    # [join.NAME] tables of the map file: other files put on the log's clock (logs/mapping/joins.py)
    joins: tuple[Join, ...] = ()
    # a step longer than this is a gap (None: logs/read/sampling.py default_max_gap_s); how the
    # model's states cross it: "carry" or "restart"
    max_gap_s: float | None = None
    gap_states: str = "carry"
    # a field-format file's stream read as the log (logs/read/field_formats.py): the map's
    # `stream = "/imu"`; None: the file's only one
    stream: str | None = None
    # `layout = "plateaus"` in the map file: a row per rate plateau (logs/plateau_table.py)
    layout: PlateauLayout | None = None
    # --allow-clock-offset: a join whole hours off the log's clock is joined as it is, not
    # refused as a time zone read as UTC (logs/mapping/time_zone.py)
    allow_clock_offset: bool = False
    # --bad-cells: "refuse" a cell that holds no number, or "skip": its row measures nothing
    # (logs/read/bad_cells.py)
    bad_cells: str = "refuse"

    @property
    def gyro_name(self) -> str | None:
        """The log's column read as gyro_dps: --gyro-column, or gyro_A_dps for --axis A."""
        return self.gyro_column or (f"gyro_{self.axis}_dps" if self.axis else None)

    @staticmethod
    def mapping_file(path: str | Path) -> tuple[tuple[str, str], ...]:
        """A JSON object or TOML table {"time_s": "t", ...}: our name to the log's column, a
        number, or an expression over the log's columns."""
        p = Path(path)
        m = _map_file(p)
        plateaus = isinstance(m, dict) and layout_of(m, str(p)) is not None
        m = ({k: v for k, v in m.items() if k not in ("join", "stream", *LAYOUT_KEYS)}
             if isinstance(m, dict) else m)
        # a plateau table in the format's names needs no column map, only its layout keys
        if (not isinstance(m, dict) or not (m or plateaus)
                or not all(_is_value(v) for v in m.values())):
            raise UserError(f"{p}: expected a mapping of our names to the log's columns, "
                            'numbers or expressions, e.g. {"time_s": "t", "earth_rate_dps": '
                            '0.00234} (TOML: time_s = "t")')
        return Dialect._checked([(k, _text(v)) for k, v in m.items()], str(p),
                                PLATEAU_NAMES if plateaus else ())

    @staticmethod
    def mapping_layout(path: str | Path) -> PlateauLayout | None:
        """The layout keys of a column map file (logs/mapping/layout.py); None: samples."""
        m = _map_file(Path(path))
        return layout_of(m, str(path)) if isinstance(m, dict) else None

    @staticmethod
    def mapping_joins(path: str | Path) -> tuple[Join, ...]:
        """The [join.NAME] tables of a column map file (none: ())."""
        m = _map_file(Path(path))
        if not isinstance(m, dict) or "join" not in m:
            return ()
        return joins_of(m["join"], str(path), is_our_name)

    @staticmethod
    def mapping_stream(path: str | Path) -> str | None:
        """The `stream = "..."` of a column map file (a field format's main stream)."""
        m = _map_file(Path(path))
        v = m.get("stream") if isinstance(m, dict) else None
        if v is not None and not isinstance(v, str):
            raise UserError(f"{path}: stream = {v!r}: a topic, message or group name")
        return v

    @staticmethod
    def parse_columns(text: str) -> tuple[tuple[str, str], ...]:
        """`time_s=t,temp_c=temperature` or a JSON/TOML file {"time_s": "t", ...}. Pairs are
        split at the commas outside parentheses and backquotes; each at its first '='."""
        if text.lower().endswith((".json", ".toml")) and "=" not in text:
            return Dialect.mapping_file(text)
        pairs = []
        for part in (p for p in split_top_level(text) if p.strip()):
            ours, eq, theirs = part.partition("=")
            if not eq or not ours.strip() or not theirs.strip():
                raise UserError(f"--columns: expected OURS=THEIRS pairs like "
                                f"time_s=t,temp_c=temperature, got {part!r}")
            pairs.append((ours.strip(), theirs.strip()))
        return Dialect._checked(pairs, "--columns")

    @staticmethod
    def _checked(pairs: list[tuple[str, str]], source: str, extra: tuple[str, ...] = ()
                 ) -> tuple[tuple[str, str], ...]:
        """`pairs` with every name one the format has (or in `extra`: a plateau table's)."""
        ours_seen: set[str] = set()
        for ours, theirs in pairs:
            if not is_our_name(ours) and ours not in extra:
                raise UserError(f"{source}: {ours!r} is not a column of the format "
                                f"({', '.join(OUR_NAMES)})")
            if ours in ours_seen:
                raise UserError(f"{source}: {ours} is mapped twice")
            if not theirs.strip():
                raise UserError(f"{source}: {ours} is mapped to nothing")
            ours_seen.add(ours)
        plain = [t for _, t in pairs if _plain_name(t)]
        twice = sorted({t for t in plain if plain.count(t) > 1})
        if twice:
            raise UserError(f"{source}: the log's column {twice[0]!r} is mapped to two names")
        return tuple(pairs)


OUR_NAMES = (*REQUIRED, *OPTIONAL, "temp_<name>_c", "gyro_<a>_dps", "table_rate_<a>_dps",
             "earth_rate_<a>_dps")


def _map_file(p: Path) -> object:
    try:
        text = p.read_text(encoding="utf-8-sig")
        return tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
    except (OSError, ValueError) as e:  # TOMLDecodeError is a ValueError
        raise UserError(f"{p}: cannot read the column mapping ({e})") from None


def _is_value(v: object) -> bool:
    """A map value a file may hold: text, or a finite number (not true/false)."""
    if isinstance(v, bool):
        return False
    return isinstance(v, str) or isinstance(v, int | float) and math.isfinite(v)


def _text(v: str | float) -> str:
    return v if isinstance(v, str) else repr(v)


def _plain_name(text: str) -> bool:
    """A map value that is a column name, not an expression or a number."""
    try:
        return parse_expression(text, condition=True).is_name
    except ExpressionError:
        return True


def map_folders(log_path: str | Path) -> list[Path]:
    """Where a log's column map (MAPPING_FILES) is looked for: the log's folder; for a ROS 2
    bag (a folder with metadata.yaml) the bag's folder first, then the one it lies in."""
    p = Path(log_path)
    inside = [p] if p.is_dir() and (p / "metadata.yaml").is_file() else []
    return [*inside, p.parent]


def mapping_beside(log_path: str | Path) -> Path | None:
    """The column mapping file (MAPPING_FILES) of the first of `map_folders` that holds
    one, if any; two in one folder are refused."""
    for folder in map_folders(log_path):
        found = [folder / n for n in MAPPING_FILES if (folder / n).is_file()]
        if len(found) > 1:
            raise UserError(f"{folder}: both {found[0].name} and {found[1].name}; keep one")
        if found:
            return found[0]
    return None


def looked_in(log_path: str) -> str:
    """Where a column map was looked for and not found, for a missing column's message;
    "" for a log not on disk."""
    if not Path(log_path).exists():
        return ""
    where = " or ".join(str(f) for f in map_folders(log_path))
    return f" (no {' or '.join(MAPPING_FILES)} in {where})"


def _sniff(header_line: str, path: str) -> str:
    """The one of , ; and tab that the header uses; none or several are refused."""
    found = [d for d in DELIMITER_NAMES if d in header_line]
    if len(found) == 1:
        return found[0]
    if not found:
        if " " in header_line.strip():
            raise LogError(path, 1, "no delimiter",
                           f"the header {header_line.strip()[:60]!r} has no ',' ';' or tab "
                           "between column names (spaces are not read as a delimiter): "
                           "write the log with one of them")
        return ","  # one column: the missing-column message says what is wrong
    raise LogError(path, 1, "ambiguous delimiter",
                   f"the header holds {' and '.join(DELIMITER_NAMES[d] for d in found)}; "
                   "give --delimiter")


def unquote_lines(lines: list[str], delim: str, path: str) -> list[str]:
    """Lines with CSV quoting ("time_s","0.1") read by the csv module and written back
    without quotes; a quoted cell that holds the delimiter itself is refused."""
    import csv

    out = []
    reader = csv.reader(lines, delimiter=delim, strict=True)
    try:
        rows = list(reader)
    except csv.Error as e:
        raise LogError(path, reader.line_num, "bad quoting", str(e)) from None
    for i, row in enumerate(rows, start=1):
        bad = delimiter_in_cell(row, i, delim, path)
        if bad is not None:
            raise bad
        out.append(delim.join(row))
    return out


def delimiter_in_cell(row: list[str], i: int, delim: str, path: str) -> LogError | None:
    """The refusal of row `i` (from 1) when a quoted cell of it holds the delimiter."""
    for cell in row:
        if delim in cell:
            return LogError(path, i, "delimiter inside a quoted cell",
                            f"{cell!r} holds {DELIMITER_NAMES[delim]}: write numbers "
                            "without thousands separators (or use --decimal-comma with "
                            "';' or tab cells)")
    return None


# A column that looks like a gyro's rate: gx, gx[dps], gyro_x, wx, omega_z, ...; not a
# thermometer (gyro_temp, gyro_temp_c, gx_degc)
GYRO_LIKE = re.compile(r"(?i)gyro|^(gyr|g|w|omega)[_ -]?[xyz](?![a-z0-9])")
TEMPERATURE_LIKE = re.compile(r"(?i)temp|deg_?c\b|_c$|\[c\]")


AXIS_GYRO = re.compile(r"gyro_(\w+)_dps")


def log_axes(header: list[str]) -> list[str]:
    """The axes A of a header in the format's names (gyro_A_dps columns), in header order:
    what `--axis all` runs over."""
    return [m.group(1) for h in header if (m := AXIS_GYRO.fullmatch(h))]


def _missing_hint(missing: list[str], header: list[str]) -> str:
    axes = log_axes(header)
    if "gyro_dps" in missing and axes:
        names = [f"gyro_{a}_dps" for a in axes]
        return (f"; the log has {', '.join(names)}: pick one with --gyro-column {names[0]} "
                f"(or --axis {axes[0]})")
    hints = []
    if "gyro_dps" in missing:
        like = [h for h in header if h not in REQUIRED + OPTIONAL and GYRO_LIKE.search(h)
                and not TEMPERATURE_LIKE.search(h)]
        if like:
            hints.append(f"the gyro's rate (deg/s) may be {', '.join(like)}: read it with "
                         f"--gyro-column {shlex.quote(like[0])}")
    if set(missing) - {"gyro_dps"} or not hints:
        hints.append(COLUMNS_HINT)
    return "; " + "; ".join(hints)


def find_delimiter(first: str, path: str, dialect: Dialect, notes: list[str]) -> str:
    delim = dialect.delimiter or _sniff(first, path)
    if dialect.decimal_comma and delim == ",":  # given or sniffed: one check for both
        raise LogError(path, 1, "decimal comma with ',' cells",
                       "--decimal-comma needs cells separated by ';' or tab, not ','")
    if dialect.delimiter is None and delim != ",":
        notes.append(f"cells separated by {DELIMITER_NAMES[delim]} (from the header)")
    if dialect.decimal_comma:
        notes.append("decimal comma (--decimal-comma)")
    return delim


def raw_header(first: str, delim: str, path: str) -> list[str]:
    """The header row's names as the log writes them; an empty or repeated one is refused."""
    return checked_names([h.strip() for h in first.split(delim)], path)


def checked_names(raw: list[str], path: str) -> list[str]:
    """A log's column names (a header row's, a Parquet schema's); an empty or repeated one is
    refused."""
    seen: set[str] = set()
    for h in raw:
        if not h:
            raise LogError(path, 1, "bad header", "an empty column name")
        if h in seen:
            raise LogError(path, 1, "bad header", f"column {h!r} appears twice")
        seen.add(h)
    return raw


def map_plan(raw: list[str], dialect: Dialect, path: str, notes: list[str]) -> ColumnPlan:
    """The column map applied to a header, before --gyro-column / --axis. A mapping file
    beside the logs is not applied to a log already in the format's names that holds none
    of the columns the map reads."""
    columns = dialect.columns
    if (columns and dialect.columns_from != "--columns"
            and all(r in raw for r in REQUIRED)
            and (reads := map_reads(raw, columns)) and not reads & set(raw)):
        notes.append(f"{dialect.columns_from} not applied: the header has the format's names")
        columns = ()
    return plan_map(raw, columns, dialect.columns_from, path)


def read_header(first: str, delim: str, path: str, dialect: Dialect, notes: list[str]
            ) -> ColumnPlan:
    """The header row read through the column map and --gyro-column / --axis, checked: no
    empty or repeated name, every required one."""
    return names_plan(raw_header(first, delim, path), path, dialect, notes)


def names_plan(raw: list[str], path: str, dialect: Dialect, notes: list[str]) -> ColumnPlan:
    """A log's column names (checked by `checked_names`) read through the column map and
    --gyro-column / --axis, checked: no repeated name after them, every required one."""
    mapped = map_plan(raw, dialect, path, notes)
    notes.extend(moved_notes(mapped))
    option = "--gyro-column" if dialect.gyro_column else "--axis"
    plan = pick_axis(mapped, dialect.gyro_name, dialect.axis, option, path, notes)
    seen: set[str] = set()
    for h in plan.names:
        if h in seen:
            raise LogError(path, 1, "bad header", f"column {h!r} appears twice"
                           " (after --columns / --gyro-column)")
        seen.add(h)
    # a plateau table may stand for its times with duration_s or plateau_s (its own check)
    required = PLATEAU_REQUIRED if dialect.layout is not None else None
    missing = [m for m in missing_required(plan, required) if m not in join_names(dialect.joins)]
    if missing:
        raise LogError(path, 1, "missing required column",
                       f"{', '.join(missing)} (header has: {', '.join(raw)})"
                       + _missing_hint(missing, mapped.names)
                       + ("" if dialect.columns else looked_in(path)))
    return plan
