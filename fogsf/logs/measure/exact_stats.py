"""Whole-series statistics made a block at a time with numpy's bits: the median (a radix
select over the float64 bit patterns, a few passes over the blocks, memory of one block and
a 64 k histogram) and the mean of a series seen once in order (numpy's pairwise sum).
`nominal_step_s` of a log whose time column is on disk uses them, and `median_step` gives
the median sample step of a time column of either kind."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from fogsf.logs.read import columns
from fogsf.logs.read.columns import _pairwise

Blocks = Callable[[], Iterator[np.ndarray]]  # a fresh pass over the series, block by block
DIGIT = 16
_SIGN = np.uint64(1 << 63)


def _keys(x: np.ndarray) -> np.ndarray:
    """uint64 keys in the order of the float64 values (IEEE 754 bit patterns, sign folded)."""
    u = np.ascontiguousarray(x, dtype=np.float64).view(np.uint64)
    return np.where(u & _SIGN, ~u, u | _SIGN)


def _value(key: int) -> float:
    k = np.uint64(key)
    u = k & ~_SIGN if k & _SIGN else ~k
    return float(np.array([u], dtype=np.uint64).view(np.float64)[0])


def _select(series: Blocks, rank: int) -> tuple[float, int]:
    """(the value of 0-based `rank` in sorted order, how many ranks after it hold the same
    value)."""
    prefix, shift = 0, 64
    for _ in range(64 // DIGIT):
        shift -= DIGIT
        hist = np.zeros(1 << DIGIT, dtype=np.int64)
        for x in series():
            k = _keys(x)
            if shift + DIGIT < 64:
                k = k[(k >> np.uint64(shift + DIGIT)) == np.uint64(prefix)]
            hist += np.bincount(((k >> np.uint64(shift)) & np.uint64((1 << DIGIT) - 1))
                                .astype(np.int64), minlength=1 << DIGIT)
        cum = np.cumsum(hist)
        d = int(np.searchsorted(cum, rank, side="right"))
        rank -= int(cum[d - 1]) if d else 0
        prefix = (prefix << DIGIT) | d
        same = int(hist[d]) - rank - 1
    return _value(prefix), same


def median(series: Blocks, n: int) -> float:
    """The bits of np.median over the `n` values `series` gives."""
    if n % 2:
        return _select(series, n // 2)[0]
    lo, same = _select(series, n // 2 - 1)
    hi = lo if same > 0 else _select(series, n // 2)[0]
    return float(np.mean(np.array([lo, hi])))


def mean_in_order(series: Blocks, n: int) -> float:
    """The bits of x.mean() of the `n` values `series` gives (x their concatenation)."""
    it = series()
    buf = np.empty(0)
    at = 0

    def take(a: int, b: int) -> np.ndarray:  # _pairwise asks for the series in order
        nonlocal buf, at
        assert a == at
        while buf.shape[0] < b - a:
            buf = np.concatenate([buf, next(it)])
        out, buf = buf[:b - a], buf[b - a:]
        at = b
        return out

    if n <= max(columns.READ_SAMPLES, columns.PAIRWISE_LEAF):
        return float(np.concatenate([*series(), np.empty(0)]).mean())
    return (0.0 + _pairwise(take, 0, n)) / n


def step_blocks(t: columns.Column) -> Blocks:
    """np.diff(t) a block at a time (a fresh pass each call)."""
    n = len(t)

    def steps() -> Iterator[np.ndarray]:
        size = columns.READ_SAMPLES
        for a in range(0, n - 1, size):
            yield np.diff(np.asarray(t[a:a + size + 1], dtype=np.float64))

    return steps


def median_step(t: columns.Column) -> float:
    """The bits of np.median(np.diff(t)) (NaN for fewer than two samples), a block at a time
    when t is a column on disk."""
    if not columns.is_lazy(t):
        return float(np.median(np.diff(np.asarray(t, dtype=np.float64))))
    if len(t) < 2:
        return float("nan")
    return median(step_blocks(t), len(t) - 1)
