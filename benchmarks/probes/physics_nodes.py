"""Physics nodes against the lag bank, least squares only, per protocol, and the default's
choice among them.

For each gyro and protocol of `benchmarks.population` (and the default gyro's paper
protocol with `--paper`, noise seeds FIRST..), prints the test RMS / noise floor of every
candidate of `training.structure.choice` (physics nodes with 1-3 nodes, the lag bank; with
`--candidates`, others such as `node`), of the one the rule chooses ("default"), of plain
averages of candidates' predictions, and the held-out scores the rule reads.
Run it on development gyros (the rule is tuned there):

    python -m benchmarks.probes.physics_nodes --first 1 --n 24 --protocols a,b,c,d,e
    python -m benchmarks.probes.physics_nodes --paper --first 0 --n 8
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks.population import protocol_logs
from benchmarks.probes import finish, ratio, spread_cells
from fogsf.sim.population import DEV_SEEDS, gyro_for_seed
from fogsf.training.structure.choice import CANDIDATES, choose
from fogsf.training.structure.heldout import candidate_compensation

CANDS = CANDIDATES


def case(train: list, test) -> dict:  # noqa: ANN001
    out: dict = {}
    preds = {}
    for name in CANDS:
        preds[name] = candidate_compensation(name, train)(test)
        out[name] = ratio(test, preds[name])
    phys = [preds[k] for k in preds if k.startswith("physics")]
    if phys:
        out["pmean"] = ratio(test, np.mean(phys, axis=0))
    out["allmean"] = ratio(test, np.mean(list(preds.values()), axis=0))
    if "bank" in preds and phys:
        out["bank+pmean"] = ratio(test, 0.5 * preds["bank"] + 0.5 * np.mean(phys, axis=0))
    choice = choose(train, candidates=None if CANDS == CANDIDATES else CANDS)
    out["scores"] = choice.scores
    out["chosen"] = choice.name
    out["default"] = out[choice.name]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--protocols", default="a,b,e")
    ap.add_argument("--paper", action="store_true", help="the default gyro's paper protocol")
    ap.add_argument("--out", default=None)
    ap.add_argument("--lam", type=float, default=None, help="NODE_LAMBDA for this run")
    ap.add_argument("--curved-max", type=float, default=None,
                    help="CURVED_MAX_TAU_S: slower nodes enter linearly")
    ap.add_argument("--no-cube", action="store_true", help="no cube of T in the node law")
    ap.add_argument("--candidates", default=None, help="comma list (default CANDIDATES)")
    args = ap.parse_args(argv)
    from fogsf.models.structures import physics_nodes

    if args.lam is not None:
        physics_nodes.NODE_LAMBDA = args.lam
    if args.curved_max is not None:
        physics_nodes.CURVED_MAX_TAU_S = args.curved_max
    if args.no_cube:
        physics_nodes.CUBE_T = False
    global CANDS
    if args.candidates:
        CANDS = tuple(args.candidates.split(","))
    rows = []
    t0 = time.perf_counter()
    if args.paper:
        from fogsf.sim.gyro import simulate
        from fogsf.sim.scenarios import paper

        for seed in range(args.first, args.first + args.n):
            tr = simulate(paper(0.5, seed=1000 + seed)).log
            te = simulate(paper(1.0, seed=2000 + seed)).log
            r = case([tr], te)
            rows.append({"seed": seed, "p": "paper", **r})
            print(seed, "paper", {k: round(v, 2) if isinstance(v, float) else v
                                  for k, v in r.items() if k != "scores"},
                  {k: round(v, 2) for k, v in r["scores"].items()}, flush=True)
    else:
        for seed in range(args.first, args.first + args.n):
            assert seed in DEV_SEEDS or seed >= 20000
            gyro = gyro_for_seed(seed)
            for p in args.protocols.split(","):
                train, test = protocol_logs(gyro, seed, p)
                r = case(train, test)
                rows.append({"seed": seed, "p": p, **r})
                print(seed, p, {k: round(v, 2) if isinstance(v, float) else v
                                for k, v in r.items() if k != "scores"},
                      {k: round(v, 2) for k, v in r["scores"].items()}, flush=True)
    names = [n for n in (*CANDS, "default", "pmean", "allmean", "bank+pmean") if n in rows[0]]
    for p in sorted({r["p"] for r in rows}):
        sub = [r for r in rows if r["p"] == p]
        print(f"({p}) median/p90/worst {spread_cells(sub, names)}")
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
