"""Chamber logs as Parquet (pyarrow): the same column names, column map and rules as CSV.

A Parquet log holds one column per name of a CSV log's header, each numeric (floating
point, integer or boolean: read as float64). Its names go through the column map, --axis
and --gyro-column as a header row does, and the log is validated by the same rules; a
refusal names the data row (from 1) where a CSV refusal names the line, and the column
names where it names line 1. Parquet has no delimiter and no decimal comma: --delimiter and
--decimal-comma are said not to apply. `write_columns` writes named columns as Parquet, the
same columns giving the same bytes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from fogsf.logs.chamber_log import LogError
from fogsf.logs.read.dialect import Dialect, checked_names, names_plan

PARQUET_SUFFIXES = (".parquet", ".pq")
BATCH_ROWS = 1 << 17  # rows read (and written) per batch
COMPRESSION = "zstd"

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.parquet as pq

T = TypeVar("T")


def is_parquet(path: str | Path) -> bool:
    """Whether a log or an output path names a Parquet file (by its suffix)."""
    return Path(path).suffix.lower() in PARQUET_SUFFIXES


def _open(path: str | Path) -> pq.ParquetFile:
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = str(path)
    try:
        # no pre-buffering: it holds column chunks read ahead, memory that grows with the file
        return pq.ParquetFile(p, pre_buffer=False)
    except FileNotFoundError:
        raise LogError(p, None, "cannot read", "no such file") from None
    except (pa.ArrowException, OSError) as e:
        raise LogError(p, None, "cannot read", f"not a Parquet file ({e})") from None


def parquet_names(path: str | Path) -> list[str]:
    """The column names of a Parquet log (its schema), checked as a header row is."""
    return in_rows(str(path), lambda: checked_names(list(_open(path).schema_arrow.names),
                                                     str(path)))


def in_rows(path: str, f: Callable[[], T]) -> T:
    """f(), its LogError told in a Parquet log's terms: line 1 is its column names, line L
    its data row L - 1."""
    try:
        return f()
    except LogError as e:
        if e.path != path or e.line is None:
            raise
        where = "column names" if e.line == 1 else f"row {e.line - 1}"
        raise LogError(path, None, e.rule, f"{where}: {e.detail}") from None


def read_parquet_numbers(path: str | Path) -> tuple[list[str], np.ndarray]:
    """(column names, every column as float64 [rows, columns], each column contiguous),
    batch by batch; a column that is not numeric, an empty (null) or non-finite cell is
    refused with its row."""
    names, rows, batches = parquet_blocks(path)
    out = np.empty((rows, len(names)), dtype=np.float64, order="F")
    at = 0
    for block in batches:
        out[at:at + block.shape[0]] = block
        at += block.shape[0]
    return names, out


def parquet_blocks(path: str | Path) -> tuple[list[str], int, Iterator[np.ndarray]]:
    """(column names, rows, the rows in blocks of BATCH_ROWS as float64 [rows, columns]); a
    column that is not numeric or an empty file is refused here, an empty (null) or
    non-finite cell with its row when its block is read."""
    import pyarrow as pa

    p = str(path)
    pf = _open(path)
    names = parquet_names(path)
    for field in pf.schema_arrow:
        t = field.type
        if not (pa.types.is_floating(t) or pa.types.is_integer(t) or pa.types.is_boolean(t)):
            raise LogError(p, None, "non-numeric column",
                           f"column {field.name!r} holds {t}: a log's columns are numbers")
    rows = pf.metadata.num_rows
    if rows == 0:
        raise LogError(p, None, "empty file", "column names but no data rows")

    def read() -> Iterator[pa.RecordBatch]:
        # a file damaged past its footer fails where its pages are read: one line too
        try:
            yield from pf.iter_batches(batch_size=BATCH_ROWS, use_threads=True)
        except (pa.ArrowException, OSError) as e:
            raise LogError(p, None, "cannot read", f"a damaged Parquet file ({e})") from None

    def batches() -> Iterator[np.ndarray]:
        at = 0
        for batch in read():
            k = batch.num_rows
            out = np.empty((k, len(names)), dtype=np.float64, order="F")
            for i, col in enumerate(batch.columns):
                if col.null_count:
                    r = at + int(np.flatnonzero(col.is_null().to_numpy(zero_copy_only=False))[0])
                    raise LogError(p, None, "empty cell", f"row {r + 1}: column {names[i]!r} "
                                                          "has no value (null)")
                v = col.to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
                bad = np.flatnonzero(~np.isfinite(v))
                if bad.size:
                    r = int(bad[0])
                    raise LogError(p, None, "non-finite cell",
                                   f"row {at + r + 1}: column {names[i]!r} is {v[r]:g}")
                out[:, i] = v
            at += k
            yield out

    return names, rows, batches()


def read_parquet_log(path: str | Path, dialect: Dialect,
                     log_of: Callable[..., T]) -> T:
    """A Parquet log through the column map and the rules of a CSV log (`log_of`:
    logs.validation's `_log_of`, from the parsed cells, the plan, the path, the dialect, the
    notes)."""
    p = str(path)
    notes: list[str] = []
    given = [o for o, on in (("--delimiter", dialect.delimiter), ("--decimal-comma",
                                                                  dialect.decimal_comma)) if on]
    if given:
        notes.append(f"{' and '.join(given)} not used: a Parquet log")
    names = parquet_names(path)
    plan = in_rows(p, lambda: names_plan(names, p, dialect, notes))
    _, data = read_parquet_numbers(path)
    return in_rows(p, lambda: log_of(data, plan, p, dialect, notes))


def write_columns(path: str | Path, columns: dict[str, np.ndarray],
                  block_rows: int = BATCH_ROWS) -> None:
    """Named columns (float64 or float32, all of one length) as one Parquet file, a row
    group per `block_rows` rows; the same columns give the same bytes."""
    with ParquetColumns(path, {k: v.dtype for k, v in columns.items()}) as w:
        n = len(next(iter(columns.values()))) if columns else 0
        for a in range(0, n, block_rows):
            w.write({k: v[a:a + block_rows] for k, v in columns.items()})


def arrow_table(schema: pa.Schema, block: dict[str, np.ndarray]) -> pa.Table:
    """`block`'s columns as an Arrow table of `schema` (each cast to its field's type): what
    the Parquet and CSV column writers write."""
    import pyarrow as pa

    arrays = [pa.array(np.asarray(block[f.name], dtype=f.type.to_pandas_dtype()))
              for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


class ParquetColumns:
    """A Parquet file written block by block (a row group per block): named columns of fixed
    dtypes. The same blocks give the same bytes."""

    def __init__(self, path: str | Path, dtypes: dict[str, np.dtype]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        self.schema = pa.schema([(k, pa.from_numpy_dtype(np.dtype(d)))
                                 for k, d in dtypes.items()])
        self._writer = pq.ParquetWriter(str(path), self.schema, compression=COMPRESSION)

    def write(self, block: dict[str, np.ndarray]) -> None:
        self._writer.write_table(arrow_table(self.schema, block))

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> ParquetColumns:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
