"""Can the training logs tell the time constants that transfer from those that do not?

For each gyro, the physics structure of `--structure physics` (2 or 3 first-order lags of T,
their quadratic with cross terms and the cube of T, ridge at `NODE_LAMBDA`) is fitted on the
protocol's training logs at every combination of the lag bank's grid time constants, least
squares as `fogsf train` fits it, and scored on the test log (test RMS / noise floor):
- `ident`: the time constants variable projection identifies (what `fogsf train --structure
  physics --nodes K` trains);
- `train`: the grid combination with the least training sum of squares;
- `parts`: the grid combination that predicts the training logs' held-out parts best (each
  ramp in three parts, as `fogsf train`'s structure choice holds them out);
- `test`: the grid combination best on the test itself (no method has it: the most the
  family reaches with the time constants the test would pick);
- `dchi2`: how much worse `test`'s combination fits the training logs than the best fit
  does (the best grid combination or `ident`, whichever fits better), in units of the
  residual variance (SSE_min / (n - p), n model steps, p the structure's coefficients; the
  ridge's effective degrees of freedom and the K time constants are left out, negligible
  with thousands of steps): under the chi-square 95 % point of K parameters (5.99 for 2,
  7.81 for 3), the training logs cannot tell the two apart even with white noise;
- `bank`: the lag bank at its prior, and `mix`: the mean of the bank's and `train`'s
  predictions (a two-structure average).
`--partial` runs the partial-cycle programs of `make bench-hysteresis` instead of the
protocols, on its gyros that draw a play with the play taken out (its "same-flat" group: the
structure alone, no hysteresis term).

    python -m benchmarks.probes.tau_information --first 1 --n 24 --protocols b,e
    python -m benchmarks.probes.tau_information --partial --first 1 --n 12
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks.probes import StepScorer, finish, spread_cells
from benchmarks.probes.sf_oracle import Run, partial_case, protocol_cases
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.physics_nodes import fit_coefficients, identify_taus, node_design
from fogsf.training.structure import heldout as sh

CHI2_95 = {2: 5.99, 3: 7.81}  # the chi-square 95 % points of 2 and 3 parameters


def score(train: list[Run], test: Run, nodes: tuple[int, ...]) -> dict:
    """`ident`, `train`, `parts`, `test` and `dchi2` per node count, `bank` and `mix`."""
    sd = sh.step_data([r.log for r, _ in train])
    by_parts = dataclasses.replace(sd, fold=sh.part_folds(sd))
    on_test = StepScorer.of(test[0].log, sd.fe)
    nt = on_test.nt

    def fitted(taus: tuple[float, ...]) -> tuple[float, float, np.ndarray]:
        z = sd.nodes.z(taus)
        f = fit_coefficients(z, sd.y, taus)
        p = f.predict(nt.z(taus))
        return float(np.sum((f.predict(z) - sd.y) ** 2)), on_test(p), p

    def fit_at(taus: tuple[float, ...]) -> Callable[[sh.StepData, np.ndarray], sh.Predictor]:
        def fit(s: sh.StepData, rows: np.ndarray) -> sh.Predictor:
            f = fit_coefficients(s.nodes.z(taus)[rows], s.y[rows], taus)
            return lambda nt: f.predict(nt.z(taus))
        return fit

    out: dict = {}
    bank = sh.fit_candidate("bank", sd, np.arange(sd.y.size))(nt)
    out["bank"] = on_test(bank)
    for k in nodes:
        ident = identify_taus(sd.nodes, sd.y, k)
        sse_ident, out[f"ident{k}"], _ = fitted(ident)
        grid = [(c, *fitted(c)) for c in itertools.combinations(TAU_GRID_S, k)]
        best_train = min(grid, key=lambda g: g[1])
        best_test = min(grid, key=lambda g: g[2])
        sse_min = min(best_train[1], sse_ident)  # variable projection may beat the grid
        p = node_design(sd.nodes.z(best_train[0]), best_train[0]).shape[1] + 1
        s2 = sse_min / (sd.y.size - p)
        out[f"train{k}"] = best_train[2]
        held = min(grid, key=lambda g: sh.heldout_score("", by_parts, fit_at(g[0])))
        out[f"parts{k}"] = held[2]
        out[f"test{k}"] = best_test[2]
        out[f"dchi2_{k}"] = (best_test[1] - sse_min) / s2
        out[f"mix{k}"] = on_test(0.5 * (bank + best_train[3]))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.probes.tau_information",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.probes.tau_information --first 1 --n 8 "
        "--protocols e",
    )
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--protocols", default="b,e")
    ap.add_argument("--nodes", default="2,3", help="node counts, from 2,3")
    ap.add_argument("--partial", action="store_true",
                    help="the partial-cycle programs of make bench-hysteresis instead, on its "
                    "gyros that draw a play with the play taken out")
    ap.add_argument("--out", type=Path, default=Path("out/probe-tau-information.json"))
    args = ap.parse_args(argv)
    nodes = tuple(int(k) for k in args.nodes.split(","))
    if any(k not in CHI2_95 for k in nodes):
        ap.error(f"--nodes: each of {sorted(CHI2_95)}")
    if args.partial:
        from benchmarks.hysteresis import pick_seeds
        from fogsf.sim.population import DEV_SEEDS, EVAL_SEEDS

        pool = EVAL_SEEDS if args.first in EVAL_SEEDS else DEV_SEEDS
        seeds = pick_seeds(args.first, args.n, pool)["same-flat"]
        cases = ["partial"]
    else:
        seeds = list(range(args.first, args.first + args.n))
        cases = args.protocols.split(",")
    rows: list[dict] = []
    t0 = time.perf_counter()
    for seed in seeds:
        got = ({"partial": partial_case(seed, "same-flat")} if args.partial
               else protocol_cases(seed, cases))
        row: dict = {"gyro": seed}
        for c, (train, test) in got.items():
            row[c] = score(train, test, nodes)
            print(f"gyro {seed:5d} {c} "
                  + " ".join(f"{k} {v:.2f}" for k, v in row[c].items()), flush=True)
        rows.append(row)
    for c in cases:
        sub = [r[c] for r in rows]
        print(f"({c}) {len(sub)} gyros; median/p90/worst {spread_cells(sub, list(sub[0]))}")
        for k in nodes:
            inside = sum(1 for s in sub if s[f"dchi2_{k}"] < CHI2_95[k])
            print(f"  {k} nodes: the test's time constants within the training logs' 95 % "
                  f"allowance on {inside} of {len(sub)} gyros")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    return finish(rows, str(args.out), t0)


if __name__ == "__main__":
    raise SystemExit(main())
