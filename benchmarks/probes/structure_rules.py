"""How the default model's structure was chosen: candidate rules on population gyros.

Least squares only (no LSTM), so it runs in minutes. For each gyro and protocol of
`benchmarks.population` it prints the test RMS as a multiple of the test log's noise floor
for these rules (all fitted on the protocol's training logs, scored on its test log):

  node1        one effective node with a cubic, profiled (the previous default)
  best12       the best-fitting plausible lag model with one or two nodes
  consistent   the mean prediction of every plausible lag model that fits as well as the
               best (the rate-transfer check's set)
  oracle       the lag model (one or two nodes) best ON THE TEST LOG: what perfect
               selection within that family would reach (not a method)
  bank:LAM     the lag bank (models.structures.lag_bank: T and the lags up to 2000 s as cubics, the
               slower lags linear) with a fixed ridge prior LAM (1e-3 is the default)
  bank:allcubic  every lag as a cubic, prior 1e-3
  bank:gcv     every lag as a cubic, the penalty chosen by GCV

Run it on development seeds only (the choice it informs is tuned there):

    python -m benchmarks.probes.structure_rules --first 1 --n 24 --protocols a,b,c,d,e
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.population import protocol_logs
from fogsf.logs.measure.metrics import log_metrics
from fogsf.models.features import MODEL_STEP_S, front_end_for, prepare
from fogsf.models.reference import expand
from fogsf.models.structures.lag_bank import BANK_LAMBDA, bank_design, bank_spec, fit_bank, n_curved
from fogsf.models.structures.least_squares import (
    TAU_GRID_S,
    fit_candidates,
    grid_data,
    node_candidates,
)
from fogsf.sim.population import DEV_SEEDS, gyro_for_seed
from fogsf.training.inputs import bank_data, training_inputs
from fogsf.training.interval.transfer import CHI2_ALLOWANCE, long_run_ratio
from fogsf.training.options import TrainOptions

BANK_LAMBDAS = (1e-4, 1e-3, 1e-2)
GCV_GRID = tuple(float(x) for x in np.geomspace(1e-8, 1e2, 41))


def ratio(log, steps: np.ndarray) -> float:  # noqa: ANN001 - a ChamberLog
    m = log_metrics(log, correction_ppm=expand(steps, len(log), 50))
    return m["rms_ppm"] / m["noise_floor_ppm"]


def lag_family_rules(train: list, test) -> dict[str, np.ndarray]:  # noqa: ANN001
    fe = front_end_for([*train, test], MODEL_STEP_S, ())
    data, y = grid_data(train, fe, TAU_GRID_S, None)
    (td,), _ = grid_data([test], fe, TAU_GRID_S, None)
    s = np.concatenate([d.s for d in data])
    one = fit_candidates(node_candidates(1), s, y)
    every = one + fit_candidates(node_candidates(2), s, y)
    pool1 = [f for f in one if f.plausible] or one
    pool = [f for f in every if f.plausible] or every
    b1 = min(pool1, key=lambda f: f.sse)
    b = min(pool, key=lambda f: f.sse)
    infl = long_run_ratio(y - b.cand.design(s) @ b.coef, [d.n_steps for d in data])
    var = b.sse / max(1, y.size - 6)
    ok = [f for f in pool if f.sse <= b.sse + CHI2_ALLOWANCE * var * infl]
    err = [float(np.mean((f.cand.design(td.s) @ f.coef - td.target_ppm) ** 2)) for f in every]
    o = every[int(np.argmin(err))]
    return {"node1": b1.cand.design(td.s) @ b1.coef, "best12": b.cand.design(td.s) @ b.coef,
            "consistent": np.mean([f.cand.design(td.s) @ f.coef for f in ok], axis=0),
            "oracle": o.cand.design(td.s) @ o.coef}


def _gcv_lambda(z: np.ndarray, y: np.ndarray) -> float:
    x = bank_design(z)
    xc = x - x.mean(axis=0)
    u, sv, _ = np.linalg.svd(xc, full_matrices=False)
    uy = u.T @ (y - y.mean())
    rest = float(np.sum((y - y.mean()) ** 2) - np.sum(uy**2))
    scale, n = float(np.mean(sv**2)), y.size
    scores = []
    for lam in GCV_GRID:
        f = sv**2 / (sv**2 + lam * scale)
        rss = rest + float(np.sum(((1 - f) * uy) ** 2))
        scores.append(rss / max(1e-12, 1 - (f.sum() + 1) / n) ** 2)
    return GCV_GRID[int(np.argmin(scores))]


def bank_inputs(train: list, test) -> tuple:  # noqa: ANN001 - ChamberLogs
    """(ti, z, y, zt): the default model's bank inputs as `inputs.fit_bank_head` builds them
    (normalised features z and targets y of every training step) and the test log's z."""
    ti = training_inputs(TrainOptions(model="lag-lstm"), train, bank_spec(), physical=True)
    z, y = bank_data(ti)
    return ti, z, y, ti.norm.apply(prepare(test, ti.fe, None, None).s)


def bank_rules(train: list, test) -> dict[str, np.ndarray]:  # noqa: ANN001
    ti, z, y, zt = bank_inputs(train, test)

    def pred(lam: float, curved: int | None) -> np.ndarray:
        return fit_bank(z, y, lam, curved).predict(zt) * ti.scale + ti.offset

    out = {f"bank:{lam:g}": pred(lam, n_curved()) for lam in BANK_LAMBDAS}
    out["bank:allcubic"] = pred(BANK_LAMBDA, None)
    out["bank:gcv"] = pred(_gcv_lambda(z, y), None)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.probes.structure_rules --first 1 --n 4 "
               "--protocols a,b")
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--protocols", default="a,b,c,d,e")
    ap.add_argument("--out", default="out/structure-rules.json")
    args = ap.parse_args(argv)
    seeds = range(args.first, args.first + args.n)
    if any(s not in DEV_SEEDS for s in seeds):
        ap.error(f"structure rules are compared on development seeds only ({DEV_SEEDS})")
    protocols = [p for p in args.protocols.split(",") if p]
    t0 = time.perf_counter()
    table: dict[str, dict[str, list[float]]] = {}
    for seed in seeds:
        gyro = gyro_for_seed(seed)
        for p in protocols:
            train, test = protocol_logs(gyro, seed, p)
            preds = {**lag_family_rules(train, test), **bank_rules(train, test)}
            row = {k: ratio(test, v) for k, v in preds.items()}
            for k, v in row.items():
                table.setdefault(p, {}).setdefault(k, []).append(v)
            print(f"gyro {seed:>4} {p} " + " ".join(f"{k} {v:.2f}" for k, v in row.items()),
                  flush=True)
    print(f"test RMS / noise floor, development gyros {seeds.start}-{seeds.stop - 1}: "
          "median / p90 / worst")
    rules = list(next(iter(table.values())))
    print(f"{'':>3} " + " ".join(f"{r:>17}" for r in rules))
    summary: dict = {}
    for p in protocols:
        cells = []
        for r in rules:
            v = np.asarray(table[p][r])
            s = (float(np.median(v)), float(np.percentile(v, 90)), float(v.max()))
            summary.setdefault(p, {})[r] = s
            cells.append(f"{s[0]:5.2f} {s[1]:5.2f} {s[2]:5.1f}")
        print(f"{p:>3} " + " ".join(f"{c:>17}" for c in cells))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"seeds": [seeds.start, seeds.stop - 1], "table": table,
                               "summary": summary}, indent=2) + "\n")
    print(f"-> {out} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
