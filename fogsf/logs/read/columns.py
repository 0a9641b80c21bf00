"""Columns of a log that are not held in memory: read from a spill file on disk, or computed
from other columns, a block at a time.

`replay` and `inspect` read a log of any length in bounded memory (logs/read/stream_read.py): the
log's columns are written to a temporary directory as raw float64 (a `Spill`, deleted when
the command ends) and a `ChamberLog` holds `DiskColumn`s over them. A `LazyColumn` answers
what the code asks of a column (`len`, `col[i]`, `col[a:b]`, `col[index array]`) by reading
only those samples; `np.asarray(col)` still reads the whole column (what a plot needs).
Whole-column results are made block by block (`blocks`, `col_min`, `col_max`,
`searchsorted`) and give the same bits as numpy over the whole array (`exact_sum` follows
numpy's pairwise summation; logs/measure/exact_stats.py has the median).
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from bisect import bisect_left
from collections.abc import Callable, Iterable, Iterator
from io import BufferedRandom
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import DTypeLike

if TYPE_CHECKING:
    from typing_extensions import TypeIs

from fogsf.errors import UserError

READ_SAMPLES = 1 << 18  # samples read at a time by the block helpers (2 MB of float64)
PAIRWISE_LEAF = 128  # numpy's pairwise summation: runs this long are summed in one loop
STRICT = False  # tests: refuse to read a whole column (np.asarray) where a block would do


class LazyColumn:
    """A read-only 1-D column of `n` samples of `dtype`, read on demand by `take(a, b)`
    (samples [a, b) as a new array)."""

    def __init__(self, n: int, dtype: np.dtype, take: Callable[[int, int], np.ndarray]) -> None:
        self.n = int(n)
        self.dtype = np.dtype(dtype)
        self._take = take

    @property
    def shape(self) -> tuple[int]:
        return (self.n,)

    @property
    def size(self) -> int:
        return self.n

    ndim = 1

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, at: int | slice | np.ndarray) -> np.ndarray:
        if isinstance(at, (int, np.integer)):
            i = int(at) + (self.n if at < 0 else 0)
            if not 0 <= i < self.n:
                raise IndexError(f"index {int(at)} out of range for {self.n} samples")
            return self._take(i, i + 1)[0]
        if isinstance(at, slice):
            a, b, step = at.indices(self.n)
            if step < 0:  # backwards: samples (b, a], read together
                return self._take(b + 1, a + 1)[::step] if a > b else np.empty(0, self.dtype)
            if step != 1:
                if b <= a:
                    return np.empty(0, self.dtype)
                # every step-th sample, read a block at a time (blocks of a multiple of step)
                size = max(1, READ_SAMPLES // step) * step
                return np.concatenate([self._take(s, min(b, s + size))[::step].copy()
                                       for s in range(a, b, size)])  # no block kept
            return self._take(a, b) if b > a else np.empty(0, self.dtype)
        idx = np.asarray(at)
        if idx.dtype == bool:
            raise TypeError("a lazy column takes slices and index arrays, not masks")
        idx = np.where(idx < 0, idx + self.n, idx)
        if idx.size == 0:
            return np.empty(idx.shape, self.dtype)
        if idx.ndim == 2:  # windows: one row per window, each a run of samples
            return np.stack([self._gather(row) for row in idx]) if idx.shape[0] else \
                np.empty(idx.shape, self.dtype)
        return self._gather(idx)

    def _gather(self, idx: np.ndarray) -> np.ndarray:
        lo, hi = int(idx.min()), int(idx.max()) + 1
        if hi - lo <= READ_SAMPLES:
            return self._take(lo, hi)[idx - lo]
        # scattered samples: only the blocks that hold them, one at a time
        out = np.empty(idx.shape, self.dtype)
        block = idx // READ_SAMPLES
        for b in np.unique(block):
            sel = block == b
            a = int(b) * READ_SAMPLES
            out[sel] = self._take(a, min(self.n, a + READ_SAMPLES))[idx[sel] - a]
        return out

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        if STRICT:
            raise AssertionError("a whole lazy column was read")
        out = self._take(0, self.n) if self.n else np.empty(0, self.dtype)
        return out if dtype is None else out.astype(dtype)

    def __iter__(self) -> Iterator[np.generic]:
        for _, x in blocks(self):
            yield from x

    # arithmetic and comparisons read the whole column (code that works a block at a time
    # does not use them; with STRICT, tests see where they are used)
    def _whole(self, other: object) -> tuple[np.ndarray, object]:
        return np.asarray(self), np.asarray(other) if isinstance(other, LazyColumn) else other

    def __add__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a + b

    def __radd__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return b + a

    def __sub__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a - b

    def __rsub__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return b - a

    def __mul__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a * b

    def __rmul__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return b * a

    def __truediv__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a / b

    def __rtruediv__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return b / a

    def __neg__(self) -> np.ndarray:
        return -np.asarray(self)

    def __abs__(self) -> np.ndarray:
        return np.abs(np.asarray(self))

    def __eq__(self, o: object) -> np.ndarray:  # type: ignore[override]
        a, b = self._whole(o)
        return a == b

    def __ne__(self, o: object) -> np.ndarray:  # type: ignore[override]
        a, b = self._whole(o)
        return a != b

    def __lt__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a < b

    def __le__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a <= b

    def __gt__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a > b

    def __ge__(self, o: object) -> np.ndarray:
        a, b = self._whole(o)
        return a >= b

    __hash__ = None  # type: ignore[assignment]

    def min(self) -> np.generic:
        return min(x.min() for _, x in blocks(self))

    def max(self) -> np.generic:
        return max(x.max() for _, x in blocks(self))

    def astype(self, dtype: np.dtype) -> LazyColumn:
        return LazyColumn(self.n, dtype, lambda a, b: self._take(a, b).astype(dtype))


def derived(n: int, dtype: np.dtype, f: Callable[[slice], np.ndarray]) -> LazyColumn:
    """A column computed sample by sample from others: f(slice) gives its samples there."""
    return LazyColumn(n, dtype, lambda a, b: np.asarray(f(slice(a, b)), dtype=dtype))


class Spill:
    """A temporary directory of raw columns (deleted by `close`, and at exit)."""

    def __init__(self, where: str | None = None) -> None:
        self.dir = Path(tempfile.mkdtemp(prefix="fogsf-spill-", dir=where))
        atexit.register(self.close)
        self._files: list[SpillFile] = []

    def file(self, name: str, dtype: DTypeLike) -> SpillFile:
        f = SpillFile(self.dir / f"{len(self._files)}.bin", np.dtype(dtype))
        self._files.append(f)
        return f

    def close(self) -> None:
        for f in self._files:
            f.close()
        shutil.rmtree(self.dir, ignore_errors=True)


class SpillFile:
    """One column written block by block (`append`), then read as a `DiskColumn`."""

    def __init__(self, path: Path, dtype: np.dtype) -> None:
        self.path = path
        self.dtype = dtype
        self.n = 0
        self._file: BufferedRandom | None = open(path, "w+b")  # noqa: SIM115 - closed by close()

    def append(self, block: np.ndarray) -> None:
        assert self._file is not None
        b = np.ascontiguousarray(block, dtype=self.dtype)
        try:
            self._file.seek(self.n * self.dtype.itemsize)
            self._file.write(b.data.cast("B"))
        except OSError as e:  # a full disk: one line, and what to do

            raise UserError(f"cannot write the log's columns to {self.path.parent}: "
                            f"{e.strerror or e}; they need 8 bytes a sample a column on disk "
                            "(set TMPDIR to a directory with room)") from None
        self.n += b.shape[0]

    def column(self) -> LazyColumn:
        size = self.dtype.itemsize

        def take(a: int, b: int) -> np.ndarray:
            assert self._file is not None
            out = np.empty(b - a, self.dtype)
            self._file.seek(a * size)
            if self._file.readinto(out.data.cast("B")) != (b - a) * size:
                raise OSError(f"{self.path}: spill file shorter than expected")
            return out

        return LazyColumn(self.n, self.dtype, take)

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


Column = np.ndarray | LazyColumn


def is_lazy(col: object) -> TypeIs[LazyColumn]:
    return isinstance(col, LazyColumn)


def stand_in(col: Column) -> np.ndarray:
    """`col` where an array is declared (a `ChamberLog`'s columns, a model's input): a lazy
    column stands in for one, answering len, indexing and slicing alike. Nothing is read."""
    return cast(np.ndarray, col)


def held(step_values: np.ndarray, like: Column, decimation: int) -> Column:
    """Per-sample values of a column like `like` (its length; on disk when it is) holding
    step i's value over its samples i*D .. i*D + D - 1: a log on disk gets a derived column,
    made a block at a time when read."""
    steps = np.asarray(step_values)
    if is_lazy(like):
        return derived(len(like), steps.dtype,
                       lambda s: steps[np.arange(s.start, s.stop) // decimation])
    return steps[np.arange(len(like)) // decimation]


def blocks(col: Column, a: int = 0, b: int | None = None, size: int | None = None
           ) -> Iterator[tuple[int, np.ndarray]]:
    """(start, samples) of col[a:b] in blocks of `size` (READ_SAMPLES)."""
    b = len(col) if b is None else min(b, len(col))
    size = size or READ_SAMPLES
    for s in range(a, b, size):
        yield s, np.asarray(col[s:min(b, s + size)])


def block_means(col: Column, k: int) -> np.ndarray:
    """The mean of every k consecutive samples (a trailing part of fewer is left out): the
    bits of col[:n // k * k].reshape(-1, k).mean(axis=1), read a block at a time."""
    n = len(col) // k * k
    size = max(1, READ_SAMPLES // k) * k
    parts = [np.asarray(x, dtype=np.float64).reshape(-1, k).mean(axis=1)
             for _, x in blocks(col, 0, n, size)]
    return np.concatenate(parts) if parts else np.empty(0)


def col_min(col: Column) -> float:
    if not is_lazy(col):
        return float(np.min(col))
    return float(min(x.min() for _, x in blocks(col)))


def col_max(col: Column) -> float:
    if not is_lazy(col):
        return float(np.max(col))
    return float(max(x.max() for _, x in blocks(col)))


def any_true(col: Column) -> bool:
    if not is_lazy(col):
        return bool(np.any(col))
    return any(bool(x.any()) for _, x in blocks(col))


def searchsorted(col: Column, v: float) -> int:
    """np.searchsorted(col, v) (side 'left') on an increasing column."""
    if not is_lazy(col):
        return int(np.searchsorted(col, v))
    return bisect_left(range(len(col)), v, key=lambda i: float(col[i]))


def all_equal(col: Column, a: int, b: int, v: float) -> bool:
    """np.all(col[a:b] == v)."""
    return all(bool(np.all(x == v)) for _, x in blocks(col, a, b))


def _pairwise(take: Callable[[int, int], np.ndarray], lo: int, n: int) -> float:
    """numpy's pairwise sum of samples [lo, lo + n), read in pieces of up to READ_SAMPLES:
    numpy halves a long run at a multiple of 8 until the pieces fit its unrolled loop, so a
    piece that is a node of that tree summed by numpy is that node's value (up to the sign
    of a zero, which the final 0.0 + removes); numpy sums up to PAIRWISE_LEAF at once."""
    if n <= max(READ_SAMPLES, PAIRWISE_LEAF):
        return float(np.add.reduce(take(lo, lo + n)))
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise(take, lo, n2) + _pairwise(take, lo + n2, n - n2)


def exact_sum(take: Callable[[int, int], np.ndarray], lo: int, hi: int) -> float:
    """The bits of np.sum(x[lo:hi]) where take(a, b) gives x[a:b] (float64)."""
    if hi - lo <= max(READ_SAMPLES, PAIRWISE_LEAF):
        return float(np.add.reduce(take(lo, hi)))
    return 0.0 + _pairwise(take, lo, hi - lo)


def exact_mean(col: Column, a: int, b: int) -> float:
    """The bits of col[a:b].mean()."""
    if not is_lazy(col) or b - a <= READ_SAMPLES:
        return float(np.asarray(col[a:b]).mean())
    return exact_sum(lambda x, y: np.asarray(col[x:y], dtype=np.float64), a, b) / (b - a)


def cumsum_at(col: Column, ends: np.ndarray) -> np.ndarray:
    """c[ends] of c = [0, cumsum(col as float64)], the sum carried from block to block in
    numpy's order (one add after another)."""
    return cumsum_blocks_at(blocks(col), ends)


def span_means(col: Column, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """The mean of col over each span [start, stop) (float64; in memory or on disk, where
    only the running sum at the spans' ends is kept). An in-memory array of several columns
    ([n, k]) gives each column's means ([spans, k])."""
    start, stop = np.asarray(start, dtype=np.int64), np.asarray(stop, dtype=np.int64)
    if is_lazy(col):
        at = cumsum_at(col, np.concatenate([start, stop]))
    else:
        x = np.asarray(col, dtype=np.float64)
        c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
        at = c[np.concatenate([start, stop])]
    n = (stop - start).reshape((-1,) + (1,) * (at.ndim - 1))
    return (at[start.size:] - at[:start.size]) / n


def cumsum_blocks_at(parts: Iterable[tuple[int, np.ndarray]], ends: np.ndarray
                     ) -> np.ndarray:
    """`cumsum_at` of the series given as (start, samples) blocks in order (a series made a
    block at a time, never whole): the same bits as np.cumsum over all of it."""
    order = np.argsort(ends, kind="stable")
    out = np.empty(ends.shape[0])
    j, carry = 0, 0.0
    srt = ends[order]
    while j < srt.size and srt[j] == 0:
        out[order[j]] = 0.0
        j += 1
    for a, x in parts:
        if x.shape[0] == 0:
            continue
        y = np.array(x, dtype=np.float64)
        y[0] += carry
        c = np.cumsum(y)
        carry = float(c[-1])
        hi = a + y.shape[0]
        while j < srt.size and srt[j] <= hi:
            out[order[j]] = c[srt[j] - a - 1]
            j += 1
    return out
