"""Reading a log of any length in bounded memory: the log's columns go to a spill on disk
block by block, and the `ChamberLog` returned reads them from there (logs/read/columns.py).

The file is parsed as `read_log` parses it (pyarrow's CSV reader block by block, or a
Parquet file batch by batch), the column map is applied to each block, and our columns are
written to a temporary directory (`Spill`) as raw float64, 8 bytes a sample a column. The
rules are then checked block by block over the spilled columns. The log is the same, to the
bit, as `read_log` gives, and so is every refusal: a bad cell, wherever it lies, comes
before a column map's refusal, and of the map's refusals the first column's (in the map's
order) at its first row. A file the fast reader cannot read (a refused file, or one only the
general path reads) is read by `read_log` in memory.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import (
    _data_lines,
    plain_header,
    read_log,
    refuse_bad_line,
    refuse_plateaus,
    with_mapping_beside,
)
from fogsf.logs.mapping.column_map import ColumnPlan
from fogsf.logs.read.arrow_csv import NotFast, number_blocks
from fogsf.logs.read.columns import Column, Spill, is_lazy
from fogsf.logs.read.dialect import Dialect, names_plan
from fogsf.logs.read.field_formats import format_of
from fogsf.logs.read.parquet_log import in_rows, is_parquet, parquet_blocks, parquet_names
from fogsf.logs.validation import log_from_columns


def read_log_on_disk(path: str | Path, dialect: Dialect | None = None,
                     spill: Spill | None = None,
                     progress: Callable[[int, int], None] | None = None) -> ChamberLog:
    """`read_log`, the columns on disk (in `spill`, a new one by default); `progress` is told
    (rows read, rows) after every block."""
    p = str(path)
    dialect = with_mapping_beside(path, dialect or Dialect())
    refuse_plateaus(p, dialect)
    spill = spill or Spill()
    if format_of(path) is not None:  # a field format: its streams are read whole
        return read_log(path, dialect)
    if is_parquet(path):
        notes: list[str] = []
        given = [o for o, on in (("--delimiter", dialect.delimiter),
                                 ("--decimal-comma", dialect.decimal_comma)) if on]
        if given:
            notes.append(f"{' and '.join(given)} not used: a Parquet log")
        names = parquet_names(path)
        plan = in_rows(p, lambda: names_plan(names, p, dialect, notes))
        _, rows, batches = parquet_blocks(path)
        cols, refused = _spilled(batches, plan, p, spill, _told(progress, rows))
        if refused is not None:
            in_rows(p, partial(_raise, refused))
        return in_rows(p, lambda: log_from_columns(cols, p, dialect, notes))
    head = plain_header(path, dialect)
    if head is None:
        return read_log(path, dialect)
    delim, quoted, plan, notes = head
    rows = _data_lines(path)
    if rows < 1:
        return read_log(path, dialect)
    blocks = (np.column_stack(c) for c in number_blocks(path, delim, len(plan.raw), quoted,
                                                        dialect.decimal_comma, plan.kinds))
    counted = _Counted(blocks)
    try:
        cols, refused = _spilled(counted, plan, p, spill, _told(progress, rows))
        if counted.rows != rows:  # a blank line inside, which pyarrow skips
            raise NotFast
    except NotFast:
        refuse_bad_line(path, head, dialect, counted.rows)
        return read_log(path, dialect)
    if refused is not None:
        raise refused
    return log_from_columns(cols, p, dialect, notes)


def _told(progress: Callable[[int, int], None] | None, rows: int
          ) -> Callable[[int], None] | None:
    return None if progress is None else lambda done: progress(done, rows)


def _raise(e: LogError) -> None:
    raise e


class _Counted:
    """Blocks passed through, their rows counted (the rows read before a failure)."""

    def __init__(self, blocks: Iterator[np.ndarray]) -> None:
        self._blocks = blocks
        self.rows = 0

    def __iter__(self) -> Iterator[np.ndarray]:
        for b in self._blocks:
            self.rows += b.shape[0]
            yield b


def _spilled(blocks: Iterator[np.ndarray] | _Counted, plan: ColumnPlan, path: str,
             spill: Spill, progress: Callable[[int], None] | None
             ) -> tuple[dict[str, Column], LogError | None]:
    """({name: our column on disk} of every block, written to `spill`; the column map's
    refusal or None). The refusal is given, not raised: a bad cell after it comes first."""
    files = {s.name: spill.file(s.name, np.float64) for s in plan.sources}
    refused: dict[int, LogError] = {}  # source index -> its first refusal
    kept: dict[int, bool] = {}  # mapped valid sources -> some row is 1
    row0 = 0
    for data in blocks:
        raw = plan.raw_columns(data)
        for i, s in enumerate(plan.sources):
            if refused and min(refused) <= i:
                break  # a column before it is refused: what it gives no longer matters
            try:
                v = plan.values(s, data, raw, path, row0)
            except LogError as e:
                refused.setdefault(i, e)
                break
            if s.name == "valid" and s.origin:
                kept[i] = kept.get(i, False) or bool((v != 0.0).any())
            files[s.name].append(v)
        row0 += data.shape[0]
        if progress is not None:
            progress(row0)
    cols: dict[str, Column] = {name: f.column() for name, f in files.items()}
    for i, s in enumerate(plan.sources):
        if i in refused:
            return cols, refused[i]
        if i in kept and not kept[i]:
            return cols, plan.none_kept(s)(path)
    return cols, None


def in_memory(log: ChamberLog) -> ChamberLog:
    """A log on disk with its columns read into memory (the log `read_log` gives)."""
    def held(col):  # noqa: ANN001, ANN202 - a column on disk or in memory, an array
        return None if col is None else col[:] if is_lazy(col) else col

    return replace(log, time_s=held(log.time_s), temp_c=held(log.temp_c),
                   table_rate_dps=held(log.table_rate_dps), gyro_dps=held(log.gyro_dps),
                   earth_rate_dps=held(log.earth_rate_dps), valid=held(log.valid),
                   extra={k: held(v) for k, v in log.extra.items()})
