"""A +/- pair's bias averages its four plateaus (1, 3, 3, 1)/8: the bias model is fitted to
its columns averaged the same way (`training.bias.targets.target_kernel`, `at_targets`)."""

from __future__ import annotations

import numpy as np

from fogsf.logs.measure.bias import BiasWindows
from fogsf.training.bias.targets import at_targets, target_kernel


def _windows(source: str, window_s: float) -> BiasWindows:
    z = np.zeros(3)
    return BiasWindows(source, z, z, z, z.astype(np.int64), z.astype(np.int64) + 1, 0.1,
                       window_s, 0.0)


def test_pair_kernel_is_the_pairs_weights() -> None:
    k = target_kernel(_windows("pairs", 120.0), 5.0)  # plateaus of 60 s: 12 steps each
    assert k is not None and k.size == 48
    assert np.isclose(k.sum(), 1.0)
    assert np.allclose(k[:12] * 8 * 12, 1.0) and np.allclose(k[12:36] * 8 * 12, 3.0)
    assert target_kernel(_windows("stationary", 100.0), 5.0) is None


def test_at_targets_averages_as_the_targets_do() -> None:
    k = target_kernel(_windows("pairs", 40.0), 5.0)  # 4 steps a plateau
    assert k is not None
    x = np.column_stack([np.arange(100.0), np.where(np.arange(100) < 50, 0.0, 1.0)])
    y = at_targets(x, k)
    assert y.shape == x.shape
    # step c's target: the steps c - L/2 .. c + L/2 - 1 weighted by the kernel (the pair's
    # centre is where step c starts, so a ramp reads half a step before c's own value)
    half = k.size // 2
    for c in (20, 49, 50, 51, 79):
        assert np.allclose(y[c], k @ x[c - half:c + half])
    assert np.allclose(y[20:80, 0], x[20:80, 0] - 0.5)
    assert at_targets(x, None) is x
