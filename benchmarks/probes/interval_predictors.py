"""What predicts the error a trained model leaves on an untrained test log: candidates for the
rate-transfer interval's upper end, calibrated for 90 % coverage.

For each gyro and protocol of `benchmarks.population` (least squares: the default's
structure chosen by `training.structure.choice`, no LSTM), it records the test RMS the model
leaves, the test's noise floor, and predictors computed without the test's gyro output:
- quantiles of the distance from the model to the lag models consistent with the training
  logs (`transfer.target_spreads`; the interval uses the largest);
- the distance from the model to each other structure candidate fitted to the same logs
  (their disagreement on the test's temperatures);
- the held-out score of the chosen structure (the structure choice's).
Then, per predictor P, the K that puts 90 % of the cases inside hypot(floor, K P) and what
that interval gives: coverage and the median of its upper end over the actual error, per
protocol. Run it on development gyros (the interval is calibrated there):

    python -m benchmarks.probes.interval_predictors --first 1 --n 48 --out out/ip-dev.json
    python -m benchmarks.probes.interval_predictors --analyse out/ip-dev.json
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from benchmarks.population import protocol_logs
from benchmarks.probes import finish
from fogsf.logs.measure.metrics import log_metrics
from fogsf.sim.population import DEV_SEEDS, gyro_for_seed
from fogsf.training.interval.transfer import target_spreads
from fogsf.training.structure.choice import CANDIDATES, choose
from fogsf.training.structure.heldout import candidate_compensations, heldout_score

QUANTILES = (50, 75, 90, 100)
EXTRA = ("chain1", "chain2")  # more structures for the disagreement (`cand_max_extra`)
COVERAGE = 0.9


def gyro_cases(seed: int, protocols: tuple[str, ...]) -> list[dict]:
    gyro = gyro_for_seed(seed)
    rows = []
    for p in protocols:
        train, test = protocol_logs(gyro, seed, p)
        choice = choose(train)
        sd, comp = candidate_compensations(CANDIDATES + EXTRA, train)
        preds = {c: f(test) for c, f in comp.items()}
        pred = preds[choice.name]
        m = log_metrics(test, correction_ppm=pred)
        ts = target_spreads(train, test, prediction_ppm=pred)
        dist = {c: ts.distance(preds[c]) for c in CANDIDATES if c != choice.name}
        row = {"seed": seed, "p": p, "chosen": choice.name, "rms": m["rms_ppm"],
               "floor": m["noise_floor_ppm"], "consistent": int(ts.model_spread.size),
               "heldout": choice.scores.get(choice.name) or heldout_score(choice.name, sd)}
        for q in QUANTILES:
            row[f"lag_q{q}"] = float(np.percentile(ts.model_spread, q))
        row["cand_max"] = max(dist.values())
        row["cand_median"] = float(np.median(list(dist.values())))
        row["cand_max_extra"] = max(ts.distance(preds[c]) for c in CANDIDATES + EXTRA
                                    if c != choice.name)
        rows.append(row)
        print(seed, p, {k: round(v, 1) if isinstance(v, float) else v for k, v in row.items()},
              flush=True)
    return rows


PREDICTORS = tuple(f"lag_q{q}" for q in QUANTILES) + ("cand_max", "cand_median", "heldout",
                                                       "cand_max_extra")


def analyse(rows: list[dict], coverage: float = COVERAGE) -> None:
    rms = np.array([r["rms"] for r in rows])
    floor = np.array([r["floor"] for r in rows])
    excess = np.sqrt(np.maximum(rms**2 - floor**2, 0.0))
    prot = np.array([r["p"] for r in rows])
    for name in PREDICTORS:
        pv = np.array([r.get(name, np.nan) for r in rows], dtype=np.float64)
        if not np.all(np.isfinite(pv)):
            continue
        k = float(np.percentile(excess / np.maximum(pv, 1e-9), 100 * coverage))
        hi = np.hypot(floor, k * pv)
        inside = (0.8 * floor <= rms) & (rms <= hi)
        cells = []
        for p in sorted(set(prot)):
            s = prot == p
            cells.append(f"({p}) {np.median(hi[s] / rms[s]):.2f}x {inside[s].sum()}/{s.sum()}")
        print(f"{name:12s} K {k:7.2f}  inside {inside.sum()}/{inside.size}  upper/actual "
              f"median: " + ", ".join(cells))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--protocols", default="a,b,c,d,e")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None)
    ap.add_argument("--analyse", default=None, help="a JSON this probe wrote: analyse only")
    args = ap.parse_args(argv)
    if args.analyse:
        with open(args.analyse) as fh:
            analyse(json.load(fh))
        return 0
    seeds = list(range(args.first, args.first + args.n))
    assert all(s in DEV_SEEDS or s >= 20000 for s in seeds)
    protocols = tuple(args.protocols.split(","))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as ex:
        rows = [r for part in ex.map(gyro_cases, seeds, [protocols] * len(seeds))
                for r in part]
    analyse(rows)
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
