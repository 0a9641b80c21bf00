"""Any sample rate (issue 11, part 2): one model at 10, 100 and 1000 Hz, and a 24 h log at
100 Hz replayed through the C kernel for time and memory.

1. The default model (lag-lstm) is trained on the default gyro's paper run at 0.5 C/min,
   once from a 10 Hz log and once from a 100 Hz log of the same physics (seed 1; the rates
   differ only in their noise draws).
2. Both models run through the compiled C kernel (re-rated to each log's rate: the same 5 s
   model step) over the 1 C/min paper run (seed 2) simulated at 10, 100 and 1000 Hz: the SF
   error left, RMS over 100 s windows / the log's noise floor. A model that runs at any rate
   gives about the same figure at every rate.
3. A 24 h log at 100 Hz (8.64 million samples; the columns a rig writes: time, board
   temperature, table rate, gyro, earth rate) is written to CSV, then
   `fogsf replay MODEL LOG --out CORRECTED.csv` runs on it in a subprocess: wall time and
   peak memory (the kernel build is cached beforehand, so it is not counted). The parts
   (read, kernel, metrics, write) are timed in this process as well.

    python -m benchmarks.sample_rate --out out/bench-sample-rate.json      (make bench-rate)
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.logio import read_log
from fogsf.logs.measure.metrics import log_metrics
from fogsf.logs.writer import write_log
from fogsf.models.stream import StreamModel
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper
from fogsf.training.options import TrainOptions
from fogsf.training.train import run_training

RATES_HZ = (10.0, 100.0, 1000.0)
TRAIN_SEED, TEST_SEED, DAY_SEED = 1, 2, 3
DAY_H = 24.0
DAY_RATE_HZ = 100.0


def paper_log(ramp: float, seed: int, rate_hz: float) -> ChamberLog:
    cfg = paper(ramp, seed)
    cfg.dt_s = 1.0 / rate_hz
    return simulate(cfg).log


def day_log(rate_hz: float, hours: float, seed: int) -> ChamberLog:
    """Cycles -40..50 C at 1 C/min with 60 min soaks for `hours`, only the rig's columns."""
    cfg = paper(1.0, seed)
    cfg.dt_s = 1.0 / rate_hz
    cfg.profile.kind = "cycle"
    cfg.profile.start_c, cfg.profile.stop_c = -40.0, 50.0
    cfg.profile.soak_min = 60.0
    cfg.profile.total_s = hours * 3600.0
    log = simulate(cfg).log
    log.extra = {}
    return log


def kernel_rms(model: StreamModel, log: ChamberLog) -> dict:
    """The C kernel over `log` (model re-rated to its rate): RMS / floor after correction."""
    rated = model.at_rate(log.sample_dt_s)
    _, sf, flags = Kernel(rated, build_kernel(rated)).run(log.temp_c, log.gyro_dps)
    m = log_metrics(log, correction_ppm=sf.astype(np.float64))
    return {"rate_hz": log.sample_rate_hz, "decimation": rated.decimation,
            "model_id": rated.model_id, "rms_ppm": m["rms_ppm"],
            "floor_ppm": m["noise_floor_ppm"], "x_floor": m["rms_ppm"] / m["noise_floor_ppm"],
            "flagged_samples": int(np.count_nonzero(flags))}


def across_rates(work: Path) -> dict:
    out: dict = {}
    tests = {r: paper_log(1.0, TEST_SEED, r) for r in RATES_HZ}
    for train_hz in (10.0, 100.0):
        model_dir = work / f"model-{train_hz:g}hz"
        run_training(TrainOptions(model="lag-lstm", progress=False, transfer_check=False),
                     [paper_log(0.5, TRAIN_SEED, train_hz)], None, model_dir)
        model = StreamModel.load(model_dir)
        rows = [kernel_rms(model, tests[r]) for r in RATES_HZ]
        out[f"trained at {train_hz:g} Hz"] = rows
        print(f"model trained at {train_hz:g} Hz (D={model.decimation}), paper run 1 C/min "
              f"seed {TEST_SEED}, C kernel, RMS / floor:")
        for row in rows:
            print(f"  at {row['rate_hz']:6g} Hz (D={row['decimation']:5d}): "
                  f"{row['rms_ppm']:7.2f} ppm = {row['x_floor']:.2f} x the floor "
                  f"({row['floor_ppm']:.2f} ppm)")
    return out


def day_replay(work: Path, model_dir: Path) -> dict:
    log = day_log(DAY_RATE_HZ, DAY_H, DAY_SEED)
    path = work / "day.csv"
    write_log(path, log)
    size = path.stat().st_size
    del log
    model = StreamModel.load(model_dir).at_rate(1.0 / DAY_RATE_HZ)
    build_kernel(model)  # cached: the replay below does not compile
    cmd = [sys.executable, "-m", "fogsf", "replay", str(model_dir), str(path),
           "--out", str(work / "corrected.csv"), "--json", str(work / "replay.json")]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"replay failed:\n{proc.stderr}")
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    replay = json.loads((work / "replay.json").read_text())
    parts = {}
    t = time.perf_counter()
    log = read_log(path)
    parts["read_s"] = time.perf_counter() - t
    t = time.perf_counter()
    _, sf, _ = Kernel(model, build_kernel(model)).run(log.temp_c, log.gyro_dps)
    parts["kernel_s"] = time.perf_counter() - t
    t = time.perf_counter()
    log_metrics(log, correction_ppm=sf.astype(np.float64))
    parts["metrics_s"] = time.perf_counter() - t
    result = {"samples": replay["samples"], "hours": DAY_H, "rate_hz": DAY_RATE_HZ,
              "csv_mb": size / 1e6, "replay_wall_s": wall, "replay_peak_rss_mb": peak_mb,
              "after_rms_ppm": replay["after"]["rms_ppm"],
              "floor_ppm": replay["after"]["noise_floor_ppm"], **parts}
    print(f"{DAY_H:g} h at {DAY_RATE_HZ:g} Hz: {result['samples']} samples, "
          f"{result['csv_mb']:.0f} MB of CSV; `fogsf replay` {wall:.1f} s wall, peak "
          f"{peak_mb:.0f} MB (in-process: read {parts['read_s']:.1f} s, C kernel "
          f"{parts['kernel_s']:.1f} s, metrics {parts['metrics_s']:.1f} s)")
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-sample-rate.json"))
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the logs and models (default: a temporary one)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rates = across_rates(work)
        day = day_replay(work, work / "model-10hz")
    target = 60.0
    print(f"target: the 24 h 100 Hz replay under {target:g} s: "
          f"{'met' if day['replay_wall_s'] < target else 'NOT met'}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"across_rates": rates, "day_replay": day,
                                    "target_s": target}, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
