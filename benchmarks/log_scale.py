"""Logs of any length: wall time and peak memory of `fogsf replay`, `fogsf inspect`,
`fogsf train` (`--model poly` and the default), `fogsf diagnose` and `fogsf plan
--from-logs` on logs of 2.4 h, 24 h and 7 days at 100 Hz, CSV and Parquet, and how they grow
with the log. Each command runs --repeat times (2): its best wall time (the machine's other
load only ever adds) and its largest peak are reported.

Each log cycles -40..50 C at 1 C/min with 60 min soaks (the rig's columns: time, board
temperature, table rate, gyro, earth rate), written as CSV, then read back and written as
Parquet (the same numbers). Logs longer than a day are written in chunks: a simulated
TILE_H stretch (seed SEED) repeated with its time carried on (sample index / rate), so
that no more than the stretch is ever in memory (the 7-day log: 60 million rows, 2.2 GB of
CSV, on disk only while the bench runs). Each command runs in its own process: wall time,
and its peak resident memory (the kernel is compiled beforehand, so the build is not
counted). The model is a seeded random 1x16 LSTM at D = 10 (replay's cost does not depend
on its weights).

    python -m benchmarks.log_scale --out out/bench-scale.json      (make bench-scale)
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RATE_HZ = 100.0
SEED = 3
TILE_H = 10.0  # longer logs repeat a simulated stretch of two whole cycles
TILED_FROM_H = 24.0  # logs longer than this repeat a simulated stretch


def measured(cmd: list[str], repeat: int = 1) -> tuple[float, float]:
    """(best wall s, largest peak resident MB) of `repeat` runs of one command, each in its
    own process; it must succeed."""
    runs = [_measured_once(cmd) for _ in range(repeat)]
    return min(w for w, _ in runs), max(p for _, p in runs)


def _measured_once(cmd: list[str]) -> tuple[float, float]:
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
    from fogsf.logs.logio import read_log
    from fogsf.logs.writer import write_log
    from fogsf.models import samples

    model = samples.random_model(3, 4, 1, 16, decimation=10, seed=SEED)
    model.save(work / "model")
    build_kernel(model.at_rate(1.0 / RATE_HZ))  # cached: replay does not compile
    csv = work / f"log-{hours:g}h.csv"
    if hours <= TILED_FROM_H:
        write_log(csv, day_log(RATE_HZ, hours, SEED))
        write_log(csv.with_suffix(".parquet"), read_log(csv))
    else:
        write_tiled(csv, hours)


def write_tiled(csv: Path, hours: float) -> None:
    """A log of `hours` as CSV, then Parquet (the numbers the CSV holds), written in chunks:
    a TILE_H stretch repeated, time_s = sample index / RATE_HZ."""
    from benchmarks.sample_rate import day_log
    from fogsf.logs.read.arrow_csv import number_blocks
    from fogsf.logs.read.parquet_log import ParquetColumns
    from fogsf.logs.writer import write_rows

    tile = day_log(RATE_HZ, TILE_H, SEED).columns()
    names = list(tile)
    data = np.column_stack([np.asarray(tile[k], dtype=np.float64) for k in names])
    del tile
    per, total = data.shape[0], int(round(hours * 3600.0 * RATE_HZ)) + 1
    fmts = ["%.12g" if k == "time_s" else "%.10g" for k in names]
    with open(csv, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(names) + "\n")
        for a in range(0, total, per):
            rows = data[: min(per, total - a)].copy()
            rows[:, names.index("time_s")] = (a + np.arange(rows.shape[0])) / RATE_HZ
            write_rows(f, rows, fmts)
    with ParquetColumns(csv.with_suffix(".parquet"), dict.fromkeys(names, np.float64)) as w:
        for cols in number_blocks(csv, ",", len(names)):
            w.write(dict(zip(names, cols, strict=True)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-scale.json"))
    ap.add_argument("--hours", default="2.4,24,168",
                    help="log lengths in hours (2.4,24,168)")
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the logs and outputs (default: a temporary one)")
    ap.add_argument("--repeat", type=int, default=2,
                    help="runs of each command: the best wall time, the largest peak (2)")
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
                    "diagnose": [*fogsf, "diagnose", str(log), "--json",
                                 str(work / f"diag-{fmt}.json")],
                    "plan": [*fogsf, "plan", "--from-logs", str(log), "--hours", "2",
                             "--test-rates", "1", "--interval-gyros", "0", "--workers", "1",
                             "--out", str(work / f"plan-{fmt}")],
                    "train": [*fogsf, "train", "--train", str(log), "--model", "poly",
                              "--out", str(work / f"poly-{fmt}"), "--no-progress"],
                    "train-default": [*fogsf, "train", "--train", str(log), "--out",
                                      str(work / f"default-{fmt}"), "--no-progress"],
                }
                for command, cmd in runs.items():
                    wall, peak = measured(cmd, args.repeat)
                    rows.append({"hours": h, "format": fmt, "command": command,
                                 "file_mb": size_mb, "wall_s": wall, "peak_mb": peak})
                    print(f"{h:6g} h {fmt:8s} ({size_mb:7.1f} MB) {command:13s} "
                          f"{wall:6.2f} s  peak {peak:7.0f} MB", flush=True)
                (work / f"corrected.{fmt}").unlink(missing_ok=True)
                for d in ("poly", "default", "plan"):
                    shutil.rmtree(work / f"{d}-{fmt}", ignore_errors=True)
            for p in logs.values():
                p.unlink()
    growth = []
    for a, b in zip(hours[:-1], hours[1:], strict=True):
        for fmt in ("csv", "parquet"):
            for command in ("replay", "inspect", "train", "train-default", "diagnose",
                            "plan"):
                pair = [next((r for r in rows if r["hours"] == h and r["format"] == fmt
                              and r["command"] == command), None) for h in (a, b)]
                if pair[0] is None or pair[1] is None:
                    continue
                r0, r1 = pair
                g = {"from_hours": a, "to_hours": b, "format": fmt, "command": command,
                     "rows_ratio": b / a, "wall_ratio": r1["wall_s"] / r0["wall_s"],
                     "wall_vs_linear": r1["wall_s"] / r0["wall_s"] / (b / a),
                     "peak_ratio": r1["peak_mb"] / r0["peak_mb"]}
                growth.append(g)
                print(f"{b:g} h / {a:g} h, {fmt:8s} {command:8s}: wall x{g['wall_ratio']:.2f} "
                      f"({g['wall_vs_linear']:.2f} x linear), peak x{g['peak_ratio']:.2f} "
                      f"(rows x{b / a:g})")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rate_hz": RATE_HZ, "runs": rows, "growth": growth},
                                   indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
