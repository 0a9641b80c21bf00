"""A fleet database's faults in one line, exit status 2, never a traceback: a write lock held
by another process (waited for, with a message), damaged files, a manifest in another
encoding, and `fogsf fleet list | head` (issue 54)."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.fleet import faults, store
from fogsf.fleet.manifest import read_manifest
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record

ROOT = Path(__file__).resolve().parents[1]


def _fleet(tmp_path: Path, n: int = 3) -> str:
    fleet = str(tmp_path / "line.fleet")
    with open_store(fleet) as s:
        for i in range(n):
            s.add(fake_record(f"SN{i:03d}", seed=i))
    return fleet


def _one_line(capsys: pytest.CaptureFixture, *says: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("error:") == 1, err
    for s in says:
        assert s in err, err
    return err


@pytest.fixture
def short_waits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(store, "BUSY_TIMEOUT_S", 2.0)
    monkeypatch.setattr(faults, "SQLITE_BUSY_FIRST_S", 0.3)


def _hold_write_lock(fleet: str) -> sqlite3.Connection:
    db = sqlite3.connect(fleet, isolation_level=None, check_same_thread=False)
    db.execute("BEGIN IMMEDIATE")
    return db


@pytest.mark.slow
def test_a_locked_fleet_is_waited_for_then_refused(tmp_path: Path, short_waits: None,
                                                   capsys) -> None:
    fleet = _fleet(tmp_path)
    holder = _hold_write_lock(fleet)
    try:
        t0 = time.monotonic()
        assert main(["fleet", "remove", fleet, "SN001"]) == 2
        assert time.monotonic() - t0 >= 1.5
        err = capsys.readouterr().err
        assert "is busy (another process is writing to it): waiting up to 2 s" in err
        assert "stayed locked by another process for 2 s: nothing written" in err
        assert "Traceback" not in err and err.count("\n") == 2
    finally:
        holder.rollback()
        holder.close()
    with open_store(fleet, "read") as s:
        assert len(s.units()) == 3


def test_a_lock_released_while_waiting_lets_the_write_through(tmp_path: Path,
                                                               short_waits: None,
                                                               capsys) -> None:
    fleet = _fleet(tmp_path)
    holder = _hold_write_lock(fleet)
    release = threading.Timer(0.8, lambda: holder.execute("ROLLBACK"))
    release.start()
    try:
        assert main(["fleet", "remove", fleet, "SN001"]) == 0
        assert "is busy" in capsys.readouterr().err
    finally:
        release.join()
        holder.close()


def test_damaged_fleets_in_one_line(tmp_path: Path, capsys) -> None:
    fleet = _fleet(tmp_path, n=20)
    raw = bytearray(Path(fleet).read_bytes())
    raw[4096:] = b"\xa5" * (len(raw) - 4096)  # every page after the first: garbage
    broken = tmp_path / "broken.fleet"
    broken.write_bytes(bytes(raw))
    assert main(["fleet", "list", str(broken)]) == 2
    _one_line(capsys, "broken.fleet")
    nover = tmp_path / "nover.fleet"
    nover.write_bytes(Path(fleet).read_bytes())
    with sqlite3.connect(nover) as db:
        db.execute("DELETE FROM schema_version")
    for argv in (["fleet", "list", str(nover)], ["fleet", "remove", str(nover), "SN001"]):
        assert main(argv) == 2
        _one_line(capsys, "schema_version row is missing")


def test_manifest_encodings(tmp_path: Path, capsys) -> None:
    (tmp_path / "a.csv").write_text("t\n")
    latin = tmp_path / "latin.csv"
    latin.write_bytes("unit,train\nSN1,a.csv\nKreisel-\xe9,a.csv\n".encode("latin-1"))
    assert main(["fleet", "add-many", str(tmp_path / "f.fleet"), str(latin)]) == 2
    _one_line(capsys, "line 3: not UTF-8 text (byte 0xe9)")
    assert not (tmp_path / "f.fleet").exists()
    utf16 = tmp_path / "utf16.csv"
    utf16.write_bytes("unit,train\nKreisel-\xe9,a.csv\n".encode("utf-16"))  # with its BOM
    assert [r.unit for r in read_manifest(utf16)] == ["Kreisel-\xe9"]
    huge = tmp_path / "huge.csv"
    huge.write_text("unit,train\nSN1," + "x" * 200_000 + "\n")
    assert main(["fleet", "add-many", str(tmp_path / "f.fleet"), str(huge)]) == 2
    _one_line(capsys, "not a CSV manifest")


def test_list_into_a_closed_pipe(tmp_path: Path) -> None:
    fleet = _fleet(tmp_path, n=60)  # --json of 60 units: far more than a pipe's buffer
    cmd = (f"{sys.executable} -m fogsf.cli.main fleet list {fleet} --json | head -c 100 "
           "> /dev/null")
    run = subprocess.run(["bash", "-c", "set -o pipefail; " + cmd], cwd=ROOT,
                         capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert "Traceback" not in run.stderr and "BrokenPipe" not in run.stderr, run.stderr
    assert run.stderr == "" and run.returncode in (0, 141)


@pytest.mark.slow
def test_an_add_that_cannot_record_keeps_the_training(tmp_path: Path, short_waits: None,
                                                      monkeypatch: pytest.MonkeyPatch,
                                                      capsys) -> None:
    log = tmp_path / "r2.csv"
    assert main(["simulate", "--scenario", "paper", "--ramp-rate", "2", "--seed", "1",
                 "--start-c", "-20", "--stop-c", "40", "--sample-rate-hz", "1",
                 "--out", str(log)]) == 0
    fleet = _fleet(tmp_path)
    capsys.readouterr()
    holder = None
    real_add = store.FleetStore.add

    def add_under_a_lock(self: store.FleetStore, record: object, replace: bool = False,
                         guard: object = None) -> None:  # the lock taken after training
        nonlocal holder
        holder = _hold_write_lock(fleet)
        real_add(self, record, replace, guard)

    monkeypatch.setattr(store.SQLiteStore, "add", add_under_a_lock, raising=False)
    try:
        model = tmp_path / "m1"
        assert main(["fleet", "add", fleet, "--unit", "SN9", "--train", str(log), "--out",
                     str(model), "--structure", "physics", "--iters", "2", "--hysteresis",
                     "off", "--no-progress"]) == 2
    finally:
        if holder is not None:
            holder.rollback()
            holder.close()
    _one_line(capsys, "stayed locked", f"the trained model is kept in {model}")
    assert (model / "metrics.json").is_file()
