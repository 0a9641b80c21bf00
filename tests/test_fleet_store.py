"""The fleet store: records round-trip, one transaction an add (a kill -9 inside it leaves the
database as before), two adds at once both land, a version-1 database is migrated forward.
Every test runs on SQLite and, when a PostgreSQL server is at hand (tests/fleet_units.py:
FOGSF_TEST_POSTGRES_URL, or Debian's postgresql started for the session), on it too."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fogsf.errors import UserError
from fogsf.fleet.store import SCHEMA_VERSION, open_store
from tests.fleet_units import ROOT, fake_record, fleet_urls, pause_in_add, wait_for

ADD_SCRIPT = """
import sys
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record
store = open_store(sys.argv[1])
store.add(fake_record(sys.argv[2], seed=int(sys.argv[3])), replace=sys.argv[4] == "1")
store.close()
"""

@pytest.fixture(params=fleet_urls())
def fleet(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    return request.param(tmp_path)


def _add_process(fleet: str, sn: str, seed: int, replace: bool = False,
                 env: dict | None = None, **kw: object) -> subprocess.Popen:
    """A process adding a made-up unit; `env` (`pause_in_add`'s): paused in its transaction."""
    return subprocess.Popen([sys.executable, "-c", ADD_SCRIPT, fleet, sn, str(seed),
                             "1" if replace else "0"], cwd=ROOT,
                            env=env or {**os.environ, "PYTHONPATH": str(ROOT)}, **kw)


def _snapshot(fleet: str) -> list[dict]:
    with open_store(fleet) as store:
        return [u.as_dict() for u in store.units()]


def test_records_round_trip_and_user_strings_stay_data(fleet: str) -> None:
    odd = "SN'); DROP TABLE units; --"
    with open_store(fleet) as store:
        assert store.schema_version() == SCHEMA_VERSION
        rec = fake_record(odd, seed=1)
        store.add(rec)
        store.add(fake_record("SN002", seed=2))
        assert [u.unit for u in store.units()] == sorted([odd, "SN002"])
        back = store.unit(odd)
        assert back.as_dict() == rec.as_dict()
        with pytest.raises(UserError, match="already in"):
            store.add(fake_record(odd, seed=3))
        store.add(fake_record(odd, seed=3), replace=True)
        assert store.unit(odd).summary == fake_record(odd, seed=3).summary
        store.remove(odd)
        assert [u.unit for u in store.units()] == ["SN002"]
        with pytest.raises(UserError, match="no unit"):
            store.remove(odd)
        with pytest.raises(UserError, match="no unit"):
            store.unit("nope")


@pytest.mark.slow
@pytest.mark.parametrize("replace", [False, True])
def test_kill_inside_an_add_leaves_the_database_as_before(fleet: str, tmp_path: Path,
                                                          replace: bool) -> None:
    with open_store(fleet) as store:
        store.add(fake_record("SN001", seed=1))
    before = _snapshot(fleet)
    marker = tmp_path / "inside-transaction"
    proc = _add_process(fleet, "SN001" if replace else "SN009", seed=9, replace=replace,
                        env=pause_in_add(tmp_path, marker))
    try:
        wait_for(marker.exists, 60.0, "the add never reached its transaction")
        os.kill(proc.pid, signal.SIGKILL)  # after the INSERTs, before COMMIT
        assert proc.wait(30) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
    assert _snapshot(fleet) == before
    if not fleet.startswith("postgres"):
        import sqlite3

        db = sqlite3.connect(fleet)
        assert db.execute("PRAGMA integrity_check").fetchall() == [("ok",)]
        db.close()
    with open_store(fleet) as store:  # the store still takes adds
        store.add(fake_record("SN010", seed=10))
        assert [u.unit for u in store.units()] == ["SN001", "SN010"]


@pytest.mark.slow
def test_two_adds_at_once_both_land(fleet: str, tmp_path: Path) -> None:
    open_store(fleet).close()  # created: both processes find the schema
    marker = tmp_path / "first-inside"
    first = _add_process(fleet, "SN-A", seed=1, env=pause_in_add(tmp_path, marker, 2))
    try:
        wait_for(marker.exists, 60.0, "the first add never reached its transaction")
        second = _add_process(fleet, "SN-B", seed=2)  # waits for the first's lock
        assert second.wait(120) == 0
        assert first.wait(120) == 0
    finally:
        for p in (first,):
            if p.poll() is None:
                p.kill()
    with open_store(fleet) as store:
        assert sorted(u.unit for u in store.units()) == ["SN-A", "SN-B"]
        assert store.unit("SN-B").summary == fake_record("SN-B", seed=2).summary
    # the same unit from two processes at once: the second is refused, the first stays
    marker.unlink()
    first = _add_process(fleet, "SN-C", seed=5, env=pause_in_add(tmp_path, marker, 2))
    wait_for(marker.exists, 60.0, "the first add never reached its transaction")
    second = _add_process(fleet, "SN-C", seed=6, stderr=subprocess.PIPE, text=True)
    _, err = second.communicate(timeout=120)
    assert first.wait(120) == 0 and second.returncode != 0
    assert "already in" in err or "by another process" in err, err[-500:]
    with open_store(fleet) as store:
        assert store.unit("SN-C").summary == fake_record("SN-C", seed=5).summary
    # and two started together, neither pausing
    procs = [_add_process(fleet, f"SN-{i}", seed=i) for i in range(3, 5)]
    assert [p.wait(120) for p in procs] == [0, 0]
    assert len(_snapshot(fleet)) == 5


# The schema as fogsf's first fleet store wrote it (frozen here: a file of version 1 must
# always open).
V1_DDL = [
    "CREATE TABLE schema_version (version INTEGER NOT NULL)",
    "INSERT INTO schema_version (version) VALUES (1)",
    """CREATE TABLE units (sn TEXT PRIMARY KEY, model_id TEXT NOT NULL,
       model_dir TEXT NOT NULL, fitted_with TEXT NOT NULL, figures TEXT NOT NULL,
       interval_json TEXT, summary TEXT NOT NULL, fogsf_version TEXT NOT NULL,
       created_utc TEXT NOT NULL)""",
    """CREATE TABLE logs (sn TEXT NOT NULL REFERENCES units(sn) ON DELETE CASCADE,
       idx INTEGER NOT NULL, path TEXT NOT NULL, sha256 TEXT NOT NULL,
       n_rows BIGINT NOT NULL, span_s DOUBLE PRECISION NOT NULL,
       sample_rate_hz DOUBLE PRECISION NOT NULL, ramp_rates TEXT NOT NULL,
       temp_min_c DOUBLE PRECISION, temp_max_c DOUBLE PRECISION, PRIMARY KEY (sn, idx))""",
    """INSERT INTO units VALUES ('SN-OLD', 'abc123', '', '{"model": "lag-lstm"}',
       '{"noise_floor_ppm": 8.5}', NULL, '{"params": {"tau_s": [900.0]},
       "structure": "physics1"}', '0.0.9', '2026-01-02T03:04:05Z')""",
    """INSERT INTO logs VALUES ('SN-OLD', 0, '/lab/SN-OLD/loop.csv', 'ff00', 72000, 7200.0,
       10.0, '[2.0]', -20.0, 40.0)""",
]


def test_a_version_1_database_is_migrated_forward(fleet: str) -> None:
    from tests.fleet_units import raw_execute

    raw_execute(fleet, V1_DDL)
    with open_store(fleet) as store:
        assert store.schema_version() == SCHEMA_VERSION
        old = store.unit("SN-OLD")
        assert old.summary["structure"] == "physics1"
        assert [(lg.path, lg.rows, lg.role) for lg in old.logs] == [
            ("/lab/SN-OLD/loop.csv", 72000, "train")]
        assert old.chamber_hours == pytest.approx(2.0)
        assert old.interval is None and old.fogsf_version == "0.0.9"
        store.add(fake_record("SN-NEW", seed=5))  # the migrated schema takes new units
        assert [u.unit for u in store.units()] == ["SN-NEW", "SN-OLD"]
        assert store.execute("SELECT structure FROM units WHERE sn = ?",
                             ("SN-OLD",)).fetchall() == [("physics1",)]
    raw_execute(fleet, ["UPDATE schema_version SET version = 99"])
    with pytest.raises(UserError, match="newer than this fogsf"):
        open_store(fleet)


def test_bad_locations_are_refused_in_one_line(tmp_path: Path) -> None:
    not_db = tmp_path / "notes.txt"
    not_db.write_text("hello, not a database\n" * 100)
    with pytest.raises(UserError, match="not a fleet database"):
        open_store(str(not_db))
    with pytest.raises(UserError, match="does not exist"):
        open_store(str(tmp_path / "missing" / "line.fleet"))
    with pytest.raises(UserError, match="not a file"):
        open_store(str(tmp_path))


def test_wait_for_gives_up() -> None:
    t0 = time.monotonic()
    with pytest.raises(AssertionError, match="never"):
        wait_for(lambda: False, 0.2, "never")
    assert time.monotonic() - t0 < 5
