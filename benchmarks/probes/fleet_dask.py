"""`fogsf fleet add-many` on a Dask cluster of local workers, the fleet on PostgreSQL: wall
time of whole batches of N units (and the same batch in local processes, `--workers`, for
comparison). Each unit is a real `fleet add`: a 0.5 h simulated log at 1 Hz, trained with
tests/fleet_kill.py's FAST options (physics nodes, 100 LSTM iterations); units cycle over 3
logs. The cluster: `distributed.LocalCluster`, WORKERS processes of one thread each, its
scheduler on a local TCP port; the server: tests/fleet_units.py's (FOGSF_TEST_POSTGRES_URL,
or Debian's postgresql started in a temporary folder).

    python -m benchmarks.probes.fleet_dask --sizes 10,100 --workers 2 [--local]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.fleet_kill import FAST, count_units, make_logs
from tests.fleet_units import _fresh_pg_database, pg_server


def batch(fleet: str, manifest: Path, how: list[str]) -> tuple[float, str]:
    """(seconds, the batch's last line) of `fogsf fleet add-many FLEET MANIFEST HOW...`."""
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "fogsf", "fleet", "add-many", fleet,
                          str(manifest), "--no-progress", "--train-options", FAST, *how],
                         capture_output=True, text=True)
    dt = time.perf_counter() - t0
    last = (run.stdout.strip().splitlines() or [""])[-1]
    if run.returncode != 0:
        raise SystemExit(f"add-many failed ({run.returncode}): {run.stdout[-1500:]}"
                         f"{run.stderr[-1500:]}")
    return dt, last


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,100")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--local", action="store_true",
                    help="also each batch in local processes (--workers N)")
    ap.add_argument("--out", default="out/fleet-dask.json")
    a = ap.parse_args(argv)
    server = pg_server()
    if server is None:
        raise SystemExit("no PostgreSQL server (Debian's postgresql, or FOGSF_TEST_POSTGRES_URL)")
    from distributed import LocalCluster

    rows = []
    with tempfile.TemporaryDirectory(prefix="fleet-dask-") as t, \
            LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                         host="127.0.0.1", dashboard_address=None) as cluster:
        tmp = Path(t)
        logs = make_logs(tmp / "logs")
        for n in (int(x) for x in a.sizes.split(",")):
            manifest = tmp / f"units-{n}.csv"
            manifest.write_text("unit,train\n" + "".join(
                f"SN{i:04d},{logs[i % len(logs)]}\n" for i in range(n)))
            ways = [("dask", ["--dask", cluster.scheduler_address])]
            ways += [("local", ["--workers", str(a.workers)])] if a.local else []
            for name, how in ways:
                fleet = _fresh_pg_database(server)
                dt, last = batch(fleet, manifest, how)
                row = {"units": n, "run": name, "workers": a.workers, "seconds": round(dt, 1),
                       "per_unit_s": round(dt / n, 2), "recorded": count_units(fleet)[0],
                       "said": last}
                print(json.dumps(row), file=sys.stderr, flush=True)
                rows.append(row)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(rows, indent=2) + "\n")
    print("| units | run | workers | wall time | per unit | recorded |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['units']} | {r['run']} | {r['workers']} | {r['seconds']:.0f} s | "
              f"{r['per_unit_s']:.1f} s | {r['recorded']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
