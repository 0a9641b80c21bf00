"""The simulator's open-loop FOG (the `open_loop` effect) and its plateau tables (`fogsf
simulate --plateaus`, `fogsf.sim.rigs.plateau_tables`): issue 48, item 3, the simulator's
side."""

from __future__ import annotations

import hashlib
import math
import tomllib

import numpy as np
import pytest

from fogsf.cli.main import build_parser, main
from fogsf.errors import UserError
from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.effects import EffectContext, effect_terms, parse_effect
from fogsf.sim.gyro import simulate
from fogsf.sim.population import gyro_for_seed, with_gyro
from fogsf.sim.rigs import plateau_tables as pt
from fogsf.sim.scale_factor import bias_dps, sf_error_ppm


def _quiet(cfg: SimConfig) -> SimConfig:
    cfg.noise.arw_deg_per_sqrt_h = cfg.noise.pulse_arcsec = 0.0
    cfg.noise.temp_noise_c = cfg.noise.temp_lsb_c = 0.0
    return cfg


def _soak(temp_c: float, seconds: float = 60.0) -> SimConfig:
    cfg = _quiet(SimConfig(seed=1))
    cfg.profile = ProfileConfig(kind="soak", start_c=temp_c, duration_s=seconds)
    return cfg


def _rates(n: int) -> np.ndarray:
    """0.01, 150 and -150 deg/s in turn, a third of the samples each."""
    return np.repeat([0.01, 150.0, -150.0], n // 3 + 1)[:n]


def _rate_response(cfg: SimConfig, effect: str | None
                   ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(rates, the output less the bias over the rate, the node temperatures) for a run
    with `effect` (or none), without the earth rate."""
    n = int(round(cfg.profile.duration_s / cfg.dt_s)) + 1
    cfg.effects = [parse_effect(effect)] if effect else []
    r = simulate(cfg, table_dps=_rates(n), earth_dps=0.0)
    return r.log.table_rate_dps, (r.ideal_dps - r.bias_dps) / r.log.table_rate_dps, r.nodes


def test_open_loop_keeps_the_small_rate_sf_and_falls_short_by_the_sine_at_full_scale() -> None:
    cfg = _soak(20.0)
    rate, closed, _ = _rate_response(cfg, None)
    _, opened, _ = _rate_response(cfg, "open_loop=0.2,tc_ppm_per_c=0")
    small, full = np.abs(rate) < 1.0, np.abs(rate) == 150.0
    # at 0.01 deg/s the sine is its argument to 1e-10: the closed-loop SF, thermal law included
    np.testing.assert_allclose(opened[small], closed[small], rtol=1e-10)
    x = 0.2 * math.pi / 2  # full scale reaches 0.2 of pi/2
    np.testing.assert_allclose(opened[full] / closed[full], math.sin(x) / x, rtol=1e-12)
    assert 0.015 < 1.0 - math.sin(x) / x < 0.017  # 1.6 % short at full scale


def test_open_loop_sees_the_earth_rate_and_writes_the_whole_sf_as_truth() -> None:
    cfg = _soak(30.0)
    cfg.effects = [parse_effect("open_loop=0.5,full_scale_dps=100")]
    n = int(round(cfg.profile.duration_s / cfg.dt_s)) + 1
    r = simulate(cfg, table_dps=_rates(n), earth_dps=0.4)
    w = r.log.table_rate_dps + 0.4
    # the truth column holds the sine too: the output is (table + earth)(1 + SF) + bias
    np.testing.assert_allclose(r.ideal_dps, w * (1.0 + r.sf_ppm * 1e-6) + r.bias_dps,
                               rtol=1e-14, atol=1e-15)
    k = 0.5 * math.pi / 2 / 100.0 * (1.0 - 400e-6 * (r.nodes["source"] - 20.0))
    law = sf_error_ppm(r.nodes, cfg.sf)
    np.testing.assert_allclose(1.0 + r.sf_ppm * 1e-6,
                               (1.0 + law * 1e-6) * np.sin(k * w) / (k * w), rtol=1e-13)


@pytest.mark.parametrize("tc", [-400.0, 300.0])
def test_the_phase_scale_moves_with_the_source_temperature(tc: float) -> None:
    effect = f"open_loop=0.3,tc_ppm_per_c={tc:g}"
    deficits = {}
    for temp in (0.0, 60.0):
        cfg = _soak(temp)
        rate, closed, _ = _rate_response(cfg, None)
        _, opened, nodes = _rate_response(cfg, effect)
        full = rate == 150.0
        source = nodes["source"][full]
        k = 0.3 * math.pi / 2 / 150.0 * (1.0 + tc * 1e-6 * (source - 20.0))
        np.testing.assert_allclose(opened[full] / closed[full], np.sin(150 * k) / (150 * k),
                                   rtol=1e-12)
        deficits[temp] = float(np.mean(1.0 - opened[full] / closed[full]))
    # the deficit goes as K^2: 60 C of a negative coefficient shrinks it, a positive grows it
    ratio = deficits[60.0] / deficits[0.0]
    assert ratio == pytest.approx((1 + tc * 1e-6 * 40) ** 2 / (1 - tc * 1e-6 * 20) ** 2,
                                  rel=2e-3)
    assert (ratio < 1.0) == (tc < 0)


@pytest.mark.parametrize("text", ["open_loop=0", "open_loop=1", "open_loop=1.5",
                                  "open_loop=0.2,full_scale_dps=0", "open_loop=0.2,node=3",
                                  "open_loop=0.2,tc_ppm_per_c=20000"])
def test_open_loop_refuses_what_no_gyro_runs_at(text: str) -> None:
    with pytest.raises(UserError):
        parse_effect(text)


def test_runs_without_open_loop_keep_their_numbers() -> None:
    """The SF sums as before the gain existed: the law's plus each effect's, bit for bit."""
    cfg = gyro_for_seed(17)
    cfg.seed, cfg.profile = 5, ProfileConfig(kind="ramp", start_c=10.0, stop_c=20.0)
    cfg.table.kind, cfg.table.rates_dps, cfg.table.dwell_s = "levels", [10.0, -100.0], 30.0
    cfg.effects += [parse_effect("rate_nonlinearity=50"), parse_effect("asymmetry=30")]
    r = simulate(cfg)
    sf = sf_error_ppm(r.nodes, cfg.sf)
    ctx = EffectContext(r.log.time_s, cfg.dt_s, r.log.table_rate_dps, r.nodes)
    fx = np.zeros_like(sf)
    for e in cfg.effects:
        fx += effect_terms(ctx, e).sf_ppm
    old = ((r.log.table_rate_dps + r.log.earth_rate_dps) * (1.0 + (sf + fx) * 1e-6)
           + bias_dps(r.nodes, cfg.bias, cfg.dt_s))
    assert np.array_equal(r.ideal_dps, old)


# sha256 of gyro_for_seed(seed).to_json() (and with thermal_bias), first 16 hex digits, as
# the population drew them before the open-loop FOG existed: a seed gives the same gyro
POPULATION = {0: ("ce0f08340bf14f3c", "ca7481db2fc7d8f8"),
              1: ("103ab90b4d5e7a48", "25ed9b7e21bcbf5d"),
              17: ("554e52cfa9ef636d", "60d37c899a026e54"),
              4242: ("c0608bd1c762aae7", "3e6c74ce38f3a60c"),
              20000: ("2cc958d09bf94612", "31c80ba10d903581"),
              20017: ("b2d0cccc385646f4", "ec4d2c95066d2e08")}


@pytest.mark.parametrize("seed", sorted(POPULATION))
def test_the_population_draws_the_same_gyros(seed: int) -> None:
    def digest(cfg: SimConfig) -> str:
        return hashlib.sha256(cfg.to_json().encode()).hexdigest()[:16]

    assert (digest(gyro_for_seed(seed)),
            digest(gyro_for_seed(seed, thermal_bias=True))) == POPULATION[seed]
    assert all(e.name != "open_loop" for e in gyro_for_seed(seed).effects)


def test_open_loop_gyros_of_the_population_only_when_asked() -> None:
    for seed in (0, 17, 20017):
        plain, opened = gyro_for_seed(seed), gyro_for_seed(seed, open_loop=True)
        # the same gyro and its other effects; the sine from a stream of its own
        assert opened.effects[:-1] == plain.effects and opened.sf == plain.sf
        assert opened.thermal == plain.thermal and opened.noise == plain.noise
        e = opened.effects[-1]
        assert e.name == "open_loop" and 0.1 <= e.strength <= 0.4
        assert -600 <= e.params["tc_ppm_per_c"] <= -200
        assert e == gyro_for_seed(seed, thermal_bias=True, open_loop=True).effects[-1]
    # with_gyro carries it onto a run, as it carries the gyro's hysteresis
    cfg = with_gyro(SimConfig(), gyro_for_seed(20017, open_loop=True))
    assert cfg.effects[-1].name == "open_loop"


def _gyro(seed: int = 17, effect: str | None = "open_loop=0.2") -> SimConfig:
    cfg = gyro_for_seed(seed)
    cfg.seed = seed
    cfg.effects += [parse_effect(effect)] if effect else []
    return cfg


def test_the_table_is_the_staircase_at_every_set_point_one_row_a_plateau() -> None:
    plan = pt.PlateauPlan(set_points_c=(36.0, 50.0), rate_steps=3, plateau_s=16.0, passes=2,
                          soak_s=300.0)
    run = pt.run_plateaus(_gyro(), plan)
    table = pt.plateau_table(run)
    c = table.columns
    one = [0.0, 50.0, 100.0, 150.0, 0.0, -50.0, -100.0, -150.0]
    assert list(c["table_rate_dps"]) == one * 4
    assert np.all(c["duration_s"] == 16.0)
    # rows at one set point follow each other; the table stands still between set points
    gaps = np.diff(c["time_s"]) - c["duration_s"][:-1]
    assert np.count_nonzero(np.abs(gaps) > 1e-9) == 1 and gaps.max() > 300.0
    t = run.result.log.time_s
    assert np.array_equal(c["time_s"], t[run.start])
    cold, hot = c["temp_c"][:16], c["temp_c"][16:]
    assert 36.0 < cold.min() and cold.max() < 50.0 < hot.min()  # the board over the box air
    # the table has reached the command where the mean starts
    for a, b, rate in zip(run.mean_from, run.stop, c["table_rate_dps"], strict=True):
        assert np.all(run.table_dps[a:b] == rate)


def test_rows_are_the_means_of_the_simulated_samples() -> None:
    run = pt.run_plateaus(_gyro())
    table = pt.plateau_table(run)
    log = run.result.log
    assert len(table) == 4 * 2 * 12 and np.all(run.mean_from - run.start == 20)
    for i, (a, b) in enumerate(zip(run.mean_from, run.stop, strict=True)):
        assert table.columns["gyro_dps"][i] == np.mean(log.gyro_dps[a:b])
        assert table.columns["temp_c"][i] == np.mean(log.temp_c[a:b])
        assert table.columns["table_rate_dps"][i] == run.command_dps[a]
    # the noise averages down as on a rig: the mean's error is the ARW over 16 s
    err = table.columns["gyro_dps"] - table.truth["ideal_dps"]
    sigma = run.result.config.noise.arw_deg_per_sqrt_h / 60.0 / math.sqrt(16.0)
    assert 0.7 < float(np.std(err)) / sigma < 1.4


def test_an_open_loop_table_falls_short_at_full_scale() -> None:
    run = pt.run_plateaus(_gyro())
    table = pt.plateau_table(run)
    c, earth, truth = table.columns, table.earth_rate_dps, table.truth
    rate, sf = c["table_rate_dps"], 1.0 + truth["true_sf_ppm"] * 1e-6
    x = 0.2 * math.pi / 2
    # against the SF at 30 deg/s of the same staircase, 150 is short by about the sine's
    # (the phase scale's -400 ppm/C moves the 1.6 % by up to 3 % of it over 36-57 C)
    small = (c["gyro_dps"][np.abs(rate) == 30.0] - earth) / np.abs(rate[np.abs(rate) == 30])
    full = (c["gyro_dps"][np.abs(rate) == 150.0] - earth) / 150.0
    assert np.all(np.abs(full / small - math.sin(x) / x / (math.sin(x / 5) / (x / 5)))
                  < 1e-3)
    # each row is the truth's mean output to the angle random walk over 16 s
    sigma = run.result.config.noise.arw_deg_per_sqrt_h / 60.0 / math.sqrt(16.0)
    ideal = (rate + earth) * sf + truth["true_bias_dph"] / 3600.0
    assert np.all(np.abs(c["gyro_dps"] - ideal) < 5 * sigma)


def test_same_seed_same_bytes_and_the_map_beside_the_table(tmp_path) -> None:
    args = ["simulate", "--plateaus", "--random-gyro", "20017", "--effect", "open_loop=0.25",
            "--levels-c", "36,57", "--soak-min", "5", "--passes", "1", "--rate-steps", "3",
            "--max-rate", "120", "--plateau-s", "20"]
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        assert main([*args, "--seed", seed, "--out", str(tmp_path / name / "t.csv")]) == 0
    a, b, c = ((tmp_path / n / "t.csv").read_bytes() for n in "abc")
    assert a == b != c
    toml = (tmp_path / "a" / "fogsf-columns.toml").read_bytes()
    assert toml == (tmp_path / "b" / "fogsf-columns.toml").read_bytes()
    m = tomllib.loads(toml.decode())
    assert m["layout"] == "plateaus" and m["time_is"] == "start"
    assert m["earth_rate_dps"] == pytest.approx(0.00235, 1e-3)
    data = np.genfromtxt(tmp_path / "a" / "t.csv", delimiter=",", names=True)
    assert data.dtype.names == pt.COLUMNS and data.shape == (2 * 8,)
    assert list(data["table_rate_dps"][:8]) == [0, 40, 80, 120, 0, -40, -80, -120]
    assert np.all(data["duration_s"] == 20.0)
    # the file holds the computed means to its printed digits
    cfg = gyro_for_seed(20017)
    cfg.seed, cfg.effects = 3, [*cfg.effects, parse_effect("open_loop=0.25")]
    plan = pt.PlateauPlan(set_points_c=(36.0, 57.0), soak_s=300.0, passes=1, rate_steps=3,
                          max_rate_dps=120.0, plateau_s=20.0)
    table = pt.plateau_table(pt.run_plateaus(cfg, plan))
    np.testing.assert_allclose(data["gyro_dps"], table.columns["gyro_dps"], rtol=1e-11,
                               atol=1e-14)


@pytest.mark.parametrize("extra, says", [
    (["--profile", "soak"], "--profile does not apply"),
    (["--table", "alternating"], "--table does not apply"),
    (["--summary"], "--summary does not apply"),
    ([], "needs --out"),
    (["--plateau-s", "1.5", "--out", "x.csv"], "must exceed settle_s"),
    (["--rate-steps", "0", "--out", "x.csv"], "rate_steps must lie in 1..100"),
])
def test_cli_refusals(extra: list[str], says: str, capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--plateaus", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0] and not list(tmp_path.iterdir())


def test_plateau_options_need_plateaus_and_help_ends_with_a_runnable_example(
        capsys, tmp_path) -> None:
    assert main(["simulate", "--max-rate", "100", "--out", str(tmp_path / "x.csv")]) == 2
    assert "need --plateaus" in capsys.readouterr().err
    text = build_parser({"simulate"})._subparsers._group_actions[0].choices[  # type: ignore
        "simulate"].format_help()
    last = text.strip().splitlines()[-1].split()
    assert last[:3] == ["fogsf", "simulate", "--plateaus"] and "--out" in last
