"""`fogsf train --prior FLEET --unit SN` when the database write fails: the model is kept,
the error names the `fleet add --model-dir` that records it, and that add records the unit
as the training would have (the prior it was fitted under included) without training."""

from __future__ import annotations

import json
import shlex
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.fleet import store
from fogsf.fleet.kept_model import KEPT_FILE, retry_command
from fogsf.fleet.store import open_store
from tests.fleet_units import ROOT, no_training, same_record, small_line

SEED = 4411


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return small_line(tmp_path_factory.mktemp("fleet"), SEED, 3, (2.0,))


@pytest.mark.slow
def test_a_fault_after_training_under_the_prior_names_the_add_that_records(
        fleet: dict, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    tried: list = []  # the record the training would have written

    def disk_full(self: object, record: object, *args: object, **kwargs: object) -> None:
        tried.append(record)
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(store.FleetStore, "add", disk_full)
    out = fleet["tmp"] / "kept m"  # a space: the retry is quoted for the shell
    msg = f"design {fleet['design']} (seed {SEED})"
    assert main(["train", "--prior", fleet["db"], "--unit", "SN-new", "--train",
                 str(fleet["new"]), "--out", str(out), "--iters", "2", "--seed", "4",
                 "--no-progress"]) == 2, msg
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("error:") == 1, err
    assert "database or disk is full" in err and f"kept in {out}" in err, err
    assert (out / KEPT_FILE).is_file()
    retry = shlex.split(err.split("record it without training again: ", 1)[1])
    assert retry[:4] == ["fogsf", "fleet", "add", fleet["db"]], retry
    assert retry[-2:] == ["--model-dir", str(out)] and "--prior" not in retry
    assert "--out" not in retry and retry.count(str(out)) == 1
    monkeypatch.undo()
    with open_store(fleet["db"]) as s:
        assert not s.has("SN-new")
    run = subprocess.run([sys.executable, "-m", "fogsf.cli.main", *retry[1:]], cwd=ROOT,
                         env=no_training(fleet["tmp"]), capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert "recorded from it, not trained" in run.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    with open_store(fleet["db"]) as s:
        rec = s.unit("SN-new")
    options = rec.fitted_with["options"]
    assert rec.model_id == metrics["model_id"] and options["seed"] == 4, msg
    assert options["prior"] == {"fleet_units": ["SN0", "SN1", "SN2"],
                                "used": metrics["prior"]["used"]}, msg
    want, got = json.loads(json.dumps(tried[0].as_dict())), rec.as_dict()  # as stored
    want["created_utc"] = got["created_utc"] = ""
    assert same_record(want, got) == [], msg  # the predictions within the kernel's 0.01 ppm


def test_a_prior_model_without_its_unit_file_is_refused(fleet: dict,
                                                        capsys: pytest.CaptureFixture) -> None:
    out = fleet["tmp"] / "no-unit"
    assert main(["train", "--prior", fleet["db"], "--train", str(fleet["new"]), "--out",
                 str(out), "--iters", "1", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["fleet", "add", str(fleet["tmp"] / "other.fleet"), "--unit", "SN9",
                 "--train", str(fleet["new"]), "--model-dir", str(out)]) == 2
    err = capsys.readouterr().err
    assert "trained under the design's prior without --unit" in err and "Traceback" not in err


@pytest.mark.parametrize("given", [["--out", "m d"], ["--out=m d"], ["--ou", "m d"],
                                   ["--out", "x", "--out", "m d"]])
def test_the_retry_drops_the_prior_and_the_folder(given: list[str]) -> None:
    argv = ["f.fleet", "--pri", "f.fleet", "--unit", "S1", *given, "--train", "a.csv"]
    assert retry_command(argv, ("--prior", "--out"), "m d") == (
        "fogsf fleet add f.fleet --unit S1 --train a.csv --model-dir 'm d'")


def test_the_retry_prints_no_password() -> None:
    url = "postgresql://fogsf:s3cret@db.example/line?sslmode=require&password=s3cret"
    got = retry_command([url, "--prior=" + url, "--unit", "S1", "--out", "m"],
                        ("--prior", "--out"), "m")
    assert "s3cret" not in got and "postgresql://fogsf@db.example/line?sslmode=require" in got


def test_unit_with_every_axis_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["train", "--prior", str(tmp_path / "f.fleet"), "--unit", "S1", "--axis", "all",
                 "--train", "a.csv", "--out", str(tmp_path / "m")]) == 2
    assert "give one --axis, not all" in capsys.readouterr().err
