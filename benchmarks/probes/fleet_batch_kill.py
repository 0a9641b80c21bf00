"""Probe: `fogsf fleet add-many` killed with SIGKILL, TRIALS times each way (its pid, its
process group), on SQLite and, when a server is at hand, PostgreSQL: processes of the batch
alive 2 s and 10 s after the kill, units landing after it, temporary folders left after the
next command, the fleet's integrity check (tests/fleet_kill.py runs each trial).

    python -m benchmarks.probes.fleet_batch_kill --trials 10 [--no-postgres]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from tests.fleet_kill import kill_trial, make_logs
from tests.fleet_units import _fresh_pg_database, pg_server


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--no-postgres", action="store_true")
    args = ap.parse_args()
    root = Path(tempfile.mkdtemp(prefix="batch-kill-probe-"))
    logs = make_logs(root / "logs")
    backends = ["sqlite"] + ([] if args.no_postgres or pg_server() is None else ["postgresql"])
    try:
        for backend in backends:
            for how in ("pid", "group"):
                alive = landed = left = bad = 0
                for i in range(args.trials):
                    work = root / f"{backend}-{how}-{i}"
                    work.mkdir()
                    fleet = (str(work / "line.fleet") if backend == "sqlite"
                             else _fresh_pg_database(pg_server() or ""))
                    t = kill_trial(work, fleet, logs, how)
                    alive += bool(t.alive_soon or t.alive)
                    landed += t.later - t.at_kill
                    left += len(t.fogsf_left())
                    bad += t.integrity != "ok"
                    print(f"{backend} {how} {i}: {t.at_kill} -> {t.later} units, alive "
                          f"{len(t.alive_soon)}/{len(t.alive)} (2 s/10 s), temp folders "
                          f"{len(t.temp_before)} before the next command, {len(t.temp_after)} "
                          f"after, integrity {t.integrity}", flush=True)
                print(f"== {backend}, kill {how}: {args.trials} trials: trials with a process "
                      f"alive {alive}, units landed after the kill {landed}, temp folders "
                      f"left {left}, integrity failures {bad}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
