"""Can the LSTM learn lags as long as a gyro's slowest part? (development gyros only)

lag-lstm with one effective node (`--structure node`: the LSTM must learn every other lag)
and with the lag bank (the default: the lags are in the bank), trained on random windows
of 256 model steps (21 min, the default) or on whole logs (truncated BPTT over the whole
log from the zero state firmware starts from), on protocol (e) of the population bench
(one loop 1 up / 2 down C/min with 30 min soaks, tested on 1 up / 1.5 down) and (b).
Prints test RMS / noise floor per gyro and median / worst.

    python -m benchmarks.probes.lstm_window --first 1 --n 6 --out out/lstm-window.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.population import protocol_logs
from fogsf.gsa.executors import add_executor_options, executor_from_args, run_all
from fogsf.sim.population import DEV_SEEDS

VARIANTS = {"node/256": ("node", 256), "node/whole": ("node", 100_000),
            "bank/256": ("bank", 256), "bank/whole": ("bank", 100_000)}


def one_gyro(seed: int, protocols: tuple[str, ...]) -> dict:
    import torch

    from fogsf.sim.population import gyro_for_seed
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    torch.set_num_threads(1)
    gyro = gyro_for_seed(seed)
    out: dict = {"gyro_seed": seed}
    with tempfile.TemporaryDirectory() as tmp:
        for p in protocols:
            train, test = protocol_logs(gyro, seed, p)
            for name, (structure, window) in VARIANTS.items():
                t0 = time.perf_counter()
                opts = TrainOptions(model="lag-lstm", seed=seed, progress=False, workers=1,
                                    transfer_check=False, structure=structure,
                                    lstm_window=window)
                m, _ = run_training(opts, train, test,
                                    Path(tmp) / f"{p}-{name.replace('/', '-')}")
                out[f"{p}:{name}"] = {"ratio": m["test"]["after"]["rms_ppm"]
                                      / m["noise_floor_ppm"],
                                      "kept_start": m["kept_least_squares_start"],
                                      "seconds": time.perf_counter() - t0}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--protocols", default="e,b")
    ap.add_argument("--out", default="out/lstm-window.json")
    add_executor_options(ap)
    args = ap.parse_args(argv)
    seeds = list(range(args.first, args.first + args.n))
    if any(s not in DEV_SEEDS for s in seeds):
        ap.error("development seeds only")
    protocols = tuple(p for p in args.protocols.split(",") if p)
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        rows = run_all(ex, one_gyro, seeds, protocols, desc="gyros", unit="gyro")
    keys = [f"{p}:{v}" for p in protocols for v in VARIANTS]
    for r in rows:
        print(f"gyro {r['gyro_seed']:>4} " + " ".join(f"{k} {r[k]['ratio']:.2f}"
                                                     + ("*" if r[k]["kept_start"] else "")
                                                     for k in keys))
    summary = {}
    for k in keys:
        v = np.array([r[k]["ratio"] for r in rows])
        secs = np.median([r[k]["seconds"] for r in rows])
        kept = sum(r[k]["kept_start"] for r in rows)
        summary[k] = {"median": float(np.median(v)), "worst": float(v.max()),
                      "train_seconds_median": float(secs), "kept_start": kept}
        print(f"{k:<14} median {np.median(v):.2f} worst {v.max():.2f}  "
              f"(train {secs:.0f} s, least-squares start kept on {kept}/{len(rows)})")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"seeds": seeds, "rows": rows, "summary": summary},
                                         indent=1))
    print(f"* = the least-squares start was kept; -> {args.out} "
          f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
