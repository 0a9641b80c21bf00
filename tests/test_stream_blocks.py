"""Series made a block at a time give the bits of numpy over the whole series: the lag
(`sim.lag.lag_blocks`), block means, strided reads of a column on disk, running sums over
blocks and the median step of a time column."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.logs.measure.exact_stats import median_step
from fogsf.logs.read import columns
from fogsf.logs.read.columns import LazyColumn, block_means, cumsum_at, cumsum_blocks_at
from fogsf.sim.lag import first_order_lag, lag_blocks


def _lazy(x: np.ndarray) -> LazyColumn:
    return LazyColumn(x.shape[0], x.dtype, lambda a, b: x[a:b].copy())


def _series(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0.0, 0.05, n)) + 20.0


def _recurrence(u: np.ndarray, tau: float, dt: float, y0: float) -> np.ndarray:
    """The lag one step after another (the definition first_order_lag vectorises)."""
    r = dt / tau
    a = np.exp(-r)
    g = -np.expm1(-r) / r
    y = np.empty_like(u)
    y[0] = y0
    for k in range(u.shape[0] - 1):
        y[k + 1] = a * y[k] + (g - a) * u[k] + (1.0 - g) * u[k + 1]
    return y


@pytest.mark.parametrize("tau", [0.0, 0.5, 30.0, 600.0])
def test_lag_blocks_are_the_lag(tau: float) -> None:
    u = _series(20011, 1)
    whole = first_order_lag(u, tau, 0.1, 19.0)
    own = np.concatenate([y for _, y in lag_blocks(_lazy(u), tau, 0.1, 19.0)])
    assert np.array_equal(own, whole)  # first_order_lag's own chunks: the same bits
    parts = list(lag_blocks(_lazy(u), tau, 0.1, 19.0, max_block=777))
    starts = [a for a, _ in parts]
    assert starts == sorted(starts) and max(y.shape[0] for _, y in parts) <= 777
    bounded = np.concatenate([y for _, y in parts])
    assert bounded.shape == u.shape
    np.testing.assert_allclose(bounded, whole, rtol=0, atol=1e-11)
    if tau > 0:
        np.testing.assert_allclose(bounded, _recurrence(u, tau, 0.1, 19.0), rtol=0, atol=1e-9)


def test_block_means_and_strided_reads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", 97)
    x = _series(10007, 2)
    col = _lazy(x)
    for k in (1, 3, 50, 300):
        assert np.array_equal(block_means(col, k), x[:x.shape[0] // k * k].reshape(-1, k)
                              .mean(axis=1))
    for sl in (slice(None, None, 7), slice(5, 9001, 200), slice(None, None, -3),
               slice(10, 2, -2), slice(3, 3, 5)):
        assert np.array_equal(col[sl], x[sl])


def test_running_sums_over_blocks() -> None:
    x = _series(5003, 3)
    ends = np.array([0, 1, 17, 5003, 2500, 2500, 4000])
    whole = np.concatenate([[0.0], np.cumsum(x)])[ends]
    parts = [(a, x[a:a + 333]) for a in range(0, x.shape[0], 333)]
    assert np.array_equal(cumsum_blocks_at(iter(parts), ends), whole)
    assert np.array_equal(cumsum_at(_lazy(x), ends), whole)


def test_median_step_on_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", 97)
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.choice([0.01, 0.01, 0.010000001, 0.02], size=4001))
    assert median_step(_lazy(t)) == float(np.median(np.diff(t)))
    assert median_step(t) == float(np.median(np.diff(t)))


@pytest.mark.parametrize("n", [17, 480, 1201])
def test_sign_flip_in_chunks(n: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The sign-flip test draws its signs a chunk at a time: the p-value of one draw of all."""
    from fogsf.diagnose import stats

    d = np.random.default_rng(n).normal(0.1, 1.0, n)
    whole = stats.sign_flip_p(d, draws=3000)
    monkeypatch.setattr(stats, "SIGN_ROWS_SAMPLES", 7 * n + 3)
    assert stats.sign_flip_p(d, draws=3000) == whole
    signs = np.random.default_rng(0).choice((1.0, -1.0), size=(3000, n))
    hits = int(np.sum(signs @ np.abs(d) >= d.sum() - 1e-12 * (1 + abs(d.sum()))))
    assert whole == (hits + 1) / 3001


def test_profile_solve_in_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """The profile over a grid, a few combinations at a time: the bits of all at once."""
    from fogsf.models.structures import node_fit

    rng = np.random.default_rng(5)
    x = rng.normal(size=(23, 300, 6))
    y = x[7] @ rng.normal(size=6) + rng.normal(0.0, 0.1, 300)
    w = rng.uniform(0.5, 2.0, 300)
    rows = np.flatnonzero(rng.uniform(size=300) < 0.8)
    whole = node_fit.profile_solve(x, y, w, rows)
    assert whole.index == 7
    monkeypatch.setattr(node_fit, "PROFILE_CHUNK", rows.shape[0] * 6 * 4)  # 4 at a time
    part = node_fit.profile_solve(x, y, w, rows)
    assert part.index == whole.index
    for a, b in ((part.beta, whole.beta), (part.sse, whole.sse), (part.cov, whole.cov)):
        assert np.array_equal(a, b)


def test_held_steps_on_disk_are_the_expanded_steps() -> None:
    """Step values held over their samples: a column on disk gets a derived column with the
    same samples, read in any block; one in memory the array itself."""
    from fogsf.models.reference import expand

    steps = _series(101, 5)
    x = _series(1003, 6)
    whole = expand(steps, x.shape[0], 10)
    assert np.array_equal(columns.held(steps, x, 10), whole)
    lazy = columns.held(steps, _lazy(x), 10)
    assert columns.is_lazy(lazy) and len(lazy) == x.shape[0]
    assert np.array_equal(np.concatenate([b for _, b in columns.blocks(lazy, size=97)]), whole)
