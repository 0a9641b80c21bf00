"""Simulator speed and paper calibration: `python -m benchmarks.sim_paper [--out FILE.json]`.

Times a 3-hour (0.5 C/min) paper run (simulate, write the CSV), and measures the paper
scenario's metrics over seeds at both ramp rates against the paper's 835.1 / 450.24 ppm.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from fogsf.logs.measure.metrics import log_metrics
from fogsf.logs.writer import write_log
from fogsf.sim import simulate
from fogsf.sim.scenarios import PAPER_TARGET_MAX_PPM, PAPER_TARGET_RMS_PPM, paper


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/bench-sim.json")
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args(argv)

    cfg = paper(0.5, seed=0)
    t0 = time.perf_counter()
    res = simulate(cfg)
    t_sim = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        write_log(Path(d) / "run.csv", res.log)
        t_write = time.perf_counter() - t0
    print(f"3-hour run ({len(res.log)} samples): simulate {t_sim:.3f} s, write CSV "
          f"{t_write:.3f} s")

    out: dict = {"samples": len(res.log), "simulate_s": t_sim, "write_csv_s": t_write,
                 "target": {"max_abs_ppm": PAPER_TARGET_MAX_PPM,
                            "rms_ppm": PAPER_TARGET_RMS_PPM}, "rates": {}}
    for rate in (1.0, 0.5):
        ms = [log_metrics(simulate(paper(rate, seed=s)).log) for s in range(args.seeds)]
        row = {k: [m[k] for m in ms] for k in ("max_abs_ppm", "rms_ppm", "noise_floor_ppm")}
        out["rates"][str(rate)] = row
        mx, rms, nf = (np.asarray(row[k]) for k in ("max_abs_ppm", "rms_ppm",
                                                     "noise_floor_ppm"))
        print(f"{rate:g} C/min over {args.seeds} seeds: max|e| {mx.mean():.1f} "
              f"({mx.min():.1f}..{mx.max():.1f}) ppm, RMS {rms.mean():.1f} "
              f"({rms.min():.1f}..{rms.max():.1f}) ppm, noise floor {nf.mean():.2f} ppm")
        if rate == 1.0:
            dev = max(np.max(np.abs(mx / PAPER_TARGET_MAX_PPM - 1)),
                      np.max(np.abs(rms / PAPER_TARGET_RMS_PPM - 1)))
            out["worst_rel_dev_1c"] = float(dev)
            print(f"  worst deviation from the paper's 835.1 / 450.24 ppm: {dev * 100:.2f} %")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
