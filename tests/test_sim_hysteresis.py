"""SF hysteresis in the simulator: the play operator, the effect, the population's draw and
the partial-cycle programs."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.sim import simulate
from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.effects import parse_effect, play_operator, preisach_offset
from fogsf.sim.partial_cycles import PARTIAL_TEST, PARTIAL_TRAIN
from fogsf.sim.population import (
    HYST_PPM_PER_C,
    HYST_WIDTH_C,
    gyro_for_seed,
    hysteresis_for_seed,
    run_on_gyro,
)
from fogsf.sim.scenarios import scenario


def test_play_follows_with_backlash_and_holds() -> None:
    x = np.array([0.0, 1.0, 3.0, 5.0, 5.0, 4.0, 2.0, 0.0, 0.0])
    p = play_operator(x, 4.0)
    # starts at x, sticks until x leaves p by 2, then trails by 2; turns back: sticks again
    assert p.tolist() == [0.0, 0.0, 1.0, 3.0, 3.0, 3.0, 3.0, 2.0, 2.0]
    assert np.all(np.abs(p - x) <= 2.0 + 1e-12)
    assert np.array_equal(play_operator(x, 0.0), x)


def test_play_is_rate_independent() -> None:
    """The same path in temperature at two speeds gives the same output at each point."""
    path = np.concatenate([np.linspace(0, 10, 11), np.linspace(10, 4, 7)[1:]])
    slow = np.repeat(path, 5)
    assert np.array_equal(play_operator(slow, 3.0)[4::5], play_operator(path, 3.0))


def test_preisach_sum_of_plays() -> None:
    x = np.sin(np.linspace(0, 12, 500)) * 10
    one = preisach_offset(x, 6.0, 1)
    assert np.allclose(one, play_operator(x, 6.0) - x)
    three = preisach_offset(x, 6.0, 3)
    want = sum(play_operator(x, w) - x for w in (2.0, 4.0, 6.0)) / 3
    assert np.allclose(three, want)


def test_effect_is_off_by_default_and_holds_through_a_soak() -> None:
    assert SimConfig().effects == []
    cfg = scenario("partial")
    base = simulate(cfg)
    cfg.effects = [parse_effect("hysteresis=6,width_c=8")]
    res = simulate(cfg)
    term = res.sf_ppm - base.sf_ppm
    assert np.abs(term).max() <= 6 * 4 + 1e-9
    assert np.abs(term).max() > 6 * 4 * 0.9  # the turns are wide enough to saturate it
    # at the end of a soak after a turn the term is still far from zero (a lag would relax)
    pts = np.asarray(PARTIAL_TRAIN.points())
    end_of_soak = int(round(pts[5, 0] / cfg.dt_s)) - 1
    assert abs(term[end_of_soak]) > 6 * 4 * 0.5


@pytest.mark.parametrize("bad", ["hysteresis=5,width_c=-1", "hysteresis=5,plays=0",
                                 "hysteresis=5,plays=1.5", "hysteresis=5,tau_s=3"])
def test_bad_parameters_refused(bad: str) -> None:
    with pytest.raises(UserError):
        parse_effect(bad)


def test_population_draws_hysteresis_from_its_own_stream() -> None:
    seeds = range(1, 401)
    drawn = {s: hysteresis_for_seed(s) for s in seeds}
    share = np.mean([h is not None for h in drawn.values()])
    assert 0.22 < share < 0.38  # HYST_SHARE 0.3, 400 gyros
    for s, h in drawn.items():
        with_h, without = gyro_for_seed(s), gyro_for_seed(s, hysteresis=False)
        assert with_h.thermal == without.thermal and with_h.sf == without.sf
        assert with_h.bias == without.bias and with_h.noise == without.noise
        if h is None:
            assert with_h == without
            continue
        assert with_h.effects == [h] and with_h.scenario.endswith(":hyst")
        assert HYST_WIDTH_C[0] <= h.params["width_c"] <= HYST_WIDTH_C[1]
        assert HYST_PPM_PER_C[0] <= h.strength <= HYST_PPM_PER_C[1]
    assert hysteresis_for_seed(0) is None and gyro_for_seed(0).effects == []


def test_runs_on_a_gyro_carry_its_hysteresis() -> None:
    seed = next(s for s in range(1, 100) if hysteresis_for_seed(s) is not None)
    gyro = gyro_for_seed(seed)
    run = run_on_gyro(gyro, PARTIAL_TEST.profile(), 3, "partial_test")
    assert [e.name for e in run.effects] == ["hysteresis"]
    flat = run_on_gyro(gyro_for_seed(seed, hysteresis=False), PARTIAL_TEST.profile(), 3, "x")
    assert flat.effects == []


def test_partial_programs_differ_and_span_the_range() -> None:
    for prog in (PARTIAL_TRAIN, PARTIAL_TEST):
        pts = np.asarray(prog.points())
        assert pts[:, 1].min() == -40.0 and pts[:, 1].max() >= 45.0
        inner = [t for t in prog.turns_c[1:-1]]
        assert all(-40.0 < t < 50.0 for t in inner[:2])  # turns inside the range
        ProfileConfig(kind="program", points=prog.points())
    assert set(PARTIAL_TRAIN.turns_c[1:-1]).isdisjoint(PARTIAL_TEST.turns_c[1:-1])
    assert set(PARTIAL_TRAIN.rates_c_per_min).isdisjoint(PARTIAL_TEST.rates_c_per_min)
