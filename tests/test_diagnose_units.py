"""Unit tests of the diagnose pieces on data made with small numpy functions (no simulator)
and of its statistics against known values."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.diagnose import crossval, driver, stats, verdict
from fogsf.logs.chamber_log import ChamberLog, earth_rate_vertical_dps
from fogsf.sim.lag import first_order_lag

DT = 0.1


def test_chi2_tail_matches_tables() -> None:
    # 95th percentiles of chi-square with 1, 10 and 30 degrees of freedom
    assert stats.chi2_sf(3.841459, 1) == pytest.approx(0.05, abs=1e-5)
    assert stats.chi2_sf(18.307038, 10) == pytest.approx(0.05, abs=1e-5)
    assert stats.chi2_sf(43.772972, 30) == pytest.approx(0.05, abs=1e-5)
    assert stats.chi2_sf(0.0, 4) == 1.0


def test_trimmed_chi2_mean_matches_monte_carlo() -> None:
    z2 = np.sort(np.random.default_rng(1).standard_normal(400_000) ** 2)
    mc = z2[: int(0.95 * z2.size)].mean()
    assert stats.trimmed_chi2_1_mean(0.95) == pytest.approx(mc, rel=0.01)


def test_ljung_box_tells_white_from_correlated() -> None:
    rng = np.random.default_rng(2)
    white = [rng.standard_normal(120) for _ in range(3)]
    ar = np.zeros(120)
    for i in range(1, 120):
        ar[i] = 0.8 * ar[i - 1] + rng.standard_normal()
    assert stats.ljung_box_p(white) > 0.01
    assert stats.ljung_box_p([ar]) < 1e-6


def test_sign_flip_is_exact_for_few_blocks() -> None:
    assert stats.sign_flip_p(np.ones(10)) == pytest.approx(1 / 1024)
    assert stats.sign_flip_p(-np.ones(6)) == 1.0
    d = np.array([3.0, -1.0, 2.0, 0.5])
    # by enumeration: sums of +-|d| at least 4.5 (the observed sum)
    signs = np.array(np.meshgrid(*[[1, -1]] * 4)).reshape(4, -1).T
    assert stats.sign_flip_p(d) == pytest.approx(np.mean(signs @ np.abs(d) >= 4.5))


def test_correlation_uses_effective_sample_size() -> None:
    t = np.linspace(0, 1, 100)
    r, p = stats.correlation(np.sin(6 * t), np.sin(6 * t + 0.1))
    assert r > 0.99
    assert p < 0.01
    rng = np.random.default_rng(3)
    _, p_null = stats.correlation(rng.standard_normal(100), rng.standard_normal(100))
    assert p_null > 0.001


def test_blocks_are_contiguous_and_folds_interleave() -> None:
    b = crossval.block_ids([17, 11])
    assert np.all(np.diff(b) >= 0)  # contiguous, in order
    assert b[16] != b[17]  # a block never spans two runs
    f = crossval.fold_ids(b, np.array([0] * 17 + [1] * 11))
    assert set(np.unique(f)) <= set(range(crossval.FOLDS))
    with pytest.raises(Exception, match="two logs"):
        crossval.fold_ids(b[:17], np.zeros(17, dtype=int), "runs")


def _chamber_steps(minutes: float, levels: list[float], rate: float) -> np.ndarray:
    n = int(minutes * 600) + 1
    t = np.arange(n) * DT
    pts_t, pts_c = [0.0], [levels[0]]
    soak = minutes * 60 / len(levels) - abs(levels[1] - levels[0]) / rate * 60
    for a, b in zip(levels[:-1], levels[1:], strict=True):
        pts_t += [pts_t[-1] + soak, pts_t[-1] + soak + abs(b - a) / rate * 60]
        pts_c += [a, b]
    pts_t.append(t[-1])
    pts_c.append(levels[-1])
    return np.interp(t, pts_t, pts_c)


def _numpy_log(seed: int, sf_extra: np.ndarray | None = None, power_on: bool = False,
               tau_h: float = 90.0, tau_b: float = 240.0) -> tuple[ChamberLog, dict]:
    """A chamber log from small numpy functions: housing and board as first-order lags of
    the chamber air, two internal nodes lagging the housing, the SF a quadratic in them."""
    rng = np.random.default_rng(seed)
    chamber = _chamber_steps(100, [0.0, 35.0, 10.0], 1.5)
    t = np.arange(chamber.size) * DT
    step = np.ones_like(chamber)
    q_h, q_b = (1.0, 4.0) if power_on else (0.0, 0.0)
    housing = first_order_lag(chamber + q_h * step, tau_h, DT, chamber[0])
    board = first_order_lag(housing + q_b * step, tau_b, DT, housing[0])
    if not power_on:
        board = board + 4.0
    coil = first_order_lag(housing, 1300.0, DT, housing[0])
    src = first_order_lag(housing, 2800.0, DT, housing[0])
    sf = 3.0 * (coil - 20) + 0.06 * (coil - 20) ** 2 - 2.0 * (src - 20) + 0.05 * (src - 20) ** 2
    if sf_extra is not None:
        sf = sf + sf_extra
    table = np.full_like(t, 10.0)
    earth = np.full_like(t, earth_rate_vertical_dps(34.0))
    noise = rng.standard_normal(t.size) * (0.05 / 60 / np.sqrt(DT))
    gyro = (table + earth) * (1 + sf * 1e-6) + noise
    temp = np.round((board + rng.standard_normal(t.size) * 0.02) / 0.0625) * 0.0625
    log = ChamberLog(t, temp, table, gyro, earth, {"chamber_c": np.round(chamber, 3)})
    return log, {"housing": housing, "board": board}


@pytest.mark.parametrize("power_on", [False, True])
def test_driver_finds_the_two_lags(power_on: bool) -> None:
    log, truth = _numpy_log(4, power_on=power_on)
    d = driver.identify(log.time_s, log.temp_c, log.extra["chamber_c"])
    assert d.power_on == power_on
    assert d.rms_c < 0.05  # the board thermometer is reproduced to its own noise
    # the chain chamber -> housing -> board is symmetric in its two time constants (which
    # is the housing's is only weakly told by the self-heating path after a power-on)
    assert {d.tau_housing_s, d.tau_board_s} == {90.0, 240.0}
    if power_on:
        assert d.self_heat_housing_c + d.self_heat_board_c == pytest.approx(5.0, abs=0.3)
    else:  # then the housing estimate follows the true housing closely
        err = d.temp_c - truth["housing"]
        assert np.sqrt(np.mean(err**2)) < 0.05


def test_base_model_fits_numpy_physics_to_the_noise() -> None:
    log, _ = _numpy_log(5)
    d = verdict.diagnose([log])
    assert d.base_rms < 1.15 * d.noise_floor_ppm
    assert d.cause is None and not d.unexplained
    (tau1, tau2), _ = d.base.combo
    assert 600 <= tau1 < tau2 <= 4000


@pytest.mark.slow
def test_warmup_found_in_numpy_data_with_its_time_constant() -> None:
    n = 100 * 600 + 1
    t = np.arange(n) * DT
    # a log that starts warm (no self-heating rise): no start-up transient is looked for
    warm, _ = _numpy_log(6, sf_extra=150.0 * np.exp(-t / 150.0))
    w = next(c for c in verdict.diagnose([warm]).candidates if c.name == "warmup")
    assert not w.identifiable and "--start power-on" in w.evidence
    # a transient after a power-on is found (the base's own self-heating terms, at its
    # nodes' 600 s and more, take part of a fast one: 300 ppm, 200 s)
    amp, tau = 300.0, 200.0
    log, _ = _numpy_log(6, sf_extra=amp * np.exp(-t / tau), power_on=True)
    d = verdict.diagnose([log])
    assert d.cause == "warmup", [c.evidence for c in d.candidates]
    c = next(c for c in d.candidates if c.name == "warmup")
    # a transient over a few 60 s windows pins its time constant only loosely
    lo, hi = c.params["tau_s_ci95"]
    assert lo <= tau <= hi
    assert c.params["tau_s"] == pytest.approx(tau, rel=0.7)
    slo, shi = c.params["strength_ppm_ci95"]
    assert slo - 20 <= amp <= shi + 20
    assert c.gain_pct > 20


def test_out_of_catalogue_numpy_term_is_unexplained() -> None:
    n = 100 * 600 + 1
    t = np.arange(n) * DT
    log, _ = _numpy_log(7, sf_extra=60.0 * np.sin(2 * np.pi * t / 1100.0))
    d = verdict.diagnose([log])
    assert d.unexplained
    assert d.cause is None


def test_housing_coupling_of_a_dtdt_term() -> None:
    """A coil layer lagging the housing by tau has dT/dt = (housing - T) / tau: the term
    S * dT_coil/dt (C/min) holds the housing with S * 60 * mean(1/tau); a coil node behind
    another internal node holds it with nothing (case_build.housing_coupling, the bench's
    truth, and catalogue.housing_coupling, the diagnosis's, agree on a two-layer coil)."""
    from fogsf.diagnose.cases import build as case_build
    from fogsf.diagnose.effects import catalogue
    from fogsf.sim.config import NodeConfig, SimConfig

    rng = np.random.default_rng(20261123)
    s, tau = float(rng.uniform(10.0, 3000.0)), round(float(rng.uniform(150.0, 1500.0)), 1)
    assert catalogue.housing_coupling(s, (tau, 1.0)) == pytest.approx(s * 60.0 / tau)
    cfg = SimConfig()
    cfg.thermal.nodes = [NodeConfig("housing", "chamber", 60.0, 0.0),
                         NodeConfig("board", "housing", 300.0, 0.0),
                         NodeConfig("coil_inner", "housing", tau, 0.0),
                         NodeConfig("coil_outer", "housing", 2.0 * tau, 0.0)]
    assert case_build.housing_coupling(cfg, s) == pytest.approx(
        catalogue.housing_coupling(s, (tau, 2.0)), rel=1e-3), f"S={s}, tau={tau}"
    cfg.thermal.nodes[3] = NodeConfig("coil_outer", "coil_inner", 2.0 * tau, 0.0)
    assert case_build.housing_coupling(cfg, s) == pytest.approx(s * 60.0 / tau / 2.0)
    cfg.thermal.nodes[2] = NodeConfig("coil_inner", "board", tau, 0.0)
    assert case_build.housing_coupling(cfg, s) == 0.0
