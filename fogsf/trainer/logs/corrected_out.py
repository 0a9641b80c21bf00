"""The corrected log `fogsf replay` writes: time_s, gyro_dps, gyro_corrected_dps and
sf_error_ppm (and bias_dph for a model with a bias head), as CSV (doubles with 17
significant digits, the time as logio's `time_format`, sf_error_ppm and bias_dph, float32,
with 9) or as Parquet when the path ends in .parquet (the doubles as float64, sf_error_ppm
and bias_dph as float32: every bit). Written block by block as the kernel produces them:
the same rows give the same bytes however they are cut into blocks for CSV, and for
Parquet with the same blocks (a row group each)."""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

import numpy as np

from fogsf.trainer.logs.logio import write_rows
from fogsf.trainer.logs.parquet_log import ParquetColumns, is_parquet

NAMES = ("time_s", "gyro_dps", "gyro_corrected_dps", "sf_error_ppm", "bias_dph")
DTYPES = (np.float64, np.float64, np.float64, np.float32, np.float32)


class CorrectedWriter:
    """Blocks of the corrected log to `path` (CSV or Parquet by its suffix); `time_fmt` is
    the CSV format of time_s (logio's `time_format` of the whole log's time_s); with `bias`
    (a model with a bias head), a fifth column bias_dph (float32, deg/h)."""

    def __init__(self, path: str | Path, time_fmt: str, bias: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.names = NAMES if bias else NAMES[:4]
        self._parquet: ParquetColumns | None = None
        self._csv: TextIO | None = None
        if is_parquet(self.path):
            self._parquet = ParquetColumns(self.path, dict(zip(self.names, map(np.dtype, DTYPES),
                                                               strict=False)))
        else:
            self._csv = open(self.path, "w", encoding="utf-8", newline="\n")
            self._csv.write(",".join(self.names) + "\n")
        self._fmts = [time_fmt, "%.17g", "%.17g", "%.9g", "%.9g"][:len(self.names)]

    def write(self, time_s: np.ndarray, gyro: np.ndarray, corrected: np.ndarray,
              sf_ppm: np.ndarray, bias_dph: np.ndarray | None = None) -> None:
        cols = [time_s, gyro, corrected, sf_ppm, bias_dph][:len(self.names)]
        if any(c is None for c in cols):
            raise ValueError("bias_dph: a writer with bias takes it with every block")
        if self._parquet is not None:
            self._parquet.write(dict(zip(self.names, cols, strict=True)))
        else:
            assert self._csv is not None
            rows = np.column_stack([np.asarray(c, dtype=np.float64) for c in cols])
            write_rows(self._csv, rows, self._fmts)

    def close(self) -> None:
        if self._parquet is not None:
            self._parquet.close()
        if self._csv is not None:
            self._csv.close()

    def __enter__(self) -> CorrectedWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
