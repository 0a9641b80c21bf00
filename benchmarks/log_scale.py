"""Logs of any length: wall time and peak memory of `fogsf replay` and `fogsf inspect` on
logs of 2.4 h and 24 h at 100 Hz, CSV and Parquet, and how they grow with the log.

Each log cycles -40..50 C at 1 C/min with 60 min soaks (the rig's columns: time, board
temperature, table rate, gyro, earth rate), written as CSV, then read back and written as
Parquet (the same numbers). Each command runs in its own process: wall time, and its peak
resident memory (the kernel is compiled beforehand, so the build is not counted). The model
is a seeded random 1x16 LSTM at D = 10 (replay's cost does not depend on its weights).
`--hours` takes other lengths (168: a week, 60 million rows, about 2.4 GB of CSV and as
much memory to simulate it).

    python -m benchmarks.log_scale --out out/bench-scale.json      (make bench-scale)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RATE_HZ = 100.0
SEED = 3


def measured(cmd: list[str]) -> tuple[float, float]:
    """(wall s, peak resident MB) of one command in its own process; it must succeed."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err}")
    return wall, usage.ru_maxrss / 1024.0


def prepare(work: Path, hours: float) -> None:
    """The model (its kernel compiled) and the CSV and Parquet logs of `hours` at RATE_HZ
    (the same numbers), in a process of their own: a child's peak memory counts its
    parent's at the time it starts, so the measuring process stays small."""
    from benchmarks.sample_rate import day_log
    from fogsf.bindings.kernel import build_kernel
    from fogsf.trainer.logs.logio import read_log, write_log
    from fogsf.trainer.models import samples

    model = samples.random_model(3, 4, 1, 16, decimation=10, seed=SEED)
    model.save(work / "model")
    build_kernel(model.at_rate(1.0 / RATE_HZ))  # cached: replay does not compile
    csv = work / f"log-{hours:g}h.csv"
    write_log(csv, day_log(RATE_HZ, hours, SEED))
    write_log(csv.with_suffix(".parquet"), read_log(csv))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-scale.json"))
    ap.add_argument("--hours", default="2.4,24", help="log lengths in hours (2.4,24)")
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the logs and outputs (default: a temporary one)")
    ap.add_argument("--prepare", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    hours = [float(h) for h in args.hours.split(",")]
    if args.prepare:
        prepare(args.work, hours[0])
        return 0
    fogsf = [sys.executable, "-m", "fogsf"]
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for h in hours:
            subprocess.run([sys.executable, "-m", "benchmarks.log_scale", "--prepare",
                            "--hours", f"{h:g}", "--work", str(work)], check=True)
            csv = work / f"log-{h:g}h.csv"
            logs = {"csv": csv, "parquet": csv.with_suffix(".parquet")}
            for fmt, log in logs.items():
                size_mb = log.stat().st_size / 1e6
                runs = {
                    "replay": [*fogsf, "replay", str(work / "model"), str(log), "--out",
                               str(work / f"corrected.{fmt}"), "--ref-sf", "1.0"],
                    "inspect": [*fogsf, "inspect", str(log), "--json"],
                }
                for command, cmd in runs.items():
                    wall, peak = measured(cmd)
                    rows.append({"hours": h, "format": fmt, "command": command,
                                 "file_mb": size_mb, "wall_s": wall, "peak_mb": peak})
                    print(f"{h:6g} h {fmt:8s} ({size_mb:7.1f} MB) {command:8s} "
                          f"{wall:6.2f} s  peak {peak:7.0f} MB", flush=True)
                (work / f"corrected.{fmt}").unlink(missing_ok=True)
            for p in logs.values():
                p.unlink()
    growth = []
    if len(hours) >= 2:
        a, b = hours[0], hours[-1]
        for fmt in ("csv", "parquet"):
            for command in ("replay", "inspect"):
                r0, r1 = (next(r for r in rows if r["hours"] == h and r["format"] == fmt
                               and r["command"] == command) for h in (a, b))
                g = {"format": fmt, "command": command, "rows_ratio": b / a,
                     "wall_ratio": r1["wall_s"] / r0["wall_s"],
                     "peak_ratio": r1["peak_mb"] / r0["peak_mb"]}
                growth.append(g)
                print(f"{b:g} h / {a:g} h, {fmt:8s} {command:8s}: wall x{g['wall_ratio']:.2f}, "
                      f"peak x{g['peak_ratio']:.2f} (rows x{b / a:g})")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rate_hz": RATE_HZ, "runs": rows, "growth": growth},
                                   indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
