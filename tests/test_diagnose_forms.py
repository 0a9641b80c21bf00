"""Diagnose on gyros it was not written for: every form variant of the catalogue effects, two
effects at once, a mixed-rate null and a power-on without chamber_c, each on a gyro of the
population (fogsf.sim.population, development seeds) with its chamber program, table and
strength drawn from the ranges stated in `cases.draw_population` (strength: 3-20x the noise
floor of the part the base cannot absorb). Judged by `case_judge.judge`. And bad input: refused
with one clear line."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fogsf.diagnose import driver, extend, report, verdict
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import judge as case_judge
from fogsf.diagnose.cases import planted as cases
from fogsf.diagnose.cases import programs as case_programs
from fogsf.errors import UserError
from fogsf.sim.gyro import simulate
from fogsf.sim.population import DEV_SEEDS

SEED = 300  # first development gyro of these tests (DEV_SEEDS)
# the coil bias on a log pair has its own test (test_diagnose_skip)
VARIANTS = [(e, v) for e, vs in cases.VARIANTS.items() for v in vs if v != "coil_pair"]


def _run(case: cases.Case) -> tuple[case_judge.Outcome, dict]:
    logs, truth = case_build.build(case)
    j = report.to_json(verdict.diagnose(logs), {}, None)
    out = case_judge.judge_report(case, truth, j)
    return out, j


@pytest.mark.slow
@pytest.mark.parametrize(("effect", "variant"), VARIANTS)
def test_form_variant_is_named(effect: str, variant: str) -> None:
    seed = SEED + VARIANTS.index((effect, variant))
    assert seed in DEV_SEEDS
    case = cases.draw_population("effect", effect, variant, seed)
    out, j = _run(case)
    assert out.ok, f"[{case.describe()}] -> {out.reason}"
    if out.ok and j["cause"]:
        assert j["causes"][0] == j["cause"]


@pytest.mark.slow
@pytest.mark.parametrize("pair", cases.PAIRS)
def test_two_effects_both_named(pair: tuple[str, str]) -> None:
    seed = SEED + 20 + cases.PAIRS.index(pair)
    case = cases.draw_population("two", pair[0], pair[1], seed)
    logs, truth = case_build.build(case)
    d = verdict.diagnose(logs)
    j = report.to_json(d, {}, None)
    out = case_judge.judge_report(case, truth, j)
    assert out.ok, f"[{case.describe()}] -> {out.reason}"
    assert j["cause"] == j["causes"][0]
    # the extended model carries every cause
    cfg = extend.sim_config(d, d.extended)
    assert {e["name"] for e in cfg["effects"]} >= set(pair)


@pytest.mark.slow
@pytest.mark.parametrize(("noise_seed", "chamber"), [(1000, False), (1001, True)])
def test_mixed_rate_null_stays_clean(noise_seed: int, chamber: bool) -> None:
    """The default gyro (population seed 0) with the table at +/- 10, 50, 100, 200 deg/s:
    window noise differs ~20x between the levels. (On population gyros with internal nodes
    faster than the base's 600 s, the high-rate windows resolve the base's misfit and a
    slow candidate can still take it: docs/diagnose.md gives the bench's rate.)"""
    case = cases.draw_population("null", "mixed", "", 0)
    case.config.seed = noise_seed
    case.chamber = chamber
    rates = np.abs(case.config.table.rates_dps)
    assert set(rates) == set(case_programs.MIXED_RATES_DPS)
    out, j = _run(case)
    assert j["cause"] is None and j["causes"] == []
    assert not j["unexplained"], j["structure"]


def test_power_on_from_the_board_alone() -> None:
    """A warm-up planted at power-on, the log without chamber_c: the start is found from the
    board thermometer's self-heating rise, the warm-up named."""
    case = cases.draw_population("effect", "warmup", "transient", SEED + 50)
    case.chamber = False
    logs, truth = case_build.build(case)
    assert "chamber_c" not in logs[0].extra
    rise = driver.board_power_on(logs[0].time_s, logs[0].temp_c)
    assert rise > driver.POWER_ON_MIN_C
    d = verdict.diagnose(logs)
    assert d.ctxs[0].power_on
    j = report.to_json(d, {}, None)
    out = case_judge.judge_report(case, truth, j)
    assert out.ok, f"[{case.describe()}] -> {out.reason}"


def test_warm_start_is_not_power_on() -> None:
    case = cases.draw_population("null", "", "", SEED + 51)
    case.config.thermal.start = "warm"
    log = simulate(case.config).log
    assert driver.board_power_on(log.time_s, log.temp_c) <= driver.POWER_ON_MIN_C


@pytest.fixture(scope="module")
def null_log() -> object:
    case = cases.draw_population("null", "", "", SEED + 60)
    case.chamber = True
    return case_build.build(case)[0][0]


def _one_line(e: pytest.ExceptionInfo) -> str:
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_refuses_a_log_of_one_window(null_log) -> None:
    short = null_log.slice(0, int(90.0 / 0.1))
    with pytest.raises(UserError) as e:
        verdict.diagnose([short])
    assert "window" in _one_line(e)


def test_refuses_nan_cells(null_log) -> None:
    bad = copy.copy(null_log)
    bad.gyro_dps = null_log.gyro_dps.copy()
    bad.gyro_dps[1234] = np.nan
    with pytest.raises(UserError) as e:
        verdict.diagnose([bad])
    assert "gyro_dps" in _one_line(e) and "NaN" in _one_line(e)


@pytest.mark.slow
def test_refuses_logs_of_different_gyros(null_log) -> None:
    other = cases.draw_population("null", "", "", SEED + 61)
    other.chamber = True
    other.config.profile = copy.deepcopy(cases.draw_population("null", "", "",
                                                               SEED + 60).config.profile)
    log2 = case_build.build(other)[0][0]
    with pytest.raises(UserError) as e:
        verdict.diagnose([null_log, log2])
    assert "one gyro" in _one_line(e)


def test_node_terms_need_the_chamber_air(null_log) -> None:
    """Without chamber_c a lag or dT/dt term is confounded with the base, and the text names
    the run that would separate them."""
    bare = copy.copy(null_log)
    bare.extra = {}
    j = report.to_json(verdict.diagnose([bare]), {}, None)
    for c in j["candidates"]:
        if c["effect"] in ("temp_rate", "extra_lag"):
            assert not c["identifiable"] and c["confounded_with"] == ["base"]
            assert "chamber_c" in c["separating_run"]
