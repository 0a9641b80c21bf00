"""The gyro population: ranges, structural variety, determinism, magnitudes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.measure.metrics import log_metrics
from fogsf.sim import SimConfig, simulate
from fogsf.sim import population as pop
from fogsf.sim.config import SF_FACTORS, validate
from fogsf.sim.scenarios import paper
from fogsf.sim.thermal import effective_tau_s

DRAWS = [pop.gyro_for_seed(s) for s in range(1, 81)]


def test_seed_zero_is_the_default_gyro() -> None:
    g = pop.gyro_for_seed(0)
    d = SimConfig()
    assert (g.thermal, g.sf, g.bias, g.noise) == (d.thermal, d.sf, d.bias, d.noise)


def test_same_seed_same_gyro_and_seeds_differ() -> None:
    a = pop.gyro_for_seed(123).to_json()
    assert a == pop.gyro_for_seed(123).to_json()
    assert a != pop.gyro_for_seed(124).to_json()
    rng1, rng2 = np.random.default_rng(5), np.random.default_rng(5)
    assert pop.sample_gyro(rng1) == pop.sample_gyro(rng2)


@pytest.mark.parametrize("g", DRAWS[:20], ids=lambda g: g.scenario)
def test_every_draw_is_a_valid_configuration(g: SimConfig) -> None:
    validate(g)
    assert SimConfig.from_json(g.to_json()) == g


def test_ranges_hold_over_draws() -> None:
    for g in DRAWS:
        nodes = {n.name: n for n in g.thermal.nodes}
        internal = [n for n in g.thermal.nodes if n.name not in ("housing", "board")]
        assert pop.N_INTERNAL[0] <= len(internal) <= pop.N_INTERNAL[1]
        assert pop.HOUSING_TAU_S[0] <= nodes["housing"].tau_s <= pop.HOUSING_TAU_S[1]
        assert pop.BOARD_TAU_S[0] <= nodes["board"].tau_s <= pop.BOARD_TAU_S[1]
        for n in internal:
            assert pop.INTERNAL_TAU_S[0] / 2 <= n.tau_s <= pop.INTERNAL_TAU_S[1] + 0.1
            assert pop.INTERNAL_SELF_HEAT_C[0] <= n.self_heat_c <= pop.INTERNAL_SELF_HEAT_C[1]
        assert {t.factor for t in g.sf.terms} == set(SF_FACTORS)
        swing = sum(pop._swing(t.lin_ppm_per_c, t.quad_ppm_per_c2, t.cube_ppm_per_c3)
                    for t in g.sf.terms)
        assert pop.SWING_PPM[0] * 0.99 <= swing <= pop.SWING_PPM[1] * 1.01
        lo, hi = pop.ARW_DEG_PER_SQRT_H
        assert lo <= g.noise.arw_deg_per_sqrt_h <= hi


def test_structural_variety() -> None:
    topologies = {g.scenario.split(":")[1] for g in DRAWS}
    assert topologies == set(pop.TOPOLOGIES)
    cancel = sum(g.scenario.endswith(":cancel") for g in DRAWS) / len(DRAWS)
    assert 0.15 <= cancel <= 0.45
    terms = [t for g in DRAWS for t in g.sf.terms]
    assert any(t.cube_ppm_per_c3 != 0 for t in terms)
    assert any(t.quad_ppm_per_c2 != 0 and t.cube_ppm_per_c3 == 0 for t in terms)
    assert any(t.quad_ppm_per_c2 == 0 for t in terms)
    assert any(t.lin_ppm_per_c > 0 for t in terms) and any(t.lin_ppm_per_c < 0 for t in terms)
    slowest = [max(effective_tau_s(g.thermal, n.name) for n in g.thermal.nodes) for g in DRAWS]
    assert min(slowest) < 1500 < 3000 < max(slowest)


def test_cancelling_gyros_oppose_the_source() -> None:
    for g in DRAWS:
        if not g.scenario.endswith(":cancel"):
            continue
        slope = {t.factor: SF_FACTORS[t.factor] * t.lin_ppm_per_c for t in g.sf.terms}
        others = sum(v for f, v in slope.items() if f != "lambda")
        assert slope["lambda"] * others < 0
        assert abs(slope["lambda"]) <= abs(others) * pop.CANCEL_RATIO[1] * 1.001


def test_magnitudes_are_the_papers_hundreds_of_ppm() -> None:
    rms = [log_metrics(simulate(pop.with_gyro(paper(1.0, seed=s), g)).log)["rms_ppm"]
           for s, g in enumerate(DRAWS[:24])]
    assert 100.0 < float(np.median(rms)) < 800.0
    assert min(rms) > 2.0


def test_with_gyro_keeps_the_run() -> None:
    run = paper(0.5, seed=9)
    run.thermal.start = "power-on"
    out = pop.with_gyro(run, DRAWS[0])
    assert out.profile == run.profile and out.seed == 9
    assert out.thermal.start == "power-on"
    assert out.thermal.nodes == DRAWS[0].thermal.nodes


def test_simulate_random_gyro_cli(tmp_path, capsys) -> None:  # noqa: ANN001
    cfg_path = tmp_path / "g.json"
    assert main(["simulate", "--random-gyro", "31", "--write-config", str(cfg_path)]) == 0
    d = json.loads(cfg_path.read_text())
    assert d["seed"] == 31
    assert d["thermal"] == json.loads(pop.gyro_for_seed(31).to_json())["thermal"]
    assert main(["simulate", "--random-gyro", "-1", "--summary"]) == 2
    assert "--random-gyro" in capsys.readouterr().err


def test_the_thermal_bias_is_drawn_from_its_own_stream_within_its_ranges() -> None:
    """`thermal_bias` adds a Shupe term, a quadratic and a cubic on the coil and changes
    nothing else: the thermal network, SF law, noise, bias offset and slope are the gyro's
    (its other draws do not move), and the default stays without them."""
    from fogsf.sim import population as pop

    rng = np.random.default_rng(2022)
    for seed in [0, *(int(s) for s in rng.integers(1, 10_000, 6))]:
        plain, drawn = pop.gyro_for_seed(seed), pop.gyro_for_seed(seed, thermal_bias=True)
        assert plain.bias.shupe_dph_per_c_per_min == 0.0 and plain.bias.cube_dph_per_c3 == 0.0
        assert drawn.thermal == plain.thermal and drawn.sf == plain.sf, seed
        assert drawn.noise == plain.noise, seed
        assert (drawn.bias.bias_dph, drawn.bias.lin_dph_per_c) == (plain.bias.bias_dph,
                                                                  plain.bias.lin_dph_per_c)
        lo, hi = pop.SHUPE_DPH_PER_C_PER_MIN
        assert lo * 0.99 <= abs(drawn.bias.shupe_dph_per_c_per_min) <= hi * 1.01, seed
        assert pop.BIAS_QUAD_DPH_PER_C2[0] <= drawn.bias.quad_dph_per_c2 \
            <= pop.BIAS_QUAD_DPH_PER_C2[1]
        assert pop.BIAS_CUBE_DPH_PER_C3[0] <= drawn.bias.cube_dph_per_c3 \
            <= pop.BIAS_CUBE_DPH_PER_C3[1]
        assert drawn.bias.node.startswith("coil"), seed
        assert pop.gyro_for_seed(seed, thermal_bias=True).bias == drawn.bias  # deterministic


@pytest.mark.parametrize("form", pop.OUTSIDE_FORMS)
def test_outside_forms_change_only_what_they_state(form: str) -> None:
    """A form outside the population's is drawn within its range and changes nothing else
    of the gyro: one node (the thermometer's new one, or the vented part with the parts
    behind it still behind it), never the SF law, bias, noise or effects; the same seed
    gives the same form."""
    lo, hi = pop.SENSOR_TAU_S if form == "sensor" else pop.VENT_TAU_S
    for seed in (1, 7, 123, 20005):
        plain = pop.gyro_for_seed(seed)
        g = pop.outside_form(plain, seed, form)
        validate(g)
        assert g == pop.outside_form(pop.gyro_for_seed(seed), seed, form)
        assert plain == pop.gyro_for_seed(seed)  # the gyro it was given is left alone
        assert (g.sf, g.bias, g.noise, g.effects) == (plain.sf, plain.bias, plain.noise,
                                                      plain.effects)
        assert g.scenario == plain.scenario + f":{form}"
        before = {n.name: n for n in plain.thermal.nodes}
        changed = [n for n in g.thermal.nodes if before.get(n.name) != n]
        assert len(changed) == 1, seed
        n = changed[0]
        assert lo <= n.tau_s <= hi, seed
        if form == "sensor":
            assert n.name == g.thermal.board_node == "sensor"
            assert n.parent == plain.thermal.board_node and n.self_heat_c == 0.0
        else:
            assert g.thermal.board_node == plain.thermal.board_node
            assert n.parent == "chamber" and before[n.name].parent != "chamber"
            assert n.name in pop.sf_parts(plain)  # a part an SF factor reads
            assert any(n.name in t.nodes for t in g.sf.terms)
    with pytest.raises(ValueError, match="outside form"):
        pop.outside_form(pop.gyro_for_seed(1), 1, "draft")


def test_the_thermometer_behind_the_board_reads_it_late() -> None:
    """On a steady ramp a first-order lag reads tau x rate behind its input: the "sensor"
    form's thermometer trails the board's true temperature by that much."""
    from fogsf.sim.config import ProfileConfig

    g = pop.outside_form(pop.gyro_for_seed(7), 7, "sensor")
    tau = g.thermal.nodes[-1].tau_s
    prof = ProfileConfig(kind="ramp", start_c=-10.0, stop_c=40.0, rate_c_per_min=2.0)
    r = simulate(pop.run_on_gyro(g, prof, 3, "sensor-ramp"))
    t = r.log.time_s
    mid = (t > t[0] + 900.0) & (t < t[0] + 1400.0)  # the board ramps steadily here
    board = np.asarray(r.nodes["board"])[mid]
    slope = np.polyfit(t[mid], board, 1)[0]  # C/s
    lag_c = float(np.mean(board - np.asarray(r.log.temp_c)[mid]))
    assert lag_c == pytest.approx(tau * slope, rel=0.1)
    assert lag_c > 0.9  # the form is visible: tau >= 30 s at ~2 C/min
