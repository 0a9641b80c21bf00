"""fogsf fleet add / add-many / list / remove from the command line: a unit trained as
`fogsf train` trains it, recorded with its logs' hashes; refusals in one line."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from fogsf.cli.main import main

FAST = ["--structure", "physics", "--iters", "2", "--hysteresis", "off", "--no-progress"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("logs")
    out = {}
    for name, rate, seed in (("r2", "2", "1"), ("r1", "1", "2"), ("r2b", "2", "3")):
        out[name] = d / f"{name}.csv"
        assert main(["simulate", "--scenario", "paper", "--ramp-rate", rate, "--seed", seed,
                     "--start-c", "-20", "--stop-c", "40", "--sample-rate-hz", "1",
                     "--out", str(out[name])]) == 0
    return out


def test_add_list_remove(logs: dict[str, Path], tmp_path: Path, capsys) -> None:
    fleet = str(tmp_path / "line.fleet")
    model = tmp_path / "m1"
    assert main(["fleet", "add", fleet, "--unit", "SN1", "--train", str(logs["r2"]),
                 "--test", str(logs["r1"]), "--out", str(model), *FAST]) == 0
    out = capsys.readouterr().out
    assert "SF error, ppm" in out and "recorded unit SN1" in out  # train's report, then ours
    assert (model / "metrics.json").is_file()
    assert main(["fleet", "add", fleet, "--unit", "SN1", "--train", str(logs["r2"]),
                 *FAST]) == 2
    assert "already in" in capsys.readouterr().err
    assert main(["fleet", "list", fleet, "--json"]) == 0
    (rec,) = json.loads(capsys.readouterr().out)
    assert rec["unit"] == "SN1" and rec["model_dir"] == str(model.resolve())
    assert [lg["role"] for lg in rec["logs"]] == ["train", "test"]
    train = rec["logs"][0]
    assert train["sha256"] == hashlib.sha256(logs["r2"].read_bytes()).hexdigest()
    assert train["path"] == str(logs["r2"].resolve()) and train["rows"] == 1801
    assert rec["fitted_with"]["structure"] == "physics1" and rec["figures"]["response_ppm"]
    assert rec["summary"]["fits"]  # what the design's prior reads
    metrics = json.loads((model / "metrics.json").read_text())
    assert rec["model_id"] == metrics["model_id"]
    assert rec["figures"]["test_after_rms_ppm"] == pytest.approx(
        metrics["test"]["after"]["rms_ppm"])
    assert main(["fleet", "list", fleet]) == 0
    assert "SN1" in capsys.readouterr().out
    assert main(["fleet", "remove", fleet, "SN1"]) == 0
    assert main(["fleet", "remove", fleet, "SN1"]) == 2
    assert "no unit 'SN1'" in capsys.readouterr().err


@pytest.mark.slow
def test_add_many_from_a_manifest(logs: dict[str, Path], tmp_path: Path, capsys) -> None:
    for name, p in logs.items():  # relative paths: from the manifest's folder
        (tmp_path / f"{name}.csv").write_bytes(p.read_bytes())
    manifest = tmp_path / "units.csv"
    manifest.write_text("unit,train,test,out\n"
                        "SN-A,r2.csv;r2b.csv,r1.csv,models/a\n"
                        "SN-B,r2b.csv,,\n")
    fleet = str(tmp_path / "line.fleet")
    assert main(["fleet", "add-many", fleet, str(manifest), "--workers", "2",
                 "--train-options", " ".join(FAST)]) == 0
    out = capsys.readouterr().out
    assert "2 of 2 units recorded" in out
    assert main(["fleet", "list", fleet, "--json"]) == 0
    recs = {r["unit"]: r for r in json.loads(capsys.readouterr().out)}
    assert sorted(recs) == ["SN-A", "SN-B"]
    assert [lg["role"] for lg in recs["SN-A"]["logs"]] == ["train", "train", "test"]
    assert (tmp_path / "models" / "a" / "metrics.json").is_file()
    assert recs["SN-B"]["model_dir"] == "" and recs["SN-B"]["interval"] is None
    assert main(["fleet", "add-many", fleet, str(manifest), "--workers", "1"]) == 2
    assert "already in" in capsys.readouterr().err


@pytest.mark.parametrize("text, says", [
    ("serial,train\nSN1,a.csv\n", "line 1: the manifest needs the columns unit and train"),
    ("unit,train\nSN1,\n", "line 2: unit 'SN1' has no training log"),
    ("unit,train\nSN1,r2.csv\nSN1,r2.csv\n", "line 3: unit 'SN1' again"),
    ("unit,train\nSN1,missing.csv\n", "line 2: log"),
])
def test_manifest_refusals(tmp_path: Path, logs: dict[str, Path], text: str, says: str,
                           capsys) -> None:
    (tmp_path / "r2.csv").write_bytes(logs["r2"].read_bytes())
    (tmp_path / "m.csv").write_text(text)
    assert main(["fleet", "add-many", str(tmp_path / "f.fleet"), str(tmp_path / "m.csv")]) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1


def test_train_options_are_refused_before_the_batch(tmp_path: Path, logs: dict[str, Path],
                                                    capsys) -> None:
    """--train-options that `fleet add` does not know stop add-many before any unit trains
    or the fleet is created, in one line."""
    (tmp_path / "r2.csv").write_bytes(logs["r2"].read_bytes())
    (tmp_path / "m.csv").write_text("unit,train\nSN1,r2.csv\n")
    fleet = tmp_path / "f.fleet"
    argv = ["fleet", "add-many", str(fleet), str(tmp_path / "m.csv"), "--train-options"]
    assert main([*argv, "--iters 2 --bogus"]) == 2
    err = capsys.readouterr().err
    assert "fleet add knows no --bogus" in err and err.count("\n") == 1, err
    with pytest.raises(SystemExit) as e:  # a value fleet add refuses: argparse's own line
        main([*argv, "--iters -3"])
    assert e.value.code == 2 and "--iters: expected 0 or more" in capsys.readouterr().err
    assert not fleet.exists()
