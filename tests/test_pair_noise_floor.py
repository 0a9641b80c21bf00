"""The +/- pairs' noise floor is one pair's noise: successive pairs share plateaus, so the
spread of their second differences is scaled by the ratio the pairs' weights give (not
sqrt(6), which holds for independent pairs only)."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.bias import pair_windows, second_difference_ratio
from fogsf.logs.measure.pairs import find_pairs


def _reversals(seed: int, n_plateaus: int = 400, per: int = 600) -> ChamberLog:
    """+/-100 deg/s every 60 s at 10 Hz, a constant SF and bias, white noise: the pairs'
    bias scatters by noise alone."""
    rng = np.random.default_rng(seed)
    n = n_plateaus * per
    t = np.arange(n) * 0.1
    rate = np.where((np.arange(n) // per) % 2 == 0, 100.0, -100.0)
    gyro = rate * (1 + 20e-6) + 1e-3 + rng.normal(0.0, 0.05, n)
    return ChamberLog(t, np.full(n, 25.0), rate, gyro, np.zeros(n))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pair_floor_is_one_pairs_noise(seed: int) -> None:
    log = _reversals(seed)
    w = pair_windows(log)
    assert w is not None and len(w) > 150
    truth = float(np.std(w.bias_dph))  # constant bias: the pairs' spread is their noise
    assert 0.85 < w.noise_floor_dph / truth < 1.15, (w.noise_floor_dph, truth)


def test_ratio_of_shared_plateaus() -> None:
    log = _reversals(4, n_plateaus=40)
    pp = find_pairs(log)
    assert pp is not None
    # interior pairs of four equal plateaus sharing two: 20/72; the ends differ a little
    assert second_difference_ratio(pp) == pytest.approx(20.0 / 72.0, rel=0.05)
