"""Each effect changes the data the way its physics says.

Planted effects: strength, ramp rate and seed are drawn from the stated ranges with a seeded
generator (DRAW_SEEDS); every assertion message carries the draw seed. Each check compares a
run with the effect against the same run (same seed, so the same noise) without it, on the
apparent SF of 100 s windows computed from the gyro output (fogsf.logs.measure.windows.sf_windows).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fogsf.logs.measure.pairs import plateau_pairs, rate_steps
from fogsf.logs.measure.windows import sf_windows
from fogsf.sim import SimConfig, simulate
from fogsf.sim.config import ProfileConfig, TableConfig
from fogsf.sim.effects import EFFECTS, EffectConfig, describe, parse_effect

DRAW_SEEDS = (11, 12)


def base(seed: int, profile: ProfileConfig, table: TableConfig | None = None,
         start: str = "warm") -> SimConfig:
    cfg = SimConfig(seed=seed)
    cfg.profile = profile
    cfg.table = table or TableConfig(kind="constant", rate_dps=10.0)
    cfg.thermal.start = start
    return cfg


def with_effect(cfg: SimConfig, name: str, strength: float, **params: float) -> SimConfig:
    c = copy.deepcopy(cfg)
    c.effects = [EffectConfig(name, strength, dict(params))]
    return c


def window_shift_ppm(cfg: SimConfig, fx: SimConfig, remove_bias: bool = True):
    """(windows, apparent SF with the effect - without, in ppm) per window."""
    w0 = sf_windows(simulate(cfg).log, remove_bias=remove_bias)
    w1 = sf_windows(simulate(fx).log, remove_bias=remove_bias)
    return w1, (w1.sf_ratio - w0.sf_ratio) * 1e6


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_temp_rate_shift_is_proportional_to_dTdt_and_flips_sign(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(10.0, 60.0) * rng.choice([-1, 1]))  # ppm/(C/min)
    rate = float(rng.uniform(0.5, 1.5))  # C/min
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.2f}, rate {rate:.2f}, seed {seed}"
    shifts = []
    for a, b in ((-40.0, 60.0), (60.0, -40.0)):
        cfg = base(seed, ProfileConfig(kind="ramp", start_c=a, stop_c=b, rate_c_per_min=rate))
        w, d = window_shift_ppm(cfg, with_effect(cfg, "temp_rate", strength))
        late = w.t_s > 0.6 * w.t_s[-1]  # coil at the ramp's steady rate by then
        shifts.append(np.median(d[late]))
        assert np.median(d[late]) == pytest.approx(np.sign(b - a) * strength * rate,
                                                   rel=0.08), msg
    assert np.sign(shifts[0]) == -np.sign(shifts[1]), msg
    # At the warm start the coil has not started to move yet: almost no shift.
    assert abs(d[0]) < 0.3 * abs(strength * rate), msg


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_extra_lag_keeps_settling_after_the_ramp_stops(draw: int) -> None:
    rng = np.random.default_rng(draw)
    tau = float(rng.uniform(1800.0, 5400.0))  # s
    sens = float(rng.uniform(3.0, 8.0))
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: tau {tau:.0f} s, sens {sens:.2f}, seed {seed}"
    prof = ProfileConfig(kind="ramp", start_c=-20.0, stop_c=40.0, rate_c_per_min=1.0,
                         soak_after_s=3 * tau)
    cfg = base(seed, prof)
    w, d = window_shift_ppm(cfg, with_effect(cfg, "extra_lag", tau, sens_ppm_per_c=sens))
    t_stop = 60.0 * 60.0
    soak = w.t_s > t_stop
    d_stop = d[np.argmin(np.abs(w.t_s - t_stop))]
    assert d_stop < -20.0, msg  # colder extra node on the way up: negative term
    after = d[soak]
    # Still settling long after the board has (board ~5 min): decays with about tau.
    i_tau = np.argmin(np.abs(w.t_s - (t_stop + tau)))
    assert 0.2 < d[i_tau] / d_stop < 0.6, msg
    assert abs(after[-1]) < 0.15 * abs(d_stop), msg
    smooth = np.convolve(after, np.ones(5) / 5, mode="valid")
    assert np.all(np.diff(smooth) > -0.5), msg  # monotonic return towards zero


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_asymmetry_splits_plus_and_minus_sf_at_every_rate(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(50.0, 300.0) * rng.choice([-1, 1]))  # ppm
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.1f}, seed {seed}"
    table = TableConfig(kind="levels", rates_dps=[10.0, -10.0, 100.0, -100.0], dwell_s=200.0)
    cfg = base(seed, ProfileConfig(kind="soak", start_c=20.0, duration_s=3200.0), table)
    fx = with_effect(cfg, "asymmetry", strength)
    # the raw windows (the +/- pairs' bias left in) split SF+ from SF-
    w, d = window_shift_ppm(cfg, fx, remove_bias=False)
    for r in (10.0, 100.0):
        plus = np.mean(d[np.isclose(w.rate_dps, r)])
        minus = np.mean(d[np.isclose(w.rate_dps, -r)])
        assert plus - minus == pytest.approx(strength, rel=0.02, abs=1.0), msg
        assert plus == pytest.approx(strength / 2, rel=0.02, abs=1.0), msg
    # a pair's bias holds asymmetry x rate / 2: taken off at its own rate, both signs read
    # the mean SF (what one SF correction compensates) ...
    w, d = window_shift_ppm(cfg, fx)
    for r in (10.0, -10.0, 100.0, -100.0):
        assert np.mean(d[np.isclose(w.rate_dps, r)]) == pytest.approx(0.0, abs=1.0), msg
    # ... and the rate steps (IEEE 952) give the asymmetry back
    a0 = rate_steps(simulate(cfg).log).asymmetry_ppm
    a1 = rate_steps(simulate(fx).log).asymmetry_ppm
    assert a1 - a0 == pytest.approx(strength, rel=0.02, abs=1.0), msg


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_bias_drift_scales_with_one_over_rate_and_follows_temperature(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(0.02, 0.2) * rng.choice([-1, 1]))  # deg/h/C
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.3f} deg/h/C, seed {seed}"
    prof = ProfileConfig(kind="ramp", start_c=-20.0, stop_c=60.0, rate_c_per_min=2.0)
    slopes = {}
    for rate in (10.0, 50.0):
        cfg = base(seed, prof, TableConfig(kind="constant", rate_dps=rate))
        w, d = window_shift_ppm(cfg, with_effect(cfg, "bias_drift", strength))
        expect = strength * (w.temp_c - 20.0) / 3600.0 / rate * 1e6
        assert np.max(np.abs(d - expect)) < 0.05 * np.max(np.abs(expect)) + 0.5, msg
        slopes[rate] = np.polyfit(w.temp_c, d, 1)[0]
    assert slopes[10.0] / slopes[50.0] == pytest.approx(5.0, rel=0.05), msg
    # +/- pairs separate it out: the SF of pairs is untouched, the bias carries it.
    table = TableConfig(kind="alternating", rate_dps=10.0, dwell_s=100.0)
    cfg = base(seed, prof, table)
    p0 = plateau_pairs(simulate(cfg).log)
    p1 = plateau_pairs(simulate(with_effect(cfg, "bias_drift", strength)).log)
    # Only the bias change within a pair (the temperature moves 3.3 C per 100 s plateau)
    # is left in the pair's SF, against tens of ppm in the one-rate SF above.
    within_pair = abs(strength) * (2.0 / 60.0 * 100.0) / 3600.0 / (2 * 10.0) * 1e6
    assert np.max(np.abs(p1.sf_ratio - p0.sf_ratio)) * 1e6 < 1.1 * within_pair + 0.5, msg
    dbias = (p1.bias_dps - p0.bias_dps) * 3600.0
    np.testing.assert_allclose(dbias, strength * (p1.temp_c - 20.0),
                               atol=0.05 * abs(strength) * 40 + 1e-3, err_msg=msg)


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_rate_nonlinearity_sf_depends_on_rate_magnitude(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(50.0, 500.0) * rng.choice([-1, 1]))  # ppm at 100 deg/s
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.1f}, seed {seed}"
    rates = [10.0, 50.0, -100.0, 200.0]
    table = TableConfig(kind="levels", rates_dps=rates, dwell_s=200.0)
    cfg = base(seed, ProfileConfig(kind="soak", start_c=0.0, duration_s=3200.0), table)
    w, d = window_shift_ppm(cfg, with_effect(cfg, "rate_nonlinearity", strength))
    for r in rates:
        got = np.mean(d[np.isclose(w.rate_dps, r)])
        assert got == pytest.approx(strength * abs(r) / 100.0, rel=0.02, abs=1.0), msg
    # One constant rate: a constant offset, no temperature structure.
    cfg = base(seed, ProfileConfig(kind="ramp", start_c=-20.0, stop_c=40.0))
    w, d = window_shift_ppm(cfg, with_effect(cfg, "rate_nonlinearity", strength))
    assert np.ptp(d) < 1.0, msg


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_aging_drifts_with_elapsed_time_at_constant_temperature(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(5.0, 50.0) * rng.choice([-1, 1]))  # ppm/h
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.1f} ppm/h, seed {seed}"
    cfg = base(seed, ProfileConfig(kind="soak", start_c=25.0, duration_s=2 * 3600.0))
    w, d = window_shift_ppm(cfg, with_effect(cfg, "aging", strength))
    slope_per_h = np.polyfit(w.t_s / 3600.0, d, 1)[0]
    assert slope_per_h == pytest.approx(strength, rel=0.02), msg
    assert np.ptp(w.temp_c) < 0.2, msg  # the temperature did not move


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_warmup_is_a_transient_after_power_on(draw: int) -> None:
    rng = np.random.default_rng(draw)
    strength = float(rng.uniform(100.0, 500.0) * rng.choice([-1, 1]))  # ppm
    tau = float(rng.uniform(300.0, 900.0))
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.1f}, tau {tau:.0f}, seed {seed}"
    cfg = base(seed, ProfileConfig(kind="soak", start_c=20.0, duration_s=6 * tau),
               start="power-on")
    w, d = window_shift_ppm(cfg, with_effect(cfg, "warmup", strength, tau_s=tau))
    np.testing.assert_allclose(d, strength * np.exp(-w.t_s / tau),
                               atol=0.03 * abs(strength), err_msg=msg)
    assert abs(d[0]) > 0.8 * abs(strength) and abs(d[-1]) < 0.01 * abs(strength), msg


def test_every_effect_is_listed_with_unit_and_meaning() -> None:
    text = describe()
    required = {"warmup", "extra_lag", "temp_rate", "rate_nonlinearity", "asymmetry",
                "bias_drift", "aging"}
    assert required <= set(EFFECTS)
    for name, info in EFFECTS.items():
        assert name in text and info.unit in text and info.meaning
        import fogsf.sim.effects as mod
        assert f"{name}=" in (mod.__doc__ or "")


def test_parse_effect_and_its_refusals() -> None:
    e = parse_effect("extra_lag=3600,sens_ppm_per_c=5")
    assert (e.name, e.strength, e.params) == ("extra_lag", 3600.0, {"sens_ppm_per_c": 5.0})
    from fogsf.errors import UserError
    for bad in ("temp_rate", "nope=1", "temp_rate=abc", "extra_lag=-5", "aging=1,foo=2",
                "warmup=10,tau_s"):
        with pytest.raises(UserError):
            parse_effect(bad)


@pytest.mark.parametrize("draw", DRAW_SEEDS)
def test_bias_shupe_is_a_bias_in_the_coils_rate_that_flips_with_the_ramp(draw: int) -> None:
    """+/- pairs measure the Shupe bias: strength * dT_coil/dt (deg/h), the sign of the
    ramp's; the pairs' SF is untouched."""
    rng = np.random.default_rng([draw, 22])
    strength = float(rng.uniform(0.5, 5.0) * rng.choice([-1, 1]))  # deg/h per C/min
    rate = float(rng.uniform(0.5, 1.5))  # C/min
    seed = int(rng.integers(1000))
    msg = f"draw seed {draw}: strength {strength:.3f} deg/h/(C/min), rate {rate:.2f}, seed {seed}"
    table = TableConfig(kind="alternating", rate_dps=10.0, dwell_s=100.0)
    for a, b in ((-30.0, 50.0), (50.0, -30.0)):
        cfg = base(seed, ProfileConfig(kind="ramp", start_c=a, stop_c=b, rate_c_per_min=rate),
                   table)
        p0 = plateau_pairs(simulate(cfg).log)
        res = simulate(with_effect(cfg, "bias_shupe", strength))
        p1 = plateau_pairs(res.log)
        dbias = (p1.bias_dps - p0.bias_dps) * 3600.0
        coil = np.mean([v for k, v in res.nodes.items() if k.startswith("coil")], axis=0)
        truth = strength * np.gradient(coil, cfg.dt_s) * 60.0  # deg/h per sample
        t = res.log.time_s
        over_pair = [truth[(t >= c - 100.0) & (t < c + 100.0)].mean() for c in p1.t_s]
        # (the first and last pair straddle the ramp's bends, where the pair fit's linear
        # drift does not hold)
        np.testing.assert_allclose(dbias[1:-1], over_pair[1:-1],
                                   atol=0.02 * abs(strength) * rate + 1e-3, err_msg=msg)
        late = p1.t_s > 0.8 * p1.t_s[-1]  # near the ramp's steady rate: the ramp's sign
        assert np.all(np.sign(dbias[late]) == np.sign(b - a) * np.sign(strength)), msg
        assert np.max(np.abs(p1.sf_ratio - p0.sf_ratio)[1:-1]) * 1e6 < 1.0, msg
