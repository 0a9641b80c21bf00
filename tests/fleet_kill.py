"""A killed `fogsf fleet add-many`, as an operator's terminal, CI or the OOM killer kills
it: the batch started for real, SIGKILL to its pid or its process group once a unit landed,
then what is left (processes, units landing later, temporary folders after the next
command). Shared by tests/test_fleet_batch_kill.py and benchmarks/probes/fleet_batch_kill.py."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

# A unit: 3-4 s of CPU (most of it starting fogsf); the kill comes AFTER_FIRST_S after the
# first unit landed, while the next units run.
FAST = "--structure physics --iters 100 --hysteresis off --no-progress"
AFTER_FIRST_S = 2.0
UNITS = 6
WORKERS = 2
ALIVE_SOON_S = 2.0  # a worker dies this soon after its batch


def make_logs(folder: Path, n: int = 3) -> list[Path]:
    """n short simulated chamber logs (0.5 h at 1 Hz: a unit trains in about a second)."""
    folder.mkdir(parents=True, exist_ok=True)
    logs = []
    for i in range(n):
        p = folder / f"r{i}.csv"
        if not p.exists():
            subprocess.run([sys.executable, "-m", "fogsf", "simulate", "--scenario", "paper",
                            "--ramp-rate", "2", "--seed", str(i + 1), "--start-c", "-20",
                            "--stop-c", "40", "--sample-rate-hz", "1", "--out", str(p)],
                           check=True, capture_output=True)
        logs.append(p)
    return logs


def count_units(fleet: str) -> tuple[int, str]:
    """(units, what the integrity checks said: "ok" or the first fault)."""
    if fleet.startswith("postgres"):
        import psycopg

        with psycopg.connect(fleet, autocommit=True) as db:
            n = db.execute("SELECT count(*) FROM units").fetchone()[0]
            bare = db.execute("SELECT count(*) FROM units u WHERE NOT EXISTS "
                              "(SELECT 1 FROM logs l WHERE l.sn = u.sn)").fetchone()[0]
        return int(n), "ok" if bare == 0 else f"{bare} unit(s) without logs"
    import sqlite3

    db = sqlite3.connect(f"file:{fleet}?mode=ro", uri=True)
    try:
        n = db.execute("SELECT count(*) FROM units").fetchone()[0]
        check = db.execute("PRAGMA integrity_check").fetchone()[0]
        bare = db.execute("SELECT count(*) FROM units u WHERE NOT EXISTS "
                          "(SELECT 1 FROM logs l WHERE l.sn = u.sn)").fetchone()[0]
    finally:
        db.close()
    return int(n), check if check != "ok" else ("ok" if bare == 0 else
                                                f"{bare} unit(s) without logs")


def processes_of(marker: str) -> list[str]:
    """Live processes (zombies are gone) whose command line holds `marker`."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (d / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if marker in cmd and state not in ("Z", "X"):
            found.append(f"{d.name} {cmd.strip()[:160]}")
    return found


@dataclass
class Trial:
    """What one kill left: units when killed and 10 s later, processes alive, temporary
    folders before and after the next command, the integrity check, the batch's output."""

    at_kill: int = -1
    later: int = -1
    alive_soon: list[str] = field(default_factory=list)  # ALIVE_SOON_S after the kill
    alive: list[str] = field(default_factory=list)
    temp_before: list[str] = field(default_factory=list)
    temp_after: list[str] = field(default_factory=list)
    integrity: str = ""
    output: str = ""

    def fogsf_left(self) -> list[str]:
        return [n for n in self.temp_after if n.startswith("fogsf-")]

    def __str__(self) -> str:
        return (f"units at kill {self.at_kill}, 10 s later {self.later}; alive after "
                f"{ALIVE_SOON_S:g} s {self.alive_soon}, after 10 s {self.alive}; "
                f"temp before the next command {self.temp_before}, after {self.temp_after}; "
                f"integrity {self.integrity}; batch said:\n{self.output[-2000:]}")


def kill_trial(work: Path, fleet: str, logs: list[Path], how: str, wait_s: float = 10.0
               ) -> Trial:
    """Start add-many (UNITS units, WORKERS workers) on `fleet` with TMPDIR work/tmp, SIGKILL
    it (`how`: "pid" or "group") AFTER_FIRST_S after its first unit landed, and see what is
    left."""
    tmp = work / "tmp"
    tmp.mkdir(parents=True, exist_ok=True)
    manifest = work / "units.csv"
    manifest.write_text("unit,train\n" + "".join(
        f"K{i},{logs[i % len(logs)]}\n" for i in range(UNITS)))
    env = dict(os.environ, TMPDIR=str(tmp))
    out = work / "batch.out"
    t = Trial()
    with open(out, "wb") as f:
        batch = subprocess.Popen(
            [sys.executable, "-m", "fogsf", "fleet", "add-many", fleet, str(manifest),
             "--workers", str(WORKERS), "--no-progress", "--train-options", FAST],
            env=env, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            t_end = time.monotonic() + 120
            while batch.poll() is None and time.monotonic() < t_end:
                try:
                    if count_units(fleet)[0] >= 1:
                        time.sleep(AFTER_FIRST_S)
                        break
                except Exception:  # noqa: BLE001 - the fleet not made yet
                    pass
                time.sleep(0.05)
            if batch.poll() is None:
                if how == "group":
                    os.killpg(batch.pid, signal.SIGKILL)
                else:
                    os.kill(batch.pid, signal.SIGKILL)
            batch.wait()
            t.at_kill = count_units(fleet)[0]
        finally:
            if batch.poll() is None:
                batch.kill()
    marker = fleet  # in the command line of the batch and of each of its workers
    killed = time.monotonic()
    time.sleep(ALIVE_SOON_S)
    t.alive_soon = processes_of(marker)
    time.sleep(max(0.0, killed + wait_s - time.monotonic()))
    t.alive = processes_of(marker)
    t.later, t.integrity = count_units(fleet)
    t.temp_before = sorted(os.listdir(tmp))
    subprocess.run([sys.executable, "-m", "fogsf", "fleet", "list", fleet], env=env,
                   capture_output=True, check=True)  # the next command
    t.temp_after = sorted(os.listdir(tmp))
    t.output = out.read_text(errors="replace")
    for line in processes_of(marker):  # the test's own mess is not left for the next one
        os.kill(int(line.split()[0]), signal.SIGKILL)
    return t
