"""Held-out scores for logs of several segments: which one tells the structures apart.

For each gyro and protocol (b)-(e) of `benchmarks.population` (and, with `--paper`, the
default gyro trained on 0.5 and 2 C/min and tested on 1 C/min, noise seeds FIRST..), prints
per candidate of `training.structure.choice` the test RMS / noise floor (least squares) and
its held-out score under several fold schemes:

  loso    leave one segment out (a ramp at another rate or direction: extrapolation in rate)
  parts   every segment in 3 contiguous parts, one part out at a time (interpolation in rate:
          the other segments still hold the part's temperatures at other rates); the
          default rule reads it (`structure_choice.EVIDENCE_FACTOR`)

Run it on development gyros (a rule is tuned there):

    python -m benchmarks.probes.multi_segment_scores --first 1 --n 16 --protocols b,e
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from benchmarks.population import protocol_logs
from benchmarks.probes import finish
from fogsf.logs.measure.metrics import log_metrics
from fogsf.sim.population import DEV_SEEDS, gyro_for_seed
from fogsf.training.structure.choice import choose
from fogsf.training.structure.heldout import (
    candidate_compensations,
    heldout_score,
    part_folds,
    step_data,
)

CANDS = ("physics1", "physics2", "physics3", "bank", "node")


def case(train: list, test) -> dict:  # noqa: ANN001
    sd, comps = candidate_compensations(CANDS, train)
    floor = log_metrics(test)["noise_floor_ppm"]
    out: dict = {"test": {}, "loso": {}, "parts": {}}
    for name, comp in comps.items():
        out["test"][name] = log_metrics(test, correction_ppm=comp(test))["rms_ppm"] / floor
    sd = step_data(train)
    sp = dataclasses.replace(sd, fold=part_folds(sd))
    for name in CANDS:
        out["loso"][name] = heldout_score(name, sd)
        out["parts"][name] = heldout_score(name, sp)
    out["chosen"] = choose(train).name
    out["test"]["default"] = out["test"][out["chosen"]]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--protocols", default="b,e")
    ap.add_argument("--paper", action="store_true",
                    help="the default gyro, trained on 0.5 + 2 C/min, tested on 1 C/min")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    rows = []
    t0 = time.perf_counter()
    for seed in range(args.first, args.first + args.n):
        if args.paper:
            from fogsf.sim.gyro import simulate
            from fogsf.sim.scenarios import paper

            cases = [("paper2", [simulate(paper(0.5, seed=1000 + seed)).log,
                                 simulate(paper(2.0, seed=4000 + seed)).log],
                      simulate(paper(1.0, seed=2000 + seed)).log)]
        else:
            if seed not in DEV_SEEDS:
                ap.error(f"rules are compared on development seeds only ({DEV_SEEDS})")
            gyro = gyro_for_seed(seed)
            cases = [(p, *protocol_logs(gyro, seed, p)) for p in args.protocols.split(",")]
        for p, train, test in cases:
            r = case(train, test)
            rows.append({"seed": seed, "p": p, **r})
            print(seed, p, r["chosen"], " ".join(f"{k}:{r['test'][k]:.2f}/{r['loso'][k]:.1f}/"
                                    f"{r['parts'][k]:.1f}" for k in CANDS), flush=True)
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
