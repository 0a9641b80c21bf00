"""fogsf fleet check: a defective unit among units of one design is flagged, a line of
normal units gives no flag, at the stated false-alarm rate.

The simulated fleet: a development design (`fogsf.sim.fleet_units`, design seeds 1-9999;
its units vary the time constants by +/-15 % and the SF law's coefficients by +/-25 %);
one unit is defective: its strongest part's SF slope 3-5 x off, either sign, the slowest
part an SF factor reads 2.5-4 x slower, or a mode hop (an SF step of 150-400 ppm, either
sign, above a source temperature of 5-25 C; tests/fleet_units.py). The design, the
defect, its strength and the seeds are drawn with a seeded generator; the seed is printed
on failure."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.fleet.check import check_fleet, null_threshold
from fogsf.fleet.store import open_store
from tests.fleet_units import draw_defect, fake_record, fit_unit, unit_config, unit_log

SEED = int(os.environ.get("FOGSF_TEST_SEED", "20261127"))
N_NORMAL = 7


def _line(rng: np.random.Generator, n: int, features: int, shift: float = 0.0
          ) -> list:
    """n made-up units of one structure whose features are Gaussian (the last shifted by
    `shift` standard deviations in its first feature)."""
    units = []
    for i in range(n):
        rec = fake_record(f"SN{i:03d}", seed=i)
        x = rng.standard_normal(features) * 3.0 + 100.0
        if i == n - 1:
            x[0] += 3.0 * shift
        rec.figures["response_ppm"] = {f"p{k}": float(v) for k, v in enumerate(x)}
        rec.figures.pop("train_rms_over_floor")
        units.append(rec)
    return units


def test_false_alarm_rate_holds_on_normal_lines_and_a_far_unit_is_found() -> None:
    rng = np.random.default_rng(SEED)
    alpha, lines = 0.05, 300
    alarms = sum(bool(check_fleet(_line(rng, int(rng.integers(6, 14)), 8), alpha).outliers)
                 for _ in range(lines))
    # at most alpha by construction (Bonferroni over 8 independent features: about alpha)
    assert alarms <= alpha * lines + 3 * np.sqrt(alpha * lines), f"seed {SEED}: {alarms}"
    found = [check_fleet(_line(rng, 10, 8, shift=15.0), alpha).flagged for _ in range(40)]
    assert all("SN009" in f for f in found), f"seed {SEED}: {found}"
    extra = sum(len(f) > 1 for f in found)  # the normal units beside it keep the rate
    assert extra <= alpha * 40 + 3 * np.sqrt(alpha * 40), f"seed {SEED}: {found}"


def test_structure_unlike_the_line_is_flagged() -> None:
    units = [fake_record(f"SN{i:03d}", seed=i) for i in range(6)]
    units.append(fake_record("SN-odd", seed=9, structure="bank+play"))
    result = check_fleet(units)
    assert [(o.unit, o.kind) for o in result.outliers] == [("SN-odd", "structure")]
    assert "bank+play" in result.outliers[0].why and "physics2" in result.outliers[0].why
    assert "nothing checked" in check_fleet(units[:3]).note


def test_units_fitted_under_the_prior_neither_set_nor_break_the_lines_structure() -> None:
    """`train --prior` units carry the prior's structure, not one their logs chose: they
    are not flagged for it, nor do they outvote the line's own units (named in the note)."""
    units = [fake_record(f"SN{i:03d}", seed=i, structure="bank") for i in range(4)]
    for i in range(5):  # more prior units than the line's own
        u = fake_record(f"NEW{i}", seed=20 + i)  # physics2
        u.fitted_with["options"]["prior"] = {"fleet_units": ["SN000"], "used": True}
        units.append(u)
    result = check_fleet(units)
    assert result.structure == "bank", result
    assert not [o for o in result.outliers if o.kind == "structure"], result.outliers
    assert "5 unit(s) fitted under the design's prior" in result.note and "NEW0" in result.note
    units[-1].fitted_with["options"]["prior"]["used"] = False  # fitted alone: its logs chose
    flagged = [o.unit for o in check_fleet(units).outliers if o.kind == "structure"]
    assert flagged == ["NEW4"], flagged


def test_threshold_grows_with_the_features_and_shrinks_with_the_units() -> None:
    assert null_threshold(8, 20, 0.01) > null_threshold(8, 2, 0.01)
    assert null_threshold(20, 8, 0.01) < null_threshold(6, 8, 0.01)


@pytest.fixture(scope="module")
def simulated_fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[list, dict, int]:
    rng = np.random.default_rng(SEED)
    from fogsf.sim.population import DEV_SEEDS

    design = int(rng.integers(DEV_SEEDS.start + 1, DEV_SEEDS.stop))
    first = int(rng.integers(0, 1000))  # the line's first unit index
    tmp = tmp_path_factory.mktemp("units")
    units = []
    for i in range(N_NORMAL + 1):
        cfg = unit_config(design, first + i)
        defect = None
        if i == N_NORMAL:
            defect, cfg = draw_defect(rng, cfg)
        log = unit_log(cfg, int(rng.integers(0, 2**31)), defect)
        units.append(fit_unit(f"SN{i:03d}", [log], tmp / f"u{i}", nodes=1))
    return units, defect or {}, design


@pytest.mark.slow
def test_a_defective_unit_is_flagged_and_normal_units_are_not(simulated_fleet) -> None:
    units, defect, gyro = simulated_fleet
    say = f"seed {SEED}, design gyro {gyro}, defect {defect}"
    normal = check_fleet(units[:N_NORMAL])
    assert not normal.outliers, f"{say}: a line of normal units flagged: {normal.message()}"
    result = check_fleet(units)
    assert result.flagged == {f"SN{N_NORMAL:03d}"}, f"{say}: {result.message()}"


def test_fleet_check_cli_reads_the_database_and_writes_json(simulated_fleet, tmp_path: Path,
                                                            capsys) -> None:
    units, defect, gyro = simulated_fleet
    fleet = str(tmp_path / "line.fleet")
    with open_store(fleet) as store:
        for u in units:
            store.add(u)
    out = tmp_path / "outliers.json"
    assert main(["fleet", "check", fleet, "--json", str(out)]) == 0
    text = capsys.readouterr().out
    bad = f"SN{N_NORMAL:03d}"
    assert f"  {bad}: " in text, f"seed {SEED}, gyro {gyro}, defect {defect}: {text}"
    got = json.loads(out.read_text())
    assert [o["unit"] for o in got["outliers"]] == [bad]
    assert got["outliers"][0]["why"]
