"""Simulator core: configuration round-trip, determinism, thermal network, SF physics, noise."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.logs.logio import read_log
from fogsf.logs.writer import write_log
from fogsf.sim import SimConfig, simulate
from fogsf.sim.config import (
    EffectConfig,
    NodeConfig,
    ProfileConfig,
    ScaleFactorConfig,
    SFTermConfig,
    ThermalConfig,
)
from fogsf.sim.gyro import arw_noise, quantize_pulses
from fogsf.sim.lag import first_order_lag
from fogsf.sim.scale_factor import sf_error_ppm
from fogsf.sim.thermal import effective_tau_s, equilibrium, network


def short_cfg(seed: int = 3, minutes: float = 20.0) -> SimConfig:
    cfg = SimConfig(seed=seed)
    cfg.profile = ProfileConfig(kind="ramp", start_c=10.0, stop_c=10.0 + minutes * 1.0,
                                rate_c_per_min=1.0)
    return cfg


def test_config_round_trips_through_json() -> None:
    cfg = short_cfg()
    cfg.effects = [EffectConfig("temp_rate", 25.0), EffectConfig("extra_lag", 1800.0,
                                                                 {"sens_ppm_per_c": 3.0})]
    cfg.profile.levels_c = [1.0, 2.0]
    back = SimConfig.from_json(cfg.to_json())
    assert back == cfg
    assert back.to_json() == cfg.to_json()


def test_config_refuses_unknown_keys_and_bad_values() -> None:
    d = SimConfig().to_dict()
    d["profile"]["rate_c_per_minute"] = 1.0
    with pytest.raises(UserError, match="rate_c_per_minute"):
        SimConfig.from_dict(d)
    d = SimConfig().to_dict()
    d["thermal"]["nodes"][1]["parent"] = "nowhere"
    with pytest.raises(UserError, match="parent"):
        SimConfig.from_dict(d)
    d = SimConfig().to_dict()
    d["effects"] = [{"name": "no_such_effect", "strength": 1.0}]
    with pytest.raises(UserError, match="unknown effect"):
        SimConfig.from_dict(d)
    with pytest.raises(UserError, match="JSON"):
        SimConfig.from_json("{not json")
    d = SimConfig().to_dict()
    d["profile"]["rate_c_per_min"] = "fast"
    with pytest.raises(UserError, match="profile.rate_c_per_min"):
        SimConfig.from_dict(d)
    d = SimConfig().to_dict()
    d["profile"]["cycles"] = 1.5
    with pytest.raises(UserError, match="whole number"):
        SimConfig.from_dict(d)
    d = SimConfig().to_dict()
    d["thermal"]["nodes"][0]["tau_s"] = 90  # JSON integers are fine where floats are asked
    assert SimConfig.from_dict(d) == SimConfig()


def test_same_seed_same_bytes_other_seed_other_bytes(tmp_path) -> None:
    paths = []
    for i, seed in enumerate((5, 5, 6)):
        cfg = short_cfg(seed)
        cfg.effects = [EffectConfig("aging", 10.0)]
        p = tmp_path / f"run{i}.csv"
        write_log(p, simulate(cfg).log)
        paths.append(p.read_bytes())
    assert paths[0] == paths[1]
    assert paths[0] != paths[2]


def test_written_log_passes_the_reader(tmp_path) -> None:
    res = simulate(short_cfg())
    p = tmp_path / "run.csv"
    write_log(p, res.log)
    log = read_log(p)
    assert len(log) == len(res.log)
    for name in ("chamber_c", "temp_preamp_c", "temp_coil_inner_c", "temp_coil_outer_c",
                 "temp_source_c", "temp_housing_c", "true_sf_ppm"):
        assert name in log.extra
    assert log.earth_rate_dps is not None
    np.testing.assert_allclose(log.extra["true_sf_ppm"], res.sf_ppm, rtol=1e-9, atol=1e-9)


def test_first_order_lag_matches_the_recursion_and_a_ramp() -> None:
    rng = np.random.default_rng(0)
    u = 20.0 + np.cumsum(rng.normal(size=3000)) * 0.1
    for tau in (0.05, 1.0, 40.0, 3000.0):
        a = math.exp(-0.1 / tau)
        g = (1 - a) / (0.1 / tau)
        y = np.empty_like(u)
        y[0] = -3.0
        for k in range(len(u) - 1):
            y[k + 1] = a * y[k] + (g - a) * u[k] + (1 - g) * u[k + 1]
        np.testing.assert_allclose(first_order_lag(u, tau, 0.1, -3.0), y, atol=1e-9)
    # A steady ramp is followed with a delay of exactly tau (first-order hold is exact).
    t = np.arange(0, 20000.0, 0.1)
    y = first_order_lag(t / 60.0, 300.0, 0.1, 0.0)
    assert abs((t[-1] / 60.0 - y[-1]) * 60.0 - 300.0) < 1e-6


def test_default_nodes_are_ordered_as_the_paper_fig3() -> None:
    th = ThermalConfig()
    order = ["board", "preamp", "coil_inner", "coil_outer", "source"]
    eff = [effective_tau_s(th, n) for n in order]
    assert eff == sorted(eff) and len(set(eff)) == len(eff)
    assert 3 * 60 <= eff[0] <= 8 * 60  # board ~3-8 min
    assert 15 * 60 <= effective_tau_s(th, "coil_inner") <= 40 * 60
    assert 15 * 60 <= effective_tau_s(th, "coil_outer") <= 40 * 60
    assert 30 * 60 <= eff[-1] <= 60 * 60  # source ~30-60 min


def test_lag_seen_on_a_ramp_follows_the_node_order() -> None:
    th = ThermalConfig()
    for n in th.nodes:
        n.self_heat_c = 0.0
    rate = 0.25  # C/min, long enough for every transient to die out
    t = np.arange(0, 400 * 60.0, 0.1)
    chamber = -40.0 + rate * t / 60.0
    temps = network(chamber, th, 0.1)
    lags = {}
    for n in th.nodes:
        lag = chamber[-1] - temps[n.name][-1]
        assert lag == pytest.approx(rate * effective_tau_s(th, n.name) / 60.0, rel=0.01)
        lags[n.name] = lag
    order = ["board", "preamp", "coil_inner", "coil_outer", "source"]
    assert [lags[n] for n in order] == sorted(lags[n] for n in order)


def test_warm_start_is_at_equilibrium_and_power_on_warms_up() -> None:
    th = ThermalConfig(start="warm")
    chamber = np.full(36000, 20.0)  # one hour soak
    warm = network(chamber, th, 0.1)
    eq = equilibrium(th.nodes, 20.0)
    for n in th.nodes:
        assert np.max(np.abs(warm[n.name] - eq[n.name])) < 1e-9
    cold = network(chamber, ThermalConfig(start="power-on"), 0.1)
    for n in th.nodes:
        assert cold[n.name][0] == pytest.approx(20.0)
        assert np.all(np.diff(cold[n.name]) >= -1e-12)  # self-heating only rises
    assert cold["board"][-1] == pytest.approx(eq["board"], abs=0.05)  # settled in an hour
    i15 = 15 * 600
    rise = (cold["source"][i15] - 20.0) / (eq["source"] - 20.0)
    assert 0.1 < rise < 0.5  # the source is still warming after 15 min


def test_power_on_run_shows_the_warm_up_on_the_board_thermometer() -> None:
    cfg = SimConfig(seed=1)
    cfg.profile = ProfileConfig(kind="soak", start_c=20.0, duration_s=3600.0)
    cfg.thermal.start = "power-on"
    log = simulate(cfg).log
    assert log.temp_c[:10].mean() == pytest.approx(20.0, abs=0.15)
    assert log.temp_c[-600:].mean() == pytest.approx(26.0, abs=0.15)  # housing 1 + board 5


def test_sf_follows_the_sign_of_each_factor_in_K() -> None:
    nodes = {"a": np.array([20.0, 30.0])}
    for factor, sign in (("L", 1), ("D", 1), ("Km", -1), ("K_DA", -1), ("lambda", -1)):
        cfg = ScaleFactorConfig([SFTermConfig("x", factor, {"a": 1.0}, 10.0, 0.5)])
        sf = sf_error_ppm(nodes, cfg)
        assert sf[0] == pytest.approx(0.0)
        change = (10.0 * 10 + 0.5 * 100) * 1e-6
        expect = ((1 + change) ** sign - 1) * 1e6
        assert sf[1] == pytest.approx(expect, rel=1e-12)


def test_arw_and_quantization() -> None:
    rng = np.random.default_rng(2)
    n = 1000 * 400
    noise = arw_noise(rng, n, 0.05, 0.1)
    # Mean over 100 s windows: ARW / sqrt(T) = 0.05 deg/sqrt(h) / sqrt(100 s) in deg/s.
    win = noise.reshape(-1, 1000).mean(axis=1)
    expect = 0.05 / 60.0 / math.sqrt(100.0)
    assert np.std(win) == pytest.approx(expect, rel=0.1)
    rate = 10.0 + noise
    q = quantize_pulses(rate, 1.0, 0.1)
    lsb = 1.0 / 3600.0 / 0.1
    assert np.allclose(q / lsb, np.round(q / lsb))  # whole pulses per sample
    # The remainder is carried: the total angle is lost by less than one pulse.
    assert abs(np.sum(q - rate) * 0.1) < 1.0 / 3600.0


def test_noise_floor_of_a_window_is_near_8_ppm_at_10_dps() -> None:
    from fogsf.logs.measure.metrics import noise_floor_ppm
    from fogsf.logs.measure.windows import sf_windows

    cfg = SimConfig(seed=4)
    cfg.profile = ProfileConfig(kind="soak", start_c=20.0, duration_s=3 * 3600.0)
    res = simulate(cfg)
    noise = (res.log.gyro_dps - res.ideal_dps)[:108000].reshape(-1, 1000)  # 100 s windows
    true_ppm = np.std(noise.mean(axis=1)) / 10.0 * 1e6
    assert true_ppm == pytest.approx(8.33, rel=0.2)
    assert noise_floor_ppm(sf_windows(res.log)) == pytest.approx(true_ppm, rel=0.2)


def test_bias_leaks_into_the_apparent_sf_as_bias_over_rate() -> None:
    from fogsf.logs.measure.windows import sf_windows

    cfg = SimConfig(seed=0)
    cfg.profile = ProfileConfig(kind="soak", start_c=20.0, duration_s=1000.0)
    cfg.noise.arw_deg_per_sqrt_h = 0.0
    cfg.sf = ScaleFactorConfig(terms=[])
    cfg.bias.bias_dph = 36.0  # 0.01 deg/s
    cfg.bias.lin_dph_per_c = 0.0
    w = sf_windows(simulate(cfg).log)
    assert np.allclose((w.sf_ratio - 1) * 1e6, 0.01 / 10.0 * 1e6, atol=0.5)


def test_custom_network_topology_is_honoured() -> None:
    th = ThermalConfig(nodes=[NodeConfig("housing", "chamber", 60.0),
                              NodeConfig("board", "housing", 120.0, 2.0),
                              NodeConfig("deep", "board", 600.0)], start="warm")
    assert effective_tau_s(th, "deep") == 780.0
    cfg = short_cfg()
    cfg.thermal = copy.deepcopy(th)
    cfg.sf = ScaleFactorConfig([SFTermConfig("coil", "D", {"deep": 1.0}, 10.0)])
    cfg.bias.node = "board"
    res = simulate(cfg)
    assert "temp_deep_c" in res.log.extra
