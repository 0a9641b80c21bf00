"""The fleet database is never lost: `report --out` writes only into a folder it owns, read
commands never create or change a file, unit names follow one stated rule (issue 54)."""

from __future__ import annotations

import hashlib
import sqlite3
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.fleet.names import check_unit_name, masked
from fogsf.fleet.report import MARKER
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record


def _tree(folder: Path) -> dict[str, str]:
    """Every file under `folder` with its content's hash: what "nothing changed" means."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _fleet(folder: Path, n: int = 3) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    fleet = str(folder / "line.fleet")
    with open_store(fleet) as store:
        for i in range(n):
            store.add(fake_record(f"SN{i:03d}", seed=i))
    return fleet


def _one_line_error(capsys: pytest.CaptureFixture, *says: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for s in says:
        assert s in err, err
    return err


# --- report --out ------------------------------------------------------------------------------

def test_report_refuses_folders_it_did_not_write(tmp_path: Path, capsys) -> None:
    line = tmp_path / "line"
    fleet = _fleet(line)
    (line / "notes.txt").write_text("the line's notes\n")
    models = tmp_path / "models"
    (models / "SN000").mkdir(parents=True)
    (models / "SN000" / "metrics.json").write_text("{}\n")
    before = {"line": _tree(line), "models": _tree(models)}
    for out in (line, models):
        assert main(["fleet", "report", fleet, "--out", str(out)]) == 2
        _one_line_error(capsys, "did not write", str(out))
    assert {"line": _tree(line), "models": _tree(models)} == before  # nothing deleted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["line", "models"]  # no leftovers
    assert main(["fleet", "list", fleet]) == 0  # the database still answers


@pytest.mark.slow
def test_report_replaces_its_own_report_and_nothing_else(tmp_path: Path, capsys) -> None:
    fleet = _fleet(tmp_path / "line")
    rep = tmp_path / "rep"
    rep.mkdir()  # an empty folder is the report's to fill
    assert main(["fleet", "report", fleet, "--out", str(rep)]) == 0
    assert (rep / "index.html").is_file() and (rep / MARKER).is_file()
    with open_store(fleet) as store:
        store.remove("SN002")
    assert main(["fleet", "report", fleet, "--out", str(rep)]) == 0  # its own: replaced
    assert len(list((rep / "units").glob("*.html"))) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["line", "rep"]  # no temp folders
    (rep / "units" / "my-notes.txt").write_text("kept\n")  # a user's file inside the report
    assert main(["fleet", "report", fleet, "--out", str(rep)]) == 2
    _one_line_error(capsys, "holds files the report did not write", "my-notes.txt")
    assert (rep / "units" / "my-notes.txt").read_text() == "kept\n"
    assert (rep / "index.html").is_file()


# --- read commands -----------------------------------------------------------------------------

def test_read_commands_never_create_or_change_a_file(tmp_path: Path, capsys) -> None:
    fleet = _fleet(tmp_path / "line")
    foreign = tmp_path / "other.db"
    db = sqlite3.connect(foreign)
    db.execute("CREATE TABLE parts (pn TEXT)")
    db.commit()
    db.close()
    text = tmp_path / "notes.txt"
    text.write_text("not a database\n")
    before = _tree(tmp_path)
    cwd = Path.cwd()
    try:
        import os

        os.chdir(tmp_path)  # "SN001" below is a relative path: it must not appear here
        cases = [
            (["fleet", "list", "typo.fleet"], "typo.fleet: no such fleet database"),
            (["fleet", "remove", "SN001", fleet], "SN001: no such fleet database"),
            (["fleet", "check", "typo.fleet"], "no such fleet database"),
            (["fleet", "report", "typo.fleet", "--out", "rep"], "no such fleet database"),
            (["fleet", "list", str(foreign)], "is not a fleet database"),
            (["fleet", "remove", str(foreign), "SN001"], "is not a fleet database"),
            (["fleet", "check", str(text)], "is not a fleet database"),
            (["fleet", "add", str(foreign), "--unit", "SN9", "--train", "x.csv"],
             "is not a fleet database"),  # add creates a fleet only where nothing is
            (["plan", "--prior", "typo.fleet", "--target", "1.3", "--out", "plan"],
             "typo.fleet: no such fleet database"),
            (["plan", "--prior", str(foreign), "--target", "1.3", "--out", "plan"],
             "is not a fleet database"),
            (["train", "--prior", str(foreign), "--train", "notes.txt", "--out", "m"], ""),
        ]
        for argv, says in cases:
            assert main(argv) == 2, argv
            _one_line_error(capsys, says)
    finally:
        os.chdir(cwd)
    after = _tree(tmp_path)
    assert {k: v for k, v in after.items() if not k.endswith(("-shm", "-wal"))} == before
    assert not (tmp_path / "typo.fleet").exists() and not (tmp_path / "SN001").exists()
    with sqlite3.connect(foreign) as db:  # no fleet tables written into it
        names = {r[0] for r in db.execute("SELECT name FROM sqlite_master")}
    assert names == {"parts"}


def test_a_read_only_fleet_file_is_read(tmp_path: Path, capsys) -> None:
    fleet = Path(_fleet(tmp_path / "line"))
    fleet.chmod(0o444)
    try:
        with open_store(str(fleet), "read") as store:
            assert [u.unit for u in store.units()] == ["SN000", "SN001", "SN002"]
    finally:
        fleet.chmod(0o644)


# --- unit names --------------------------------------------------------------------------------

BAD_NAMES = {
    "newline": "SN001\nSN999     2.0 h",
    "escape": "SN\x1b[2J\x1b[31mRED",
    "nul": "SN\x00001",
    "10 kB": "S" * 10_000,
    "65 characters": "N" * 65,
    "bidi override": "SN\u202e100",
    "tab": "SN\t1",
    "leading space": " SN1",
    "empty": "",
}
GOOD_NAMES = ["SN001", "D3-0000", "SN'); DROP TABLE units; --", "<script>alert(1)</script>",
              "Kreisel Ω 7", "N" * 64]


@pytest.mark.parametrize("name", list(BAD_NAMES.values()), ids=list(BAD_NAMES))
def test_bad_unit_names_are_refused_by_every_command(name: str, tmp_path: Path,
                                                     capsys) -> None:
    with pytest.raises(UserError):
        check_unit_name(name)
    fleet = _fleet(tmp_path / "line", n=1)
    with open_store(fleet) as store, pytest.raises(UserError):
        store.add(fake_record(name, seed=1))  # the store's own guard
    assert main(["fleet", "add", fleet, "--unit", name, "--train", "x.csv"]) == 2
    _one_line_error(capsys)
    assert main(["fleet", "remove", fleet, name]) == 2
    err = _one_line_error(capsys)
    assert "\x1b" not in err and "\x00" not in err and len(err) < 400
    manifest = tmp_path / "units.csv"
    log = tmp_path / "a.csv"
    log.write_text("t\n")
    manifest.write_text(f'unit,train\nSN5,a.csv\n"{name}",a.csv\n', encoding="utf-8")
    if name and name.strip() == name:  # the manifest strips its cells' ends
        assert main(["fleet", "add-many", fleet, str(manifest)]) == 2
        _one_line_error(capsys, "line 3")
    with open_store(fleet, "read") as store:
        assert [u.unit for u in store.units()] == ["SN000"]


@pytest.mark.parametrize("name", GOOD_NAMES)
def test_good_unit_names_are_kept(name: str, tmp_path: Path, capsys) -> None:
    assert check_unit_name(name) == name
    fleet = _fleet(tmp_path, n=0)
    with open_store(fleet) as store:
        store.add(fake_record(name, seed=1))
    assert main(["fleet", "list", fleet]) == 0
    assert name[:16] in capsys.readouterr().out
    assert main(["fleet", "remove", fleet, name]) == 0


def test_masked_urls() -> None:
    assert masked("line.fleet") == "line.fleet"
    assert masked("postgresql://ann:pw%40x@db.lab:5433/line") == \
        "postgresql://ann:***@db.lab:5433/line"
    assert "s3cret" not in masked("postgresql://ann@/line?host=/run/pg&password=s3cret")
    assert masked("postgresql://ann@db/line") == "postgresql://ann@db/line"


def test_stationary_logs_are_refused_before_training(tmp_path: Path, capsys) -> None:
    """A unit's record is its SF response: a stationary log (a bias-only model) is refused
    in one line before any training, no fleet created, for add and train --prior --unit."""
    log = tmp_path / "st" / "log.csv"
    assert main(["simulate", "--rig", "plain", "--protocol", "stationary", "--random-gyro",
                 "20001", "--out", str(log)]) == 0
    capsys.readouterr()
    fleet = tmp_path / "new.fleet"
    assert main(["fleet", "add", str(fleet), "--unit", "S1", "--train", str(log)]) == 2
    _refused(capsys)
    assert not fleet.exists()
    line = _fleet(tmp_path / "line")
    assert main(["train", "--prior", line, "--unit", "S2", "--train", str(log), "--out",
                 str(tmp_path / "m")]) == 2
    _refused(capsys)


def _refused(capsys: pytest.CaptureFixture) -> None:
    """The last line on stderr is the refusal (the column map's note may precede it)."""
    err = capsys.readouterr().err
    assert "Traceback" not in err and "stationary" in err.splitlines()[-1], err
    assert "bias-only" in err.splitlines()[-1], err
