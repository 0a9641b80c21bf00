"""Whole-series statistics a block at a time (logs/measure/exact_stats.py, logs/read/columns.py):
the bits numpy gives over the whole array, at every length and block size."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.logs.measure import exact_stats
from fogsf.logs.read import columns


def _series(kind: int, n: int, rng: np.random.Generator) -> np.ndarray:
    if kind == 0:
        return rng.standard_normal(n) * 10 ** rng.uniform(-3, 5, n)
    if kind == 1:  # few distinct values: time steps printed to a few digits
        return np.round(rng.standard_normal(n), 1) * 0.01 + 0.01
    x = np.full(n, 0.01)
    x[::7], x[::11] = 0.02, -3.0
    return x


@pytest.mark.parametrize("read", [97, 1 << 18])
@pytest.mark.parametrize("n", [1, 2, 3, 10, 129, 200, 411, 1000, 5003, 300_001])
def test_median_mean_sum_are_numpys(n: int, read: int, monkeypatch: pytest.MonkeyPatch
                                    ) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", read)
    rng = np.random.default_rng(n)
    for kind in range(3):
        x = _series(kind, n, rng)

        def blocks(x: np.ndarray = x) -> object:
            return (x[a:a + 31_337] for a in range(0, n, 31_337))

        assert exact_stats.median(blocks, n) == np.median(x), kind
        assert exact_stats.mean_in_order(blocks, n) == x.mean(), kind
        spill = columns.Spill()
        f = spill.file("x", np.float64)
        f.append(x[: n // 2])
        f.append(x[n // 2:])
        c = f.column()
        for a, b in ((0, n), (n // 3, n - 1)):
            if b > a:
                assert columns.exact_mean(c, a, b) == x[a:b].mean(), (kind, a, b)
        ends = np.unique(rng.integers(0, n + 1, 20))
        assert np.array_equal(columns.cumsum_at(c, ends),
                              np.concatenate([[0.0], np.cumsum(x)])[ends])
        idx = rng.integers(0, n, (3, 5))
        assert np.array_equal(c[idx], x[idx]) and c[n - 1] == x[-1]
        assert np.array_equal(c[1:n:2], x[1:n:2])
        spill.close()


def test_span_means_of_several_columns_are_each_columns() -> None:
    """`columns.span_means` of an [n, k] array: each column's span means, bit for bit those
    of the column alone (the bias interval's windows of a design use it)."""
    rng = np.random.default_rng(5)
    x = rng.normal(3.0, 2.0, (1000, 3))
    start = np.array([0, 10, 400, 999])
    stop = np.array([5, 400, 1000, 1000])
    got = columns.span_means(x, start, stop)
    assert got.shape == (4, 3)
    for j in range(3):
        one = columns.span_means(x[:, j], start, stop)
        assert np.array_equal(got[:, j], one)
        assert np.allclose(one, [x[a:b, j].mean() for a, b in zip(start, stop, strict=True)])
