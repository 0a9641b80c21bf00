"""SF windows, the 20 C reference, the metrics block and the noise floor, on logs whose
truth is known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import log_metrics, metrics_block, sf_error_ppm
from fogsf.logs.measure.pairs import plateau_pairs
from fogsf.logs.measure.plateaus import plateaus
from fogsf.logs.measure.sf_reference import reference_sf, reference_temp_c
from fogsf.logs.measure.windows import sf_windows


def ramp_log(n: int, sf_ppm: np.ndarray, rate: np.ndarray | float = 10.0, noise_dps: float = 0.0,
             bias_dps: float | np.ndarray = 0.0, seed: int = 0,
             temp: np.ndarray | None = None) -> ChamberLog:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    table = np.broadcast_to(np.asarray(rate, dtype=float), (n,)).copy()
    earth = np.full(n, 0.0023)
    gyro = (table + earth) * (1 + sf_ppm * 1e-6) + bias_dps + rng.normal(0, noise_dps, n)
    if temp is None:
        temp = np.linspace(-40, 50, n)
    return ChamberLog(t, temp, table, gyro, earth)


def test_windows_do_not_straddle_rate_changes() -> None:
    rate = np.where(np.arange(5000) < 2550, 10.0, -20.0)
    log = ramp_log(5000, np.zeros(5000), rate)
    w = sf_windows(log, window_s=100.0, settle_s=0.0)
    assert plateaus(rate) == [(0, 2550), (2550, 5000)]
    # 2 whole windows in the first plateau, 2 in the second; the tails are not windows
    assert list(w.start) == [0, 1000, 2550, 3550]
    # the settle margin (2 s by default) is trimmed off the second plateau's first window;
    # the log's first plateau follows no change and is not settled
    w = sf_windows(log, window_s=100.0)
    assert list(w.start) == [0, 1000, 2570, 3550] and list(w.stop) == [1000, 2000, 3550, 4550]
    assert set(np.unique(w.rate_dps)) == {10.0, -20.0}
    np.testing.assert_allclose(w.sf_ratio, 1.0, atol=1e-12)


def test_reference_and_metrics_of_known_curve() -> None:
    n = 54000
    temp = np.linspace(-40, 50, n)
    true = 3.0 * (temp - 20.0) + 0.05 * (temp - 20.0) ** 2 + 150.0  # ppm vs nominal
    log = ramp_log(n, true, temp=temp)
    w = sf_windows(log)
    ref = reference_sf(w)
    assert ref == pytest.approx(1 + 150e-6, abs=2e-7)
    e = sf_error_ppm(w, ref)
    expected = 3.0 * (w.temp_c - 20.0) + 0.05 * (w.temp_c - 20.0) ** 2
    np.testing.assert_allclose(e, expected, atol=0.3)
    m = log_metrics(log)
    assert m["max_abs_ppm"] == pytest.approx(np.max(np.abs(expected)), abs=0.5)
    assert m["rms_ppm"] > m["std_ppm"]  # the error is not centred on the reference
    assert set(m) == {"max_abs_ppm", "pp_ppm", "rms_ppm", "std_ppm", "window_s",
                      "noise_floor_ppm"}


def test_metrics_block_definitions() -> None:
    m = metrics_block(np.array([1.0, -3.0, 2.0]), 100.0, 0.5)
    assert m["max_abs_ppm"] == 3.0 and m["pp_ppm"] == 5.0
    assert m["rms_ppm"] == pytest.approx(np.sqrt(14 / 3))
    assert m["std_ppm"] == pytest.approx(np.std([1.0, -3.0, 2.0]))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_floor_matches_true_noise(seed: int) -> None:
    # white rate noise of sigma per sample: one 100 s window mean has sigma / sqrt(1000)
    n, sigma = 100_000, 2.6e-3
    temp = np.linspace(-40, 50, n)
    true = 4.0 * (temp - 20.0)
    noisy = sf_windows(ramp_log(n, true, noise_dps=sigma, seed=seed, temp=temp))
    clean = sf_windows(ramp_log(n, true, temp=temp))
    true_noise = np.std((noisy.sf_ratio - clean.sf_ratio) * 1e6)
    expected = sigma / np.sqrt(1000) / 10.0 * 1e6
    assert true_noise == pytest.approx(expected, rel=0.25)
    m = log_metrics(ramp_log(n, true, noise_dps=sigma, seed=seed, temp=temp))
    assert m["noise_floor_ppm"] == pytest.approx(true_noise, rel=0.2)


def test_correction_gives_residual() -> None:
    n = 20000
    temp = np.linspace(0, 40, n)
    true = 5.0 * temp + 100.0
    log = ramp_log(n, true, temp=temp)
    m = log_metrics(log, correction_ppm=true)
    assert m["max_abs_ppm"] < 1e-6
    m2 = log_metrics(log, correction_ppm=true - 7.0)
    assert m2["rms_ppm"] == pytest.approx(7.0, abs=0.01)
    with pytest.raises(UserError, match="samples"):
        log_metrics(log, correction_ppm=true[:-1])


def test_plateau_pairs_separate_sf_and_bias() -> None:
    n = 12000
    rate = np.where((np.arange(n) // 1000) % 2 == 0, 10.0, -10.0)
    log = ramp_log(n, np.full(n, 200.0), rate=rate, bias_dps=1e-3, temp=np.full(n, 20.0))
    pp = plateau_pairs(log)
    assert len(pp.sf_ratio) == 6
    np.testing.assert_allclose(pp.sf_ratio, 1 + 200e-6, atol=1e-12)
    np.testing.assert_allclose(pp.bias_dps, 1e-3 + 0.0023 * 200e-6, atol=1e-12)


def test_a_log_off_20c_takes_the_nearest_temperature(capsys) -> None:
    n = 20000
    log = ramp_log(n, np.zeros(n), temp=np.linspace(30, 50, n))
    log_metrics(log)
    assert "the SF reference is the SF at 30" in capsys.readouterr().err
    assert log_metrics(log, ref=1.0)["max_abs_ppm"] < 1e-6


def test_short_log_refused() -> None:
    # under 5 s at one rate: no window (the refusal names the options that decide it)
    with pytest.raises(UserError, match="no complete.*--settle-s.*--window-s"):
        sf_windows(ramp_log(45, np.zeros(45)))
    # 50 s, shorter than a 100 s window: one SF sample, with its noise from sub-windows
    w = sf_windows(ramp_log(500, np.zeros(500), noise_dps=1e-3))
    assert len(w) == 1 and w.stop[0] - w.start[0] == 500 and np.isfinite(w.noise_ppm[0])


def test_reference_between_set_points() -> None:
    """A log held at set points on both sides of 20 C (none within 5 C) gives the SF at
    20 C by interpolation; set points further than 15 C away do not."""
    n = 4000
    temp = np.where(np.arange(n) < n // 2, 8.0, 31.0)
    sf = 3.0 * (temp - 20.0)  # ppm, 0 at 20 C
    log = ramp_log(n, sf, temp=temp)
    w = sf_windows(log, 20.0)
    assert abs(reference_sf(w) - 1.0) < 1e-9
    far = ramp_log(n, sf, temp=np.where(np.arange(n) < n // 2, 2.0, 31.0))
    wf = sf_windows(far, 20.0)  # too far to interpolate: the nearest set point, 31 C
    assert reference_temp_c(wf) == 31.0
    assert abs(reference_sf(wf) - (1.0 + 33e-6)) < 2e-8  # 0.02 ppm
