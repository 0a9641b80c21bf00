"""Probe: does `fogsf plan --prior --target X` keep its promise on the design's real units?

Per design (`make bench-fleet`'s: a fleet of 20 units on the full program, its prior), the
planner's answer as `fogsf plan --prior FLEET --target X` gives it (the shortest candidate
whose median over units drawn from the prior reaches X, scored on the envelope's test
loops), then new units of the design (from 100, never in the fleet) simulated on that
program, fitted under the prior as `train --prior` fits them (the law it exports; the unit
alone where its data disagree), and scored on the planner's envelope loops and on the
bench's test loop (1 C/min up, 1.5 C/min down, 30 min soaks): test RMS / noise floor. The
planner's units are the prior's own model; the design's units are not.

    python -m benchmarks.probes.fleet_plan_prior --designs 3,4 --target 1.3
    python -m benchmarks.probes.fleet_plan_prior --seeds eval --designs 20000,20001,20002,20003
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from benchmarks.fleet import NEW_FIRST, _score, fleet_series, simulate_run
from fogsf.plan.programs import Program


def simulate_points(design: int, unit: int, points: tuple, seed: int, name: str):  # noqa: ANN201
    """The unit's log of one run of a planned program (chamber points)."""
    from fogsf.sim import simulate
    from fogsf.sim.config import ProfileConfig
    from fogsf.sim.fleet_units import unit_for
    from fogsf.sim.population import run_on_gyro

    prof = ProfileConfig(kind="program", points=[[float(t), float(c)] for t, c in points])
    return simulate(run_on_gyro(unit_for(design, unit), prof, seed, name)).log


def probe_design(design: int, target: float, n_fleet: int, n_new: int, hours: float) -> dict:
    import torch

    from fogsf.plan.evaluate import envelope_program, test_rates
    from fogsf.plan.prior_program import shortest
    from fogsf.plan.programs import Limits
    from fogsf.prior import design_prior as fp
    from fogsf.prior.map_estimate import map_fit
    from fogsf.prior.response_prior import function_fit
    from fogsf.prior.unit_fit import step_series

    torch.set_num_threads(1)
    prior = fp.learn(fleet_series(design, n_fleet))
    limits = Limits(-40.0, 50.0, 3.0, hours)
    rates = test_rates(0.2, 2.0, 4)
    best, tried = shortest(prior, limits, rates, target)
    out: dict = {"design": design, "target": target, "found": None,
                 "best_median": min(r.median for r in tried)}
    if best is None:
        print(f"design {design}: nothing within {hours:g} h reaches {target:g}", file=sys.stderr)
        return out
    program: Program = best.program
    envelope = envelope_program(limits, rates)
    out.update(found=program.name, hours=program.hours, planned_median=best.median,
               planned_worst=best.worst, units=[])
    for u in range(NEW_FIRST, NEW_FIRST + n_new):
        logs = [simulate_points(design, u, run, 7919 * u + i, f"plan{i}")
                for i, run in enumerate(program.runs)]
        ss = step_series(logs)
        mf = map_fit(ss, prior)
        if mf.disagrees:
            out["units"].append({"unit": u, "disagrees": True})
            continue
        law = function_fit(ss, prior, mf.s2).law()
        env = [_score(simulate_points(design, u, run, 104729 * u + i, f"env{i}"), law,
                      prior.k, prior.play) for i, run in enumerate(envelope.runs)]
        test = _score(simulate_run(design, u, "loop_test"), law, prior.k, prior.play)
        out["units"].append({"unit": u, "envelope": env, "test_loop": test})
    env_all = [x for r in out["units"] if "envelope" in r for x in r["envelope"]]
    tests = [r["test_loop"] for r in out["units"] if "test_loop" in r]
    if env_all:
        out["achieved_median"] = float(np.median(env_all))
        out["achieved_worst"] = float(np.max(env_all))
        out["test_loop_median"] = float(np.median(tests))
        out["test_loop_worst"] = float(np.max(tests))
        print(f"design {design}: {program.name} ({program.hours:.2f} h) planned "
              f"{best.median:.2f} / {best.worst:.2f}, achieved on the envelope "
              f"{out['achieved_median']:.2f} / {out['achieved_worst']:.2f}, on the test loop "
              f"{out['test_loop_median']:.2f} / {out['test_loop_worst']:.2f}",
              file=sys.stderr, flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", choices=("dev", "eval"), default="dev")
    ap.add_argument("--designs", default="3,4")
    ap.add_argument("--target", type=float, default=1.3)
    ap.add_argument("--hours", type=float, default=6.0)
    ap.add_argument("--fleet", type=int, default=20)
    ap.add_argument("--new", type=int, default=3)
    ap.add_argument("--out", default="out/probe-plan-prior.json")
    args = ap.parse_args(argv)
    designs = [int(x) for x in args.designs.split(",")]
    if args.seeds == "dev" and any(d >= 10000 for d in designs):
        ap.error("development designs are 0-9999")
    rows = [probe_design(d, args.target, args.fleet, args.new, args.hours) for d in designs]
    with open(args.out, "w") as f:
        json.dump(rows, f, indent=1)
    print(f"plan --prior --target {args.target:g} (median / worst over units x rates):")
    for r in rows:
        if r["found"] is None:
            print(f"  design {r['design']}: none within {args.hours:g} h (best median "
                  f"{r['best_median']:.2f})")
        elif "achieved_median" in r:
            print(f"  design {r['design']}: {r['found']} ({r['hours']:.2f} h) planned "
                  f"{r['planned_median']:.2f} / {r['planned_worst']:.2f}; achieved "
                  f"{r['achieved_median']:.2f} / {r['achieved_worst']:.2f}, test loop "
                  f"{r['test_loop_median']:.2f} / {r['test_loop_worst']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
