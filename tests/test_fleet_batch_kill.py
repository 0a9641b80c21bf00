"""A killed batch stops: `fleet add-many` killed with SIGKILL (its pid, or its process group)
leaves no process, lands no unit after the kill, and leaves no temporary folder once the
next command ran; a worker that outlives its batch records nothing; every fogsf process's
temporary folder goes at exit, or with the next command when the process was killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fogsf import scratch
from fogsf.errors import UserError
from fogsf.fleet.lease import BatchLease, check_batch, host_key
from fogsf.fleet.store import open_store
from tests.fleet_kill import count_units, kill_trial, make_logs
from tests.fleet_units import FLEETS, fake_record, fleet_urls, pause_in_add, wait_for

FAST = ["--structure", "physics", "--iters", "2", "--hysteresis", "off", "--no-progress"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return make_logs(tmp_path_factory.mktemp("logs"))


# Each backend once and each kill once: a kill by pid and by process group reach the same
# code on either backend. `python -m benchmarks.probes.fleet_batch_kill --trials 10` runs
# every backend killed each way, repeatedly.
KILLS = [("sqlite", "pid"), ("postgresql", "group")]


@pytest.mark.slow
@pytest.mark.parametrize("backend, how", KILLS, ids=[f"{b}-{h}" for b, h in KILLS])
def test_a_killed_batch_stops(backend: str, how: str, logs: list[Path], tmp_path: Path
                              ) -> None:
    fleet = FLEETS[backend](tmp_path)
    t = kill_trial(tmp_path, fleet, logs, how)
    assert t.at_kill >= 1, f"killed before any unit landed, or never killed: {t}"
    assert not t.alive_soon and not t.alive, f"processes of the batch alive after the kill: {t}"
    assert t.later == t.at_kill, f"units landed after the kill: {t}"
    assert t.integrity == "ok", f"the fleet's integrity check: {t}"
    assert not t.fogsf_left(), f"temporary folders left after the next command: {t}"


@pytest.mark.slow
def test_a_worker_outliving_its_batch_records_nothing(logs: list[Path], tmp_path: Path
                                                      ) -> None:
    """A worker inside its unit's transaction when its batch is killed, and left running
    (no pipe, no parent-death signal): its unit is refused, nothing recorded. On SQLite:
    the lease's check is the same SQL on both backends, tested on both below."""
    fleet = FLEETS["sqlite"](tmp_path)
    ready = tmp_path / "lease-id"
    # the batch: holds the lease until killed; its id renamed into place, never read empty
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time, pathlib\n"
         "from fogsf.fleet.lease import BatchLease\n"
         "with BatchLease(sys.argv[1]) as lease:\n"
         "    part = pathlib.Path(sys.argv[2] + '.part')\n"
         "    part.write_text(lease.id)\n"
         "    part.replace(sys.argv[2])\n"
         "    time.sleep(600)\n", fleet, str(ready)])
    marker = tmp_path / "in-transaction"
    worker = None
    try:
        wait_for(ready.exists, 60, "the lease was never taken")
        lease_id = ready.read_text()
        assert len(lease_id) == 32, f"not a whole lease id: {lease_id!r}"
        go = tmp_path / "go"  # the worker's transaction waits for the batch's death
        env = pause_in_add(tmp_path, marker, 120, go)
        worker = subprocess.Popen(
            [sys.executable, "-m", "fogsf", "fleet", "add", fleet, "--unit", "W1",
             "--train", str(logs[0]), "--workers", "1", *FAST, "--batch", lease_id],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wait_for(lambda: marker.exists() or worker.poll() is not None, 120,
                 "the worker never reached its transaction")
        holder.kill()  # the batch dies while the worker's unit is written, not committed
        holder.wait()
        go.write_text("")
        said = worker.communicate(timeout=60)[0]
    finally:
        for p in (holder, worker):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
    assert marker.exists(), f"the worker never paused in its transaction: {said}"
    # Refused because its batch's process died (its row still there), not for naming no
    # batch ("was stopped"): that refusal would pass here without testing the kill.
    assert worker.returncode == 2 and "is gone" in said and "not recorded" in said, said
    assert count_units(fleet) == (0, "ok"), said


@pytest.mark.parametrize("batch", ["", "64", "0" * 31])
def test_a_batch_id_no_lease_has_is_refused(batch: str, logs: list[Path], tmp_path: Path
                                            ) -> None:
    """`fleet add --batch ''` (or a batch size meant as `--batch-size`) names no batch:
    refused before training, never recorded as if no batch were given."""
    fleet = FLEETS["sqlite"](tmp_path)
    r = subprocess.run([sys.executable, "-m", "fogsf", "fleet", "add", fleet, "--unit", "E1",
                        "--train", str(logs[0]), "--workers", "1", *FAST, "--batch", batch],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    assert r.returncode == 2 and "names no batch" in r.stdout, r.stdout
    assert not Path(fleet).exists(), r.stdout  # refused before the fleet is opened


@pytest.mark.parametrize("make_fleet", fleet_urls())
def test_a_unit_lands_only_while_its_batch_runs(make_fleet, tmp_path: Path) -> None:
    fleet = make_fleet(tmp_path)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    with BatchLease(fleet) as lease, open_store(fleet) as store:
        store.add(fake_record("A1"), guard=lambda s: check_batch(s, lease.id))  # ours: lands
        rows = {  # id -> (host, pid, started, heartbeat age in s)
            "dead": (host_key(), dead.pid, "1", 0.0),  # a pid that no longer runs
            "reused": (host_key(), os.getpid(), "1", 0.0),  # our pid, another start
            "far-stale": ("another-host", 1, "1", 30.0),
            "far-fresh": ("another-host", 1, "1", 1.0),
        }
        with store.transaction():
            for bid, (host, pid, started, age) in rows.items():
                store.execute("INSERT INTO batches (id, host, pid, started, heartbeat) "
                              f"VALUES (?, ?, ?, ?, {store.now_sql} - ?)",
                              (bid, host, pid, started, age))
        for i, bid in enumerate(["dead", "reused", "far-stale", "gone"]):
            with pytest.raises(UserError, match="not recorded"):
                store.add(fake_record(f"B{i}"), guard=lambda s, b=bid: check_batch(s, b))
        store.add(fake_record("C1"), guard=lambda s: check_batch(s, "far-fresh"))
        assert [u.unit for u in store.units()] == ["A1", "C1"]
    with open_store(fleet, "read") as store:  # the lease's row went with the batch
        assert lease.id not in {r[0] for r in store.execute("SELECT id FROM batches")}


def _owned(base: Path, pid: int, start: str | None) -> Path:
    p = base / f"fogsf-{pid}-{start}"
    (p / "inner").mkdir(parents=True)
    return p


def test_sweep_removes_only_the_folders_of_gone_processes(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    me = os.getpid()
    gone = [_owned(tmp_path, dead.pid, "123"),  # its owner ended
            _owned(tmp_path, me, "1")]  # our pid, but another start: a reused pid
    kept = [_owned(tmp_path, me, scratch.start_time(me)),  # alive
            tmp_path / "fogsf-spill-abc", tmp_path / "fogsf-12-x", tmp_path / "other"]
    for k in kept[1:]:
        k.mkdir()
    assert sorted(scratch.sweep(tmp_path)) == sorted(gone)
    assert sorted(tmp_path.iterdir()) == sorted(kept)


@pytest.mark.slow
@pytest.mark.parametrize("command", ["add", "train"])
def test_a_killed_command_leaves_no_folder_after_the_next(command: str, logs: list[Path],
                                                          tmp_path: Path) -> None:
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    argv = {"add": ["fleet", "add", str(tmp_path / "f.fleet"), "--unit", "K1"],
            "train": ["train", "--out", str(tmp_path / "m")]}[command]
    env = dict(os.environ, TMPDIR=str(tmp))
    p = subprocess.Popen([sys.executable, "-m", "fogsf", *argv, "--train", str(logs[0]),
                          "--workers", "1", "--structure", "physics", "--iters", "400",
                          "--hysteresis", "off", "--no-progress"], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_for(lambda: any(tmp.iterdir()) or p.poll() is not None, 60, "no folder made")
        time.sleep(3.0)  # into its work (the logs read, training)
        assert p.poll() is None, p.stderr.read().decode() if p.stderr else ""
        made = sorted(x.name for x in tmp.iterdir())
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert [n for n in made if n.startswith(f"fogsf-{p.pid}-")], made
    subprocess.run([sys.executable, "-m", "fogsf", "--version"], env=env, check=True,
                   capture_output=True)
    assert not list(tmp.iterdir()), (made, sorted(x.name for x in tmp.iterdir()))


def test_a_process_folder_goes_at_exit(tmp_path: Path) -> None:
    code = ("import sys; from fogsf import scratch; p = scratch.process_dir(); "
            "(p / 'x').write_text('1'); print(p)")
    out = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, TMPDIR=str(tmp_path)),
                         capture_output=True, text=True, check=True).stdout.strip()
    assert Path(out).parent == tmp_path and not Path(out).exists()
