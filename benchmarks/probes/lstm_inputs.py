"""How many lag-bank features the default model's LSTM must read (development gyros only).

The default model (`lag-lstm` on the lag bank) carries the bank in its polynomial head and a
1 x 16 LSTM on what the bank leaves. Reading all F = 12 bank features, the LSTM's input
weights (4H x F) are a third of the model; three such models miss issue 11's 24 KB flash
target. This bench trains the default model with the LSTM reading z[0:N] (T first, then the
fastest lags) for several N on the same population gyros and protocols, and prints test
RMS / noise floor (median, p90, worst) per variant. A variant `N@S` trains with the seed
shifted by S, which measures the seed-to-seed noise of the same structure.

    python -m benchmarks.probes.lstm_inputs --n 8 --variants 12,12@1,1,3 --protocols a,b,e
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.population import PROTOCOLS, runs_for
from fogsf.gsa.executors import add_executor_options, executor_from_args, run_all


def parse_variant(text: str) -> tuple[int, int]:
    """'N' or 'N@S' -> (N, seed shift S)."""
    n, _, shift = text.partition("@")
    return int(n), int(shift or 0)


def bench_gyro(gyro_seed: int, variants: tuple[str, ...], protocols: tuple[str, ...]
               ) -> dict:
    """Every variant on every protocol for one development gyro."""
    import torch

    from fogsf.sim.population import gyro_for_seed
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    gyro = gyro_for_seed(gyro_seed)
    logs = runs_for(gyro, gyro_seed, protocols)
    out: dict = {"gyro_seed": gyro_seed, "gyro": gyro.scenario, "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for p in protocols:
            train_names, test_name = PROTOCOLS[p]
            case = {}
            for v in variants:
                n_in, shift = parse_variant(v)
                opts = TrainOptions(model="lag-lstm", seed=gyro_seed + shift, progress=False,
                                    workers=1, transfer_check=False, lstm_inputs=n_in)
                m, fitted = run_training(opts, [logs[r] for r in train_names],
                                         logs[test_name], Path(tmp) / f"{p}-{v}")
                after = m["test"]["after"]
                case[v] = {"ratio": after["rms_ppm"] / m["noise_floor_ppm"],
                           "rms_ppm": after["rms_ppm"], "params": m["params"],
                           "kept_least_squares_start": m["kept_least_squares_start"]}
            out["cases"][p] = case
    out["seconds"] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=8, help="development gyros (seeds 1..n)")
    ap.add_argument("--first", type=int, default=1, help="first development gyro seed")
    ap.add_argument("--variants", default="12,12@1,1,3",
                    help="comma-separated N or N@SEED_SHIFT: the LSTM reads z[0:N]")
    ap.add_argument("--protocols", default="a,b,e")
    ap.add_argument("--out", default="out/bench-lstm-inputs.json")
    add_executor_options(ap)
    args = ap.parse_args(argv)

    from fogsf.sim.population import seed_range

    seeds = list(range(args.first, args.first + args.n))
    dev = seed_range("dev")
    if any(s not in dev for s in seeds):
        ap.error(f"seeds {seeds[0]}..{seeds[-1]} leave the development range {dev}")
    variants = tuple(v for v in args.variants.split(",") if v)
    protocols = tuple(p for p in args.protocols.split(",") if p)
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        rows = run_all(ex, bench_gyro, seeds, variants, protocols, desc="gyros", unit="gyro")
    rows.sort(key=lambda r: r["gyro_seed"])
    summary: dict = {}
    print(f"test RMS / noise floor, default model (lag bank), development gyros "
          f"{seeds[0]}-{seeds[-1]}; the LSTM reads z[0:N] (N@S: seed + S)")
    print(f"{'protocol':>8} | " + " | ".join(f"{v:>19}" for v in variants))
    print(f"{'':>8} | " + " | ".join(f"{'median   p90  worst':>19}" for _ in variants))
    for p in protocols:
        cells = []
        for v in variants:
            r = np.array([g["cases"][p][v]["ratio"] for g in rows])
            stats = {"median": float(np.median(r)), "p90": float(np.percentile(r, 90)),
                     "worst": float(r.max())}
            summary[f"{p}/{v}"] = stats
            cells.append(f"{stats['median']:>6.2f} {stats['p90']:>5.2f} {stats['worst']:>6.2f}")
        print(f"{p:>8} | " + " | ".join(f"{c:>19}" for c in cells))
    base = variants[0]
    print(f"paired, per (gyro, protocol): ratio of each variant to {base}'s, median "
          "[p10, p90] (seed-shifted variants show the noise)")
    for v in variants[1:]:
        q = np.array([g["cases"][p][v]["ratio"] / g["cases"][p][base]["ratio"]
                      for g in rows for p in protocols])
        lo, hi = np.percentile(q, [10, 90])
        summary[f"paired/{v}"] = {"median": float(np.median(q)), "p10": float(lo),
                                  "p90": float(hi)}
        print(f"  {v:>6} / {base}: {np.median(q):.3f} [{lo:.3f}, {hi:.3f}]")
    params = {v: rows[0]["cases"][protocols[0]][v]["params"] for v in variants}
    print("parameters (torch): " + ", ".join(f"{v}: {n}" for v, n in params.items()))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    seconds = time.perf_counter() - t0
    out.write_text(json.dumps({"gyro_seeds": seeds, "variants": variants,
                               "protocols": protocols, "rows": rows, "summary": summary,
                               "params": params, "seconds": seconds}, indent=2) + "\n")
    print(f"-> {out} ({seconds:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
