"""`fogsf fleet add --model-dir DIR`: the model a training kept recorded without training
again: the record equals the one the add that trained it wrote (its response and
SF curve within the kernel's 0.01 ppm of torch's, `fleet.kept_model`), nothing is trained,
a database fault after training names the retry and the retry records the unit, and a
folder that is not the unit's model is refused in one line."""

from __future__ import annotations

import json
import shlex
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from fogsf.cli.main import main
from fogsf.fleet import store
from fogsf.fleet.kept_model import KEPT_FILE
from fogsf.fleet.store import open_store
from tests.fleet_units import ROOT, fleet_urls, no_training, same_record

FAST = ["--structure", "physics", "--iters", "2", "--hysteresis", "off", "--no-progress"]
@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("logs")
    out = {}
    for name, rate, seed in (("r2", "2", "1"), ("r1", "1", "2")):
        out[name] = d / f"{name}.csv"
        assert main(["simulate", "--scenario", "paper", "--ramp-rate", rate, "--seed", seed,
                     "--start-c", "-20", "--stop-c", "40", "--sample-rate-hz", "1",
                     "--out", str(out[name])]) == 0
    for name, seed in (("table", "1"), ("table_test", "2")):
        out[name] = d / name / "table.csv"
        assert main(["simulate", "--plateaus", "--random-gyro", "17", "--effect",
                     "open_loop=0.2", "--seed", seed, "--out", str(out[name])]) == 0
    return out


def _record(fleet: str, unit: str) -> dict[str, Any]:
    with open_store(fleet, "read") as s:
        (rec,) = [u for u in s.units() if u.unit == unit]
    return rec.as_dict()


def _add_untrained(argv: list[str], tmp_path: Path) -> subprocess.CompletedProcess:
    """`fogsf fleet add ARGV` in a process where any training raises."""
    return subprocess.run([sys.executable, "-m", "fogsf.cli.main", "fleet", "add", *argv],
                          cwd=ROOT, env=no_training(tmp_path), capture_output=True,
                          text=True, timeout=300)


@pytest.mark.parametrize("make_fleet", fleet_urls())
def test_the_kept_model_records_what_the_trained_add_did(make_fleet, logs: dict[str, Path],
                                                          tmp_path: Path, capsys) -> None:
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
    fleet, again = make_fleet(tmp_path / "a"), make_fleet(tmp_path / "b")
    model = tmp_path / "models" / "SN1"
    unit = ["--unit", "SN1", "--train", str(logs["r2"]), "--test", str(logs["r1"]), *FAST]
    assert main(["fleet", "add", fleet, *unit, "--out", str(model)]) == 0
    assert (model / KEPT_FILE).is_file()
    capsys.readouterr()
    run = _add_untrained([again, *unit, "--model-dir", str(model)], tmp_path)
    assert run.returncode == 0, run.stderr
    assert "training entered" not in run.stderr
    assert f"model in {model} (recorded from it, not trained)" in run.stdout
    assert "SF error, ppm" in run.stdout  # the kept model's figures, as add prints them
    want, got = _record(fleet, "SN1"), _record(again, "SN1")
    assert want["created_utc"] and got["created_utc"]
    want["created_utc"] = got["created_utc"] = ""
    assert same_record(want, got) == []
    assert got["model_dir"] == str(model.resolve()) and got["figures"]["response_ppm"]
    # the same add, trained, in that process: the training entry does raise there
    run = _add_untrained([again, *unit, "--unit", "SN2"], tmp_path)
    assert run.returncode != 0 and "training entered" in run.stderr


@pytest.mark.parametrize("make_fleet", fleet_urls())
def test_a_fault_after_training_names_the_retry_that_records(
        make_fleet, logs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys) -> None:
    fleet = make_fleet(tmp_path)
    error: type[Exception] = sqlite3.OperationalError
    if fleet.startswith("postgres"):
        import psycopg

        error = psycopg.OperationalError

    def disk_full(*args: object, **kwargs: object) -> None:
        raise error("database or disk is full")

    for cls in (store.FleetStore, store.PostgresStore):
        monkeypatch.setattr(cls, "add", disk_full)
    model = tmp_path / "kept model"  # a space: the retry is quoted for the shell
    assert main(["fleet", "add", fleet, "--unit", "SN7", "--train", str(logs["r2"]), *FAST,
                 "--seed", "3", "--out", str(model)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("error:") == 1, err
    assert "database or disk is full" in err and f"kept in {model}" in err
    retry = shlex.split(err.split("record it without training again: ", 1)[1])
    assert retry[:3] == ["fogsf", "fleet", "add"] and retry[-2:] == ["--model-dir", str(model)]
    assert "--out" not in retry and retry.count(str(model)) == 1
    monkeypatch.undo()
    run = _add_untrained(retry[3:], tmp_path)
    assert run.returncode == 0, run.stderr
    rec = _record(fleet, "SN7")
    metrics = json.loads((model / "metrics.json").read_text())
    assert rec["model_id"] == metrics["model_id"] and rec["fitted_with"]["options"]["seed"] == 3


def test_plateau_units_from_their_kept_model(logs: dict[str, Path], tmp_path: Path,
                                             capsys) -> None:
    fleet, again = str(tmp_path / "a.fleet"), str(tmp_path / "b.fleet")
    model = tmp_path / "SN-P"
    unit = ["--unit", "SN-P", "--train", str(logs["table"]), "--test", str(logs["table_test"])]
    assert main(["fleet", "add", fleet, *unit, "--out", str(model)]) == 0
    capsys.readouterr()
    run = _add_untrained([again, *unit, "--model-dir", str(model)], tmp_path)
    assert run.returncode == 0, run.stderr
    want, got = _record(fleet, "SN-P"), _record(again, "SN-P")
    want["created_utc"] = got["created_utc"] = ""
    assert want == got  # the plateau model is the reference's in both: to the bit
    # sample logs given to a plateau model
    assert main(["fleet", "add", again, "--unit", "SN-Q", "--train", str(logs["r2"]),
                 "--model-dir", str(model)]) == 2
    assert "holds a plateau model and the logs given are sample logs" in capsys.readouterr().err
    # a sample log's option, refused as the add that trains refuses it
    assert main(["fleet", "add", again, *unit, "--unit", "SN-R", "--structure", "bank",
                 "--model-dir", str(model)]) == 2
    assert "--structure is for sample logs" in capsys.readouterr().err


@pytest.mark.slow
def test_folders_not_the_units_model_are_refused(logs: dict[str, Path], tmp_path: Path,
                                                 capsys) -> None:
    model = tmp_path / "m"
    fleet = str(tmp_path / "line.fleet")
    assert main(["fleet", "add", fleet, "--unit", "SN1", "--train", str(logs["r2"]), *FAST,
                 "--out", str(model)]) == 0
    poly = tmp_path / "poly"
    assert main(["train", "--model", "poly", "--train", str(logs["r2"]), "--out", str(poly),
                 "--no-progress"]) == 0
    trained = tmp_path / "trained"  # `fogsf train`'s folder: no KEPT_FILE
    shutil.copytree(model, trained)
    (trained / KEPT_FILE).unlink()
    broken = tmp_path / "broken"
    shutil.copytree(model, broken)
    (broken / "stream_weights.npz").unlink()
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "metrics.json").write_text("{not json")
    other = tmp_path / "other"
    shutil.copytree(model, other)
    (other / "metrics.json").write_text((other / "metrics.json").read_text().replace(
        json.loads((other / "metrics.json").read_text())["model_id"], "0" * 16))
    retrained = tmp_path / "retrained"  # KEPT_FILE left by an add, another training over it
    shutil.copytree(model, retrained)
    assert main(["train", "--train", str(logs["r1"]), *FAST, "--seed", "5", "--out",
                 str(retrained)]) == 0
    capsys.readouterr()
    r2, r1 = ["--train", str(logs["r2"])], ["--train", str(logs["r1"])]
    refusals = [
        (tmp_path / "none", r2, "no such folder"),
        (broken, r2, "stream_weights.npz: missing"),
        (garbage, r2, "metrics.json cannot be read"),
        (tmp_path, r2, "no metrics.json: not a complete fogsf model folder"),
        (other, r2, "parts of two trainings"),
        (poly, r2, "a 'poly' model keeps no firmware artifact"),
        (model, r1, f"was trained on {logs['r2'].resolve()} (train), not on {logs['r1']}"),
        (model, [*r2, "--test", str(logs["r1"])], "1 training log(s) without a test log"),
        (model, [*r2, "--seed", "4"], "was trained with seed = 0, the options given say 4"),
        (trained, r1, "other ramps than those given"),
        (retrained, r2, "other ramps than those given"),
        (trained, [*r2, "--model", "lstm"], "trained with model = 'lag-lstm'"),
        (model, [*r2, "--out", str(tmp_path / "x")], "give one of them"),
        (model, ["--train", str(logs["table"])], "holds a lag-lstm model and the logs given "
                                                 "are plateau tables"),
    ]
    for folder, given, says in refusals:
        argv = ["fleet", "add", str(tmp_path / "new.fleet"), "--unit", "SN2", *given, *FAST,
                "--model-dir", str(folder)]
        assert main(argv) == 2, (folder, given)
        err = capsys.readouterr().err
        assert "Traceback" not in err and err.count("error:") == 1 and says in err, (says, err)
    assert not (tmp_path / "new.fleet").exists()  # a refused add creates no fleet
    # `fogsf train`'s folder with its logs and options: recorded, checked by its ramps
    assert main(["fleet", "add", fleet, "--unit", "SN3", *r2, *FAST, "--model-dir",
                 str(trained)]) == 0


@pytest.mark.parametrize("out", [["--out", "m d"], ["--out=m d"]])
def test_the_retry_replaces_out_in_either_form(out: list[str]) -> None:
    import argparse

    from fogsf.cli.fleet import _retry

    argv = ["f.fleet", "--unit", "S1", *out, "--train", "a.csv", "--batch", "b1"]
    ns = argparse.Namespace(fleet="f.fleet", unit="S1", batch="b1", out="m d",
                            _argv=["fleet", "add", *argv])
    assert _retry(ns) == "fogsf fleet add f.fleet --unit S1 --train a.csv --model-dir 'm d'"
