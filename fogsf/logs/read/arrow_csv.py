"""The fast reader of a log's cells: pyarrow's CSV reader (multi-threaded), block by block.

It reads the data rows (the header is read by logio through the column map) as float64 and
only says whether every cell is a finite number: it never refuses. A file it cannot read
that way (a cell that is no number, a row of another length, quotes where the header has
none, a non-finite cell, fewer rows than the file has lines: a blank line inside, which
pyarrow skips) gives
`NotFast`, and the general path reads the file again and names the line. pyarrow accepts
exactly the numbers numpy's parser does (leading and trailing blanks, `+.5e-3`, `1.`; not
`1_000`, `0x10` or an empty cell), rounded the same way.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fogsf.logs.read.cell_kinds import ISO_TIME, NUMBER, TEXT, epoch_seconds_ns

if TYPE_CHECKING:
    from pyarrow import csv as pa_csv

BLOCK_BYTES = 1 << 20  # pyarrow parses blocks of 1 MB (about 23 k rows of a 5-column log)


class NotFast(Exception):  # a signal to the caller, not an error
    """pyarrow could not read the cells as finite numbers: the general path reads the file.
    `rows_ok`: the first rows (blank lines not counted) that were read as finite numbers
    of the header's length before the failure."""

    def __init__(self, rows_ok: int = 0) -> None:
        super().__init__(rows_ok)
        self.rows_ok = rows_ok


def _options(delim: str, ncol: int, quoted: bool, decimal_comma: bool,
             kinds: tuple[str, ...] = ()
             ) -> tuple[pa_csv.ReadOptions, pa_csv.ParseOptions, pa_csv.ConvertOptions]:
    import pyarrow as pa
    from pyarrow import csv

    names = [f"c{i}" for i in range(ncol)]
    kinds = kinds or (NUMBER,) * ncol
    types = {NUMBER: pa.float64(), ISO_TIME: pa.timestamp("ns", "UTC"), TEXT: pa.string()}
    read = csv.ReadOptions(column_names=names, skip_rows=1, block_size=BLOCK_BYTES,
                           use_threads=True)
    parse = csv.ParseOptions(delimiter=delim, quote_char='"' if quoted else False,
                             double_quote=quoted, ignore_empty_lines=True,
                             newlines_in_values=False)
    convert = csv.ConvertOptions(column_types={n: types[k] for n, k in zip(names, kinds,
                                                                          strict=True)},
                                 null_values=[], strings_can_be_null=False,
                                 quoted_strings_can_be_null=False,
                                 decimal_point="," if decimal_comma else ".")
    return read, parse, convert


def number_blocks(path: str | Path, delim: str, ncol: int, quoted: bool = False,
                  decimal_comma: bool = False, kinds: tuple[str, ...] = ()
                  ) -> Iterator[list[np.ndarray]]:
    """The data rows (the first line is the header) in blocks, in order: each block its
    `ncol` float64 columns (pyarrow's own buffers, valid until the next block); raises
    NotFast on a cell that is not a finite number or a malformed row."""
    import pyarrow as pa
    from pyarrow import csv

    read, parse, convert = _options(delim, ncol, quoted, decimal_comma, kinds)
    kinds = kinds or (NUMBER,) * ncol
    try:
        # the system's allocator: blocks freed go back to it (pyarrow's own pool keeps them)
        pool = pa.system_memory_pool()
        for batch in csv.open_csv(str(path), read, parse, convert, memory_pool=pool):
            cols = [_as_numbers(c, k) for c, k in zip(batch.columns, kinds, strict=True)]
            if not all(np.isfinite(c).all() for c in cols):
                raise NotFast
            yield cols
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, OSError, UnicodeDecodeError):
        raise NotFast from None


def _as_numbers(column, kind: str) -> np.ndarray:  # noqa: ANN001 - a pyarrow array
    """A parsed column as float64: numbers as they are, time stamps as epoch seconds, text
    as zeros (a column the map does not read)."""
    if kind == TEXT:
        return np.zeros(len(column))
    if kind == ISO_TIME:
        if column.null_count:
            raise NotFast
        return epoch_seconds_ns(column.cast("int64").to_numpy())
    return column.to_numpy(zero_copy_only=False)


def read_numbers(path: str | Path, rows: int, delim: str, ncol: int, quoted: bool = False,
                 decimal_comma: bool = False, kinds: tuple[str, ...] = ()) -> np.ndarray:
    """Every data row as one float64 array [rows, ncol] (each column contiguous), filled
    block by block (no second copy of the log); NotFast when the file does not hold exactly
    `rows` data rows of finite numbers."""
    out = np.empty((rows, ncol), dtype=np.float64, order="F")
    at = 0
    try:
        for cols in number_blocks(path, delim, ncol, quoted, decimal_comma, kinds):
            k = cols[0].shape[0]
            if at + k > rows:
                raise NotFast
            for i, c in enumerate(cols):
                out[at:at + k, i] = c
            at += k
    except NotFast:
        raise NotFast(at) from None
    if at != rows:
        raise NotFast(at)
    return out
