"""A catalogue form that cannot apply is skipped and named, never an error for the whole run;
a bias on the coil under a reversing table without chamber air (a log pair) is named
`bias_drift` again.

Cases from `fogsf.diagnose.cases.planted` on development gyros of the population, drawn with a
seeded generator (gyro, profile, table, strength, simulator seed; ranges in
`diagnose.cases.kinds` and `diagnose.cases.planted`). A failure prints the case and its seed:
`cases.draw_population(kind, name, variant, seed)` rebuilds it.
"""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.diagnose import extend, report, verdict
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import judge as case_judge
from fogsf.diagnose.cases import planted as cases
from fogsf.diagnose.effects import catalogue
from fogsf.errors import UserError

MASTER_SEED = 20261127


def _gyros(tag: int, n: int) -> list[int]:
    rng = np.random.default_rng([MASTER_SEED, tag])
    return [int(s) for s in rng.integers(1, 10_000, n)]


@pytest.fixture(scope="module")
def shupe() -> tuple[cases.Case, verdict.Diagnosis]:
    """A Shupe bias (a coil form) diagnosed with bias_shupe as the only candidate: the
    extended model then holds a coil cause."""
    case = cases.draw_population("effect", "bias_shupe", "coil", _gyros(1, 1)[0])
    logs, _ = case_build.build(case)
    return case, verdict.diagnose(logs, effects=["bias_shupe"])


def test_a_coil_cause_brings_its_coil_to_the_extended_model(shupe) -> None:
    case, d = shupe
    assert d.causes == ["bias_shupe"], f"[{case.describe()}] causes {d.causes}"
    cfgs, sim = extend.extended(d)  # the simulator's coil effects need coil nodes
    nodes = [n["name"] for n in cfgs[0]["thermal"]["nodes"]]
    assert any(n.startswith("coil") for n in nodes), nodes
    assert [e["name"] for e in cfgs[0]["effects"]][-1] == "bias_shupe"
    assert d.skipped == []
    assert sim is not None and sim["rms_extended_sim_ppm"] < sim["rms_base_sim_ppm"]


def test_a_coil_cause_without_coil_nodes_is_skipped_in_the_simulation(
        shupe, monkeypatch: pytest.MonkeyPatch) -> None:
    case, d = shupe
    d.skipped = []
    monkeypatch.setattr(extend, "_coil_taus", lambda c, g: ())  # a fit with no coil
    cfgs, sim = extend.extended(d)
    assert "bias_shupe" not in [e["name"] for e in cfgs[0]["effects"]]
    assert sim is not None  # the run goes on
    assert d.skipped == [{"effect": "bias_shupe", "stage": "simulation of the extended model",
                          "reason": "needs coil nodes (names starting with 'coil'), the "
                                    "fitted base has none"}]
    text = report.summary_text(report.to_json(d, cfgs[0], sim))
    assert "skipped: bias_shupe in the simulation of the extended model: needs coil nodes" \
        in text
    d.skipped = []


def test_a_form_that_cannot_apply_is_skipped_not_an_error(
        monkeypatch: pytest.MonkeyPatch) -> None:
    case = cases.draw_population("null", "", "", _gyros(2, 1)[0])
    logs, _ = case_build.build(case)
    form = catalogue.CATALOGUE["aging"]

    def column(ctx, b, g):  # type: ignore[no-untyped-def]
        raise UserError("needs coil nodes (names starting with 'coil'), the fitted base "
                        "has none")

    monkeypatch.setitem(catalogue.CATALOGUE, "aging",
                        catalogue.Candidate(form.name, form.coef_name, form.grid_name,
                                            form.grid, column, form.meaning))
    d = verdict.diagnose(logs)
    j = report.to_json(d, {}, None)
    c = next(c for c in j["candidates"] if c["effect"] == "aging")
    assert c["evidence"].startswith("skipped: needs coil nodes") and not c["significant"]
    assert j["skipped"] == [{"effect": "aging", "stage": "scoring",
                             "reason": "needs coil nodes (names starting with 'coil'), the "
                                       "fitted base has none"}]
    assert "skipped: aging in the scoring: needs coil nodes" in report.summary_text(j)


@pytest.mark.slow
@pytest.mark.parametrize("seed", _gyros(3, 2))
def test_a_coil_bias_on_a_reversing_table_without_chamber_air_is_bias_drift(seed: int) -> None:
    """The held-out case's kind: one log pair, a reversing table, a bias on the coil, no
    chamber air. Named bias_drift (its slope within 30 %), nothing else, and the extended
    model simulates."""
    case = cases.draw_population("effect", "bias_drift", "coil_pair", seed)
    logs, truth = case_build.build(case)
    assert len(logs) == 2 and all("chamber_c" not in log.extra for log in logs)
    d = verdict.diagnose(logs)
    cfgs, sim = extend.extended(d)
    out = case_judge.judge_report(case, truth, report.to_json(d, cfgs[0], sim))
    assert out.ok, f"[{case.describe()}] -> {out.reason}"
