"""The corrected log `fogsf replay` writes: time_s, gyro_dps, gyro_corrected_dps and
sf_error_ppm (and bias_dph for a model with a bias head), as CSV or as Parquet when the path
ends in .parquet. CSV cells are each number's shortest decimal form that reads back as the
same number (pyarrow's CSV writer): the doubles as float64, sf_error_ppm and bias_dph as
float32 (so `2.7094662`, read as float32, is the kernel's float32 exactly); Parquet holds
the doubles as float64, sf_error_ppm and bias_dph as float32: every bit either way. Written
block by block as the kernel produces them: the same rows give the same bytes however they
are cut into blocks for CSV, and for Parquet with the same blocks (a row group each)."""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

import numpy as np

from fogsf.logs.read.parquet_log import ParquetColumns, arrow_table, is_parquet

NAMES = ("time_s", "gyro_dps", "gyro_corrected_dps", "sf_error_ppm", "bias_dph")
DTYPES = (np.float64, np.float64, np.float64, np.float32, np.float32)


class CorrectedWriter:
    """Blocks of the corrected log to `path` (CSV or Parquet by its suffix); with `bias` (a
    model with a bias head), a fifth column bias_dph (float32, deg/h)."""

    def __init__(self, path: str | Path, bias: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.names = NAMES if bias else NAMES[:4]
        dtypes = dict(zip(self.names, map(np.dtype, DTYPES), strict=False))
        self._parquet: ParquetColumns | None = None
        self._csv: CsvColumns | None = None
        if is_parquet(self.path):
            self._parquet = ParquetColumns(self.path, dtypes)
        else:
            self._csv = CsvColumns(self.path, dtypes)

    def write(self, time_s: np.ndarray, gyro: np.ndarray, corrected: np.ndarray,
              sf_ppm: np.ndarray, bias_dph: np.ndarray | None = None) -> None:
        cols = [time_s, gyro, corrected, sf_ppm, bias_dph][:len(self.names)]
        given = [c for c in cols if c is not None]
        if len(given) < len(cols):
            raise ValueError("bias_dph: a writer with bias takes it with every block")
        block = dict(zip(self.names, given, strict=True))
        if self._parquet is not None:
            self._parquet.write(block)
        else:
            assert self._csv is not None
            self._csv.write(block)

    def close(self) -> None:
        if self._parquet is not None:
            self._parquet.close()
        if self._csv is not None:
            self._csv.close()

    def __enter__(self) -> CorrectedWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class CsvColumns:
    """A CSV file written block by block by pyarrow's writer: a header line of the names,
    then each number in its shortest decimal form that reads back as the same number of its
    dtype (float64 or float32), no quotes."""

    def __init__(self, path: str | Path, dtypes: dict[str, np.dtype]) -> None:
        import pyarrow as pa
        from pyarrow import csv

        self.schema = pa.schema([(k, pa.from_numpy_dtype(np.dtype(d))) for k, d in dtypes.items()])
        self._file: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed by close()
        self._file.write((",".join(dtypes) + "\n").encode())
        self._writer = csv.CSVWriter(self._file, self.schema, write_options=csv.WriteOptions(
            include_header=False, quoting_style="none", batch_size=1 << 16))

    def write(self, block: dict[str, np.ndarray]) -> None:
        self._writer.write_table(arrow_table(self.schema, block))

    def close(self) -> None:
        self._writer.close()
        self._file.close()
