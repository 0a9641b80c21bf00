"""`fogsf diagnose` on plateau tables (docs/diagnose.md, "Plateau tables"): a rate response
hidden in a population gyro's tables is named, its form told (an open-loop FOG's sine from a
closed-loop FOG's polynomial), an asymmetry hidden alone is named alone, and a gyro without
a rate term is left with none. The draws are test_plateau_train's (seeded, stated ranges)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_plateau_train import DRAWS, draw, rows_of_run

from fogsf.cli.main import main
from fogsf.diagnose.rate_terms import RateDiagnosis, diagnose_rate
from fogsf.sim import population as pop
from fogsf.sim.effects import EffectConfig
from fogsf.sim.rigs import plateau_tables as pt
from fogsf.training.rate.plateau_model import PlateauRows, choice_rows


def _diagnose(rows: PlateauRows) -> RateDiagnosis:
    fs = float(np.max(np.abs(rows.rate_dps)))
    return diagnose_rate(choice_rows(rows, fs, float(np.mean(rows.temp_c))), fs)


@pytest.mark.slow
@pytest.mark.parametrize("i", range(DRAWS))
def test_the_hidden_rate_response_is_named_with_its_form(i: int) -> None:
    h = draw(i)
    d = _diagnose(rows_of_run(h, h.run_seed))
    named = [t.term for t in d.named]
    want = "sine" if h.kind == "open-loop" else "polynomial"
    assert d.nonlinearity_form == want, f"{h}: named {named}, steps {d.steps}"
    assert d.model_dph * 2.0 < d.base_dph, f"{h}: no gain, {d.model_dph} vs {d.base_dph}"


@pytest.mark.slow
@pytest.mark.parametrize("i", range(DRAWS))
def test_two_runs_of_a_gyro_name_the_form_one_names(i: int) -> None:
    """Two runs of one gyro stacked: the form named is still the gyro's (the bias and SF's
    degree in T, chosen with the rate terms, does not answer the nonlinearity's residual)."""
    h = draw(i)
    a, b = rows_of_run(h, h.run_seed), rows_of_run(h, h.run_seed + 1)
    both = PlateauRows(*(np.concatenate([getattr(a, f), getattr(b, f)])
                         for f in ("gyro_dps", "rate_dps", "temp_c")))
    d = _diagnose(both)
    want = "sine" if h.kind == "open-loop" else "polynomial"
    assert d.nonlinearity_form == want, f"{h}: named {[t.term for t in d.named]}, {d.steps}"


@pytest.mark.slow
@pytest.mark.parametrize("i", range(2))
def test_an_asymmetry_alone_is_named_alone_and_no_term_is_named_without_one(i: int) -> None:
    h = draw(10 + i)
    strength = float(np.random.default_rng([0x48A, i]).uniform(*pop.CLOSED_LOOP_ASYM_PPM))
    asym = replace(h, effects=(EffectConfig("asymmetry", round(strength, 2)),))
    d = _diagnose(rows_of_run(asym, h.run_seed))
    assert [t.term for t in d.named] == ["asymmetry"], f"{asym}: {d.named}, {d.steps}"
    clean = replace(h, effects=())
    d = _diagnose(rows_of_run(clean, h.run_seed))
    assert not d.named, f"{clean}: named {d.named} in a gyro without rate terms"


@pytest.mark.slow
def test_the_command_prints_and_writes_what_it_named(tmp_path: Path, capsys) -> None:
    cfg = pop.gyro_for_seed(17)
    cfg.effects.append(EffectConfig("open_loop", 0.25))
    table = pt.plateau_table(pt.run_plateaus(cfg, pt.PlateauPlan()))
    path, _ = pt.write_plateau_table(tmp_path / "t.csv", table)
    out_json = tmp_path / "d.json"
    assert main(["diagnose", str(path), "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "named: rate nonlinearity: an open-loop FOG's sine (phase at full scale" in out
    j = json.loads(out_json.read_text())
    assert j["nonlinearity_form"] == "sine" and j["named"][0]["phase_rad"] == pytest.approx(
        0.25 * np.pi / 2, rel=0.05)
