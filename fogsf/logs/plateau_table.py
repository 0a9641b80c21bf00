"""Plateau tables (docs/logs.md, "Plateau tables"): a log whose rows are rate plateaus' means
(the mean gyro output, the commanded rate, the mean board temperature), as a rig's DAQ
software writes them, read into a `PlateauTable`.

The map beside the table says `layout = "plateaus"` (logs/mapping/layout.py). The file is
read as a sample log is (logs/logio.py: dialect, column map, expressions, Parquet), then
checked by the rules of a table: a time for every row (a `time_s` column, with `time_is`
"start" or "middle"; a `duration_s` column; or `plateau_s` in the map), rows at least
MIN_PLATEAU_S apart (closer rows are samples), two table rates or more, two temperatures or
more (TEMP_GROUP_C apart). Every refusal is one `LogError` naming the file and the line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import TEMP_RANGE_C, LogError, earth_rate_vertical_dps
from fogsf.logs.logio import cannot_read, parse_log, with_mapping_beside
from fogsf.logs.mapping.column_map import ColumnPlan
from fogsf.logs.mapping.layout import PlateauLayout
from fogsf.logs.measure.plateaus import MIN_PLATEAU_S
from fogsf.logs.measure.table_figures import TEMP_GROUP_C
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.parquet_log import is_parquet, read_parquet_log

# a time_s and a duration_s may overlap by this fraction of a plateau (rounding in the DAQ)
OVERLAP_TOL = 0.01


@dataclass
class PlateauTable:
    """One plateau table: a row per rate plateau, float64 arrays of one length."""

    time_s: np.ndarray  # each plateau's start (s)
    duration_s: np.ndarray  # each plateau's length (s)
    table_rate_dps: np.ndarray  # the commanded rate; 0: a bias plateau
    gyro_dps: np.ndarray  # the mean output, scaled with the nominal SF (deg/s)
    temp_c: np.ndarray  # the mean board temperature
    earth_rate_dps: np.ndarray | None = None  # None: --latitude-deg gives it
    path: str = "<memory>"
    valid: np.ndarray | None = None  # per row, True where it measures; None: every row
    read_notes: tuple[str, ...] = ()
    time_from: str = ""  # where the times came from, for the summary

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    @property
    def measures(self) -> np.ndarray:
        """Per row, True where it measures (its `valid`)."""
        return np.ones(len(self), bool) if self.valid is None else self.valid

    def earth(self, latitude_deg: float | None = None, axis_cosine: float = 1.0
              ) -> np.ndarray:
        """The earth rate on the axis per row: the table's column, else from a latitude (a
        vertical axis times `axis_cosine`); with neither, refused as a sample log is."""
        if self.earth_rate_dps is not None:
            return self.earth_rate_dps
        if latitude_deg is None:
            raise LogError(self.path, None, "no earth rate",
                           "the table has no earth_rate_dps column; pass --latitude-deg")
        return np.full(len(self), earth_rate_vertical_dps(latitude_deg) * axis_cosine)


def is_plateau_table(path: str | Path, dialect: Dialect | None = None) -> bool:
    """True when the log's map (--columns FILE, or the file beside it) says
    `layout = "plateaus"`."""
    return with_mapping_beside(path, dialect or Dialect()).layout is not None


def read_plateau_table(path: str | Path, dialect: Dialect | None = None) -> PlateauTable:
    """Read and check a plateau table (CSV or Parquet) through its map; LogError on the first
    broken rule."""
    p = str(path)
    dialect = with_mapping_beside(path, dialect or Dialect())
    layout = dialect.layout
    if layout is None:
        raise UserError(f"{p}: not a plateau table: its column map has no layout = "
                        "\"plateaus\" (docs/logs.md, \"Plateau tables\")")

    def build(data: np.ndarray, plan: ColumnPlan, path: str, _d: Dialect, notes: list[str]
              ) -> PlateauTable:
        return _table_of(layout, data, plan, path, notes)

    if is_parquet(path):
        return read_parquet_log(path, dialect, build)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise cannot_read(p, e) from None
    return parse_log(text, p, dialect, build)  # type: ignore[return-value]


def _table_of(layout: PlateauLayout, data: np.ndarray, plan: ColumnPlan, path: str,
              notes: list[str]) -> PlateauTable:
    """The table from its parsed cells, checked (the module's rules)."""
    cols = plan.apply(data, path)
    n = data.shape[0]
    valid = (cols["valid"] != 0.0) if "valid" in cols else None
    start, duration, time_from = _times(layout, cols, n, path)
    table = PlateauTable(start, duration, cols["table_rate_dps"], cols["gyro_dps"],
                         cols["temp_c"], cols.get("earth_rate_dps"), path, valid,
                         tuple(notes), time_from)
    _check_values(table)
    return table


def _times(layout: PlateauLayout, cols: dict[str, np.ndarray], n: int, path: str
           ) -> tuple[np.ndarray, np.ndarray, str]:
    """(start, duration, where they came from) of every row. A row without a duration lasts
    until the next row's time (the last as long as the one before it): rows in time order."""
    t, d = cols.get("time_s"), cols.get("duration_s")
    origin = layout.origin
    if d is not None and layout.plateau_s is not None:
        raise LogError(path, 1, "plateau table", f"a duration_s column and plateau_s = "
                       f"{layout.plateau_s:g} ({origin}): give one")
    if t is None and d is None and layout.plateau_s is None:
        raise LogError(path, 1, "plateau table",
                       "no time for the rows: a time_s column (with time_is = \"start\" or "
                       f"\"middle\" in {origin}), a duration_s column, or plateau_s = S "
                       "(every plateau's length) in the map")
    if t is not None and layout.time_is is None:
        raise LogError(path, 1, "plateau table",
                       f"time_s without time_is ({origin}): say which instant of its plateau "
                       "a row's time gives, time_is = \"start\" or \"middle\"")
    dur = d if d is not None else (None if layout.plateau_s is None
                                   else np.full(n, layout.plateau_s))
    if dur is not None:
        short = np.flatnonzero(~(dur >= MIN_PLATEAU_S))
        if short.size:
            i = int(short[0])
            raise LogError(path, i + 2, "not a plateau",
                           f"a plateau of {dur[i]:g} s: a plateau lasts {MIN_PLATEAU_S:g} s "
                           "or more (rows of samples need a sample log: no layout = "
                           "\"plateaus\" in its map)")
    if t is None:
        assert dur is not None
        where = "duration_s" if d is not None else f"plateau_s = {layout.plateau_s:g}"
        return np.concatenate([[0.0], np.cumsum(dur)[:-1]]), dur, where
    _check_steps(t, path)
    if dur is None:  # each row lasts until the next
        step = np.diff(t)
        dur = np.append(step, step[-1]) if step.size else np.full(n, MIN_PLATEAU_S)
    start = t if layout.time_is == "start" else t - 0.5 * dur
    overlap = np.flatnonzero(start[1:] < start[:-1] + dur[:-1] * (1.0 - OVERLAP_TOL))
    if overlap.size:
        i = int(overlap[0]) + 1
        raise LogError(path, i + 2, "plateaus overlap",
                       f"this plateau starts at {start[i]:g} s, before the one above ends "
                       f"({start[i - 1] + dur[i - 1]:g} s; time_is = \"{layout.time_is}\")")
    return start, dur, f"time_s (plateau {layout.time_is})"


def _check_steps(t: np.ndarray, path: str) -> None:
    """Rows in time order, at least MIN_PLATEAU_S apart: closer rows are samples mixed in."""
    step = np.diff(t)
    bad = np.flatnonzero(~(step >= MIN_PLATEAU_S))
    if not bad.size:
        return
    i = int(bad[0]) + 1
    if step[i - 1] <= 0:
        raise LogError(path, i + 2, "time not increasing",
                       f"time_s {t[i]:g} after {t[i - 1]:g}: a plateau table's rows are in "
                       "time order")
    raise LogError(path, i + 2, "samples in a plateau table",
                   f"time_s {t[i]:g} is {step[i - 1]:g} s after the row above: rows closer "
                   f"than {MIN_PLATEAU_S:g} s are samples, not plateau means (a sample log "
                   "has no layout = \"plateaus\" in its map)")


def _check_values(table: PlateauTable) -> None:
    """The rows that measure: temperatures in range, two table rates or more (the SF needs
    them), two temperatures or more (every figure is against temperature)."""
    path, keep = table.path, table.measures
    if not keep.any():
        raise LogError(path, None, "no row measures", "valid is 0 on every row")
    hot = np.flatnonzero((table.temp_c < TEMP_RANGE_C[0]) | (table.temp_c > TEMP_RANGE_C[1]))
    if hot.size:
        i = int(hot[0])
        raise LogError(path, i + 2, "temperature out of range",
                       f"temp_c {table.temp_c[i]:g} C outside {TEMP_RANGE_C[0]:g} .. "
                       f"{TEMP_RANGE_C[1]:g} C")
    rates = np.unique(table.table_rate_dps[keep])
    if rates.size < 2:
        raise LogError(path, None, "rates never change",
                       f"table_rate_dps is {rates[0]:g} deg/s on every row: a plateau table "
                       "measures the SF from plateaus at two rates or more")
    temp = table.temp_c[keep]
    if np.ptp(temp) < TEMP_GROUP_C:
        raise LogError(path, None, "one temperature only",
                       f"every row's temp_c lies in {temp.min():.2f} .. {temp.max():.2f} C: "
                       f"the figures against temperature need plateaus at two temperatures "
                       f"({TEMP_GROUP_C:g} C apart) or more")
