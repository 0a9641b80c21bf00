"""`fogsf fleet add` on a rig's plateau tables: the unit's plateau model trained as `fogsf
train` trains it and recorded with the tables' static figures; `list` and `report` show it,
`check` and the design's prior leave it out and say why. A refused add or add-many creates
no fleet."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record, fleet_urls

FAST = ["--structure", "physics", "--iters", "2", "--hysteresis", "off", "--no-progress"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two plateau tables of one open-loop gyro (a sine rate response) and a sample log."""
    d = tmp_path_factory.mktemp("tables")
    out = {}
    for name, seed in (("train", "1"), ("test", "2")):
        out[name] = d / name / "table.csv"
        assert main(["simulate", "--plateaus", "--random-gyro", "17", "--effect",
                     "open_loop=0.2", "--seed", seed, "--out", str(out[name])]) == 0
    out["sample"] = d / "r2.csv"
    assert main(["simulate", "--scenario", "paper", "--ramp-rate", "2", "--seed", "1",
                 "--start-c", "-20", "--stop-c", "40", "--sample-rate-hz", "1",
                 "--out", str(out["sample"])]) == 0
    return out


def _fleet_there(fleet: str) -> bool:
    """Whether anything of a fleet is at `fleet`: the file, or the schema in the database."""
    if not fleet.startswith("postgres"):
        return Path(fleet).exists()
    import psycopg

    with psycopg.connect(fleet, autocommit=True) as db:
        return db.execute("SELECT to_regclass('schema_version')").fetchone()[0] is not None


@pytest.mark.parametrize("make_fleet", fleet_urls())
def test_a_refused_add_creates_no_fleet(make_fleet, logs: dict[str, Path], tmp_path: Path,
                                        capsys) -> None:
    fleet = make_fleet(tmp_path)
    junk = tmp_path / "junk.csv"
    junk.write_text("a,b\n1,2\n")
    refusals = {
        "an unreadable log": ["--train", str(junk), *FAST],
        "a missing log": ["--train", str(tmp_path / "missing.csv"), *FAST],
        "a table and a sample log": ["--train", str(logs["train"]), "--test",
                                     str(logs["sample"])],
        "a sample log's option on a table": ["--train", str(logs["train"]), "--structure",
                                             "physics"],
    }
    for what, argv in refusals.items():
        assert main(["fleet", "add", fleet, "--unit", "SN1", *argv]) == 2, what
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, (what, err)
        assert not _fleet_there(fleet), f"{what}: refused, and left a fleet behind"
    manifest = tmp_path / "units.csv"
    manifest.write_text(f"unit,train\nSN1,{logs['sample']}\n")
    for what, argv in {"no workers": ["--workers", "0"],
                       "a sample log's option for a manifest": ["--train-options",
                                                                 "--unit SN2"]}.items():
        assert main(["fleet", "add-many", fleet, str(manifest), *argv]) == 2, what
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, (what, err)
        assert not _fleet_there(fleet), f"add-many, {what}: refused, and left a fleet behind"
    assert main(["fleet", "list", fleet]) == 2  # still nothing there
    assert "no such fleet" in capsys.readouterr().err or fleet.startswith("postgres")


def test_a_plateau_unit_is_recorded_listed_and_reported(logs: dict[str, Path],
                                                        tmp_path: Path, capsys) -> None:
    fleet = str(tmp_path / "line.fleet")
    assert main(["fleet", "add", fleet, "--unit", "P1", "--train", str(logs["train"]),
                 "--test", str(logs["test"]), "--out", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    assert "plateau model:" in out and "recorded unit P1" in out and "structure plateau" in out
    assert (tmp_path / "m" / "metrics.json").is_file()
    with open_store(fleet, "read") as store:
        rec = store.unit("P1")
    assert [lg.role for lg in rec.logs] == ["train", "test"] and rec.logs[0].rows == 96
    s, f = rec.summary, rec.figures
    assert s["structure"] == "plateau" and rec.fitted_with["model"] == "plateau"
    # the open-loop gyro's sine: a nonlinearity of thousands of ppm of full scale, which
    # the model removes (its RMS on the held-out table a small part of the raw error's)
    assert abs(s["sf_nonlinearity_ppm_fs"]) > 1000.0, s
    for k in ("sf_drift_ppm_per_c", "sf_asymmetry_ppm", "bias_dph", "bias_drift_dph_per_c"):
        assert isinstance(s[k], float) and math.isfinite(s[k]), (k, s)
    assert f["test_after_rms_dph"] < 0.01 * f["test_before_rms_dph"], f
    assert len(f["sf_curve"]["temp_c"]) == 4 and max(map(abs, f["sf_curve"]["after_ppm"])) < 50
    assert main(["fleet", "list", fleet]) == 0
    listed = capsys.readouterr().out
    assert "plateau units (rate table):" in listed and "\nP1 " in listed, listed
    assert main(["fleet", "report", fleet, "--out", str(tmp_path / "report")]) == 0
    assert "wrote" in capsys.readouterr().out
    page = (tmp_path / "report" / "units" / "unit-000.html").read_text()
    assert "P1" in page and "sf_nonlinearity_ppm_fs" in page and "<svg" in page


def test_check_and_the_prior_leave_plateau_units_out(logs: dict[str, Path], tmp_path: Path,
                                                     capsys) -> None:
    fleet = str(tmp_path / "line.fleet")
    with open_store(fleet) as store:
        for i in range(5):
            store.add(fake_record(f"SN{i}", seed=i))
    assert main(["fleet", "add", fleet, "--unit", "P1", "--train", str(logs["train"])]) == 0
    capsys.readouterr()
    out_json = tmp_path / "check.json"
    assert main(["fleet", "check", fleet, "--json", str(out_json)]) == 0
    said = capsys.readouterr().out
    assert "1 plateau unit(s) left out ('P1')" in said and "6 units, 5 compared;" in said, said
    result = json.loads(out_json.read_text())
    assert "P1" not in {o["unit"] for o in result["outliers"]}, result  # not "unlike the line"
    assert result["units"] == 6 and result["compared"] == 5
    assert result["structure"] == "physics2"
    assert main(["train", "--prior", fleet, "--train", str(logs["sample"]), "--out",
                 str(tmp_path / "m"), "--iters", "2", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "1 plateau unit(s) left out" in err and "SF responses over time" in err, err
    assert err.strip().splitlines()[-1].startswith("fogsf train: error:"), err
