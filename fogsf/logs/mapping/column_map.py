"""Our columns built from a log's header and its column map (docs/logs.md, "Column map").

The reader parses every column of the log as numbers; a `ColumnPlan`, made from the header
alone, then says how each of our columns comes out of them: a column of the log as it is
(under its own name or renamed), or an expression over the log's columns (a number is an
expression too). `--gyro-column` / `--axis A` are applied last, on the names the map gives:
gyro_A_dps is read as gyro_dps, table_rate_A_dps and earth_rate_A_dps (when there are such
names) replace table_rate_dps and earth_rate_dps. Both reading paths apply the same plan.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from fogsf.logs.chamber_log import OPTIONAL, REQUIRED, LogError, is_temperature
from fogsf.logs.mapping.expressions import (
    EvaluationError,
    Expression,
    ExpressionError,
    column_named,
    parse_expression,
)
from fogsf.logs.read.cell_kinds import ISO_TIME, NUMBER, TEXT

# the names --axis A reads as the common ones: (per-axis pattern, common name)
# an axis' own names and the common ones they replace with --axis A (a 3-axis IMU with a
# thermometer per gyro writes temp_A_c)
AXIS_NAMES = (("gyro_{}_dps", "gyro_dps"), ("table_rate_{}_dps", "table_rate_dps"),
              ("earth_rate_{}_dps", "earth_rate_dps"), ("temp_{}_c", "temp_c"))
VALID_HINT = ("valid takes a condition (rig_enabled == 1 and rig_stalled == 0, with == != < "
              "<= > >= and/or/not) or a column of 0 and 1")


@dataclass(frozen=True)
class Source:
    """How one of our columns is made: the log's column `column` as it is, or `expr`."""

    name: str  # our name
    column: int | None = None  # index in the log's header
    expr: Expression | None = None
    origin: str = ""  # the map (--columns or its file), --axis, --gyro-column; "": the header

    @property
    def reads(self) -> tuple[str, ...]:
        """The log's columns an expression reads (none for a column as it is)."""
        return self.expr.names if self.expr is not None else ()

    @property
    def text(self) -> str:
        return self.expr.text.strip() if self.expr is not None else ""


@dataclass(frozen=True)
class ColumnPlan:
    """The log's header (`raw`) and our columns in order (`sources`)."""

    raw: tuple[str, ...]
    sources: tuple[Source, ...]
    # what each column of `raw` holds (logs/read/cell_kinds.py): () when every one is numbers
    kinds: tuple[str, ...] = ()

    @property
    def parsed_kinds(self) -> tuple[str, ...]:
        return self.kinds or (NUMBER,) * len(self.raw)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.sources]

    def apply(self, data: np.ndarray, path: str) -> dict[str, np.ndarray]:
        """Our columns from the parsed cells (one column per name of `raw`)."""
        raw = self.raw_columns(data)
        out = {}
        for s in self.sources:
            out[s.name] = self.values(s, data, raw, path)
            if s.name == "valid" and s.origin and not (out[s.name] != 0.0).any():
                raise self.none_kept(s)(path)
        return out

    def raw_columns(self, data: np.ndarray) -> dict[str, np.ndarray]:
        return {name: data[:, i] for i, name in enumerate(self.raw)}

    def values(self, s: Source, data: np.ndarray, raw: dict[str, np.ndarray], path: str,
               row0: int = 0) -> np.ndarray:
        """Source `s` over the rows of `data` (`raw`: its columns by name), the first of
        which is data row `row0` of the log; a refusal names the log's line."""
        v = data[:, s.column] if s.expr is None else _evaluated(s, raw, path, row0)
        if s.name == "valid" and s.origin:
            _check_valid(s, v, path, self.valid_shown(s), row0)
        return v

    def valid_shown(self, s: Source) -> str:
        return (f"valid = {s.text}" if s.column is None
                else f"valid (the log's {self.raw[s.column]!r})")

    def none_kept(self, s: Source):  # noqa: ANN201 - a refusal of a path
        """The refusal of a mapped valid that is 0 on every row (given the path)."""
        shown = self.valid_shown(s)
        return lambda path: LogError(path, None, "no row measures",
                                     f"{shown} ({s.origin}) is 0 on every row: no row is "
                                     "kept")


def plan_map(raw: list[str], columns: tuple[tuple[str, str], ...], origin: str, path: str
             ) -> ColumnPlan:
    """Our columns from the header `raw` and the map `columns` ((our name, text), from
    `origin`), before --gyro-column / --axis. The log's columns the map does not rename keep
    their names; a computed name takes the place of the log's column of that name when it
    reads that column, and is added at the end otherwise."""
    entries = [_entry(ours, text, raw, origin, path) for ours, text in columns]
    renamed: dict[int | None, Source] = {}
    for s in entries:
        if s.expr is None and s.column in renamed:
            assert s.column is not None  # a column as it is has its index
            raise LogError(path, 1, "column map", f"{origin}: the log's column "
                           f"{raw[s.column]!r} is mapped to two names "
                           f"({renamed[s.column].name}, {s.name})")
        if s.expr is None:
            renamed[s.column] = s
    computed = {s.name: s for s in entries if s.expr is not None}
    out = []
    for i, name in enumerate(raw):
        if i in renamed:
            out.append(renamed[i])
        elif name in computed and name in computed[name].reads:
            out.append(computed.pop(name))
        else:
            out.append(Source(name, column=i))
    out.extend(computed.values())
    return ColumnPlan(tuple(raw), tuple(out))


def with_kinds(plan: ColumnPlan, kinds: tuple[str, ...], path: str, notes: list[str]
               ) -> ColumnPlan:
    """`plan` for a log whose columns hold `kinds` (from its first data row): a column of
    text or time stamps the plan does not read is left out (said in `notes`); a text column
    it reads is refused, naming it."""
    if all(k == NUMBER for k in kinds):
        return plan
    used: set[int] = set()
    for s in plan.sources:
        if s.expr is not None:
            used.update(plan.raw.index(n) for n in _read_columns(s, plan.raw))
        elif s.column is not None and (s.origin or is_our_name(s.name)):
            used.add(s.column)
    dropped = [i for i, k in enumerate(kinds) if k != NUMBER and i not in used]
    for i in sorted(used):
        if kinds[i] == TEXT:
            names = [s.name for s in plan.sources if s.column == i or plan.raw[i] in
                     _read_columns(s, plan.raw)]
            raise LogError(path, 2, "text column",
                           f"column {plan.raw[i]!r} holds text, not numbers, and is read as "
                           f"{', '.join(names)}: map another column (a text column the map "
                           "does not read is left out)")
    if dropped:
        notes.append(f"text columns left out: {', '.join(plan.raw[i] for i in dropped)}")
    stamped = [plan.raw[i] for i in sorted(used) if kinds[i] == ISO_TIME]
    if stamped:
        notes.append(f"ISO-8601 time read as epoch seconds (UTC): {', '.join(stamped)}")
    return replace(plan, kinds=kinds, sources=tuple(
        s for s in plan.sources if not (s.expr is None and s.column in dropped)))


def _read_columns(s: Source, raw: tuple[str, ...]) -> list[str]:
    return [c for n in s.reads if (c := column_named(n, raw)) is not None]


# a per-axis name of the map: the axis is letters and digits (x, y, z, 1, ...)
PER_AXIS = re.compile(r"(gyro|table_rate|earth_rate)_[A-Za-z0-9]+_dps")


def is_our_name(name: str) -> bool:
    """A name the column map may give: the format's, a thermometer's, a per-axis one."""
    return (name in REQUIRED or name in OPTIONAL or is_temperature(name)
            or PER_AXIS.fullmatch(name) is not None)


def map_reads(raw: list[str], columns: tuple[tuple[str, str], ...]) -> set[str]:
    """The names the map reads from a log (a text that is no expression counts as a name)."""
    names: set[str] = set()
    for ours, text in columns:
        if text in raw:
            names.add(text)
            continue
        try:
            names.update(parse_expression(text, ours == "valid").names)
        except ExpressionError:
            names.add(text)
    return names


def pick_axis(plan: ColumnPlan, gyro: str | None, axis: str | None, option: str, path: str,
              notes: list[str]) -> ColumnPlan:
    """`gyro` (--gyro-column, or gyro_A_dps for --axis A) read as gyro_dps; for --axis A also
    table_rate_A_dps, earth_rate_A_dps and temp_A_c, when there are such names, as the
    common ones (which they replace). What moved is said in `notes`."""
    if gyro is None:
        return plan
    names = plan.names
    if gyro not in names:
        raise LogError(path, 1, "no such column",
                       f"{option} names {gyro!r} for gyro_dps; header has: "
                       f"{', '.join(plan.raw)}{_defined(plan)}")
    moves = {gyro: "gyro_dps"}
    if axis is not None:
        for own, common in AXIS_NAMES[1:]:
            if own.format(axis) in names:
                moves[own.format(axis)] = common
    replaced = set(moves.values()) - {"gyro_dps"}
    origin = f"--axis {axis}" if option == "--axis" else option
    moved = [f"{s.name} -> {moves[s.name]}" for s in plan.sources if s.name in moves]
    notes.append(f"columns {', '.join(moved)} ({origin})")
    return ColumnPlan(plan.raw, tuple(
        replace(s, name=moves[s.name]) if s.name in moves else s
        for s in plan.sources if s.name not in replaced))


def moved_notes(plan: ColumnPlan) -> list[str]:
    """What the map did, one note per origin: `t -> time_s` for a renamed column,
    `time_s = sec + nanosec * 1e-9` for a computed one."""
    by_origin: dict[str, list[str]] = {}
    for s in plan.sources:
        if s.expr is None and s.column is not None and plan.raw[s.column] != s.name:
            by_origin.setdefault(s.origin, []).append(f"{plan.raw[s.column]} -> {s.name}")
    for s in plan.sources:
        if s.expr is not None:
            by_origin.setdefault(s.origin, []).append(f"{s.name} = {s.text}")
    return [f"columns {', '.join(items)} ({origin})" for origin, items in by_origin.items()]


def missing_required(plan: ColumnPlan, required: tuple[str, ...] | None = None) -> list[str]:
    """The names of `required` (default: a sample log's REQUIRED) the plan does not give."""
    return [c for c in (REQUIRED if required is None else required) if c not in plan.names]


def _entry(ours: str, text: str, raw: list[str], origin: str, path: str) -> Source:
    """One map entry read against the header: a column of the log, or an expression whose
    names are all columns of the log."""
    if text in raw:
        return Source(ours, column=raw.index(text), origin=origin)
    try:
        expr = parse_expression(text, condition=ours == "valid")
    except ExpressionError as e:
        raise LogError(path, 1, "column map",
                       f"{origin}: {ours} = {text!r} is neither a column of the log nor an "
                       f"expression: {e}; header has: {', '.join(raw)}") from None
    for name in expr.names:
        if column_named(name, raw) is None:
            where = "" if expr.is_name else f" (in {text.strip()})"
            raise LogError(path, 1, "no such column",
                           f"{origin} names {name!r} for {ours}{where}; header has: "
                           f"{', '.join(raw)}")
    if expr.is_name:
        return Source(ours, column=raw.index(column_named(expr.names[0], raw) or ""),
                      origin=origin)
    return Source(ours, expr=expr, origin=origin)


def _defined(plan: ColumnPlan) -> str:
    computed = [s.name for s in plan.sources if s.expr is not None]
    return f"; the column map gives {', '.join(computed)}" if computed else ""


def _evaluated(s: Source, raw: dict[str, np.ndarray], path: str, row0: int = 0
               ) -> np.ndarray:
    assert s.expr is not None
    n = next(iter(raw.values())).shape[0] if raw else 0
    if row0 == 0:  # the log's first rows: unwrap() starts afresh
        s.expr.carry.clear()
    try:
        return s.expr.evaluate(raw, n)
    except EvaluationError as e:
        raise LogError(path, row0 + e.row + 2, "column map",
                       f"{s.name} = {s.text} ({s.origin}): {e.detail}") from None


def _check_valid(s: Source, v: np.ndarray, path: str, shown: str, row0: int = 0) -> None:
    """A mapped valid: 0 or 1 on every row (the caller checks it is 1 on some)."""
    if s.expr is None or not s.expr.is_condition:
        bad = np.flatnonzero((v != 0.0) & (v != 1.0))
        if bad.size:
            i = int(bad[0])
            raise LogError(path, row0 + i + 2, "column map",
                           f"{shown} ({s.origin}) is {v[i]:g}: {VALID_HINT}")
