"""`make bench-plan`: does the planned chamber program hold on gyros it was not planned on?

`fogsf plan`'s search at its default budget on development gyros (1-24) picks the best
program; then the best, the best one-rate program (one up-ramp) and the paper's protocol
(0.5 and 1 C/min up-ramps, two runs, 4.5 h over -40..50 C) are scored on evaluation gyros
(20000 on) with the same test loops (0.2-2 C/min, up and down), beside a reference: the
bank trained on the whole envelope (a loop at every test rate, other noise), what no
program of a few hours can beat with this model: the default model's lag
bank trained on the program, test RMS / noise floor, median and p90 over gyros and rates,
and over the rates not in the program. Prints the table, writes JSON and the figure.

    python -m benchmarks.plan --eval-gyros 24 --out out/bench-plan.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from fogsf.gsa.executors import add_executor_options, executor_from_args, run_all
from fogsf.plan.evaluate import envelope_program, evaluate_gyro, test_rates
from fogsf.plan.programs import Limits
from fogsf.plan.report import as_json, score, table_md, write_outputs
from fogsf.plan.search import search
from fogsf.sim.population import EVAL_SEEDS

LIMITS = Limits(-40.0, 50.0, 3.0, 4.5)
RATES = test_rates(0.2, 2.0, 4)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.plan --dev-gyros 8 --eval-gyros 8 "
               "--out out/bench-plan-small.json")
    ap.add_argument("--dev-gyros", type=int, default=24)
    ap.add_argument("--eval-gyros", type=int, default=24)
    ap.add_argument("--out", default="out/bench-plan.json")
    add_executor_options(ap)
    args = ap.parse_args(argv)
    limits, rates = LIMITS, RATES
    dev = list(range(1, 1 + args.dev_gyros))
    ev = list(range(EVAL_SEEDS.start, EVAL_SEEDS.start + args.eval_gyros))
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        ranked, paper_dev = search(limits, rates, [(g, g) for g in dev], ex)
        t_plan = time.perf_counter() - t0
        one_rate = next(s for s in ranked if s.program.name.startswith("up "))
        chosen = [ranked[0].program, one_rate.program, envelope_program(limits, rates)]
        res = run_all(ex, evaluate_gyro, [(g, g) for g in ev], [paper_dev.program, *chosen],
                      limits, rates, desc="eval gyros", unit="gyro")
    scored = score(chosen, res)
    best_e = next(s for s in scored if s.program is chosen[0])
    one_e = next(s for s in scored if s.program is chosen[1])
    env_e = next(s for s in scored if s.program is chosen[2])
    (paper_e,) = score([paper_dev.program], res)
    print(f"chosen on development gyros {dev[0]}-{dev[-1]} ({t_plan:.0f} s): "
          f"{ranked[0].program.name}; median {ranked[0].median:.2f}, p90 {ranked[0].p90:.2f}")
    print(f"on evaluation gyros {ev[0]}-{ev[-1]}, test loops at "
          + ", ".join(f"{r:.2g}" for r in rates) + " C/min:")
    print(table_md([best_e, one_e, env_e], paper_e, 3), end="")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = {"dev_seeds": dev, "eval_seeds": ev, "plan_seconds": t_plan,
            "seconds": time.perf_counter() - t0}
    out.write_text(json.dumps({**meta, "dev_best": as_json(ranked[0]),
                               "eval": {"best": as_json(best_e), "one_rate": as_json(one_e),
                                        "whole_envelope": as_json(env_e),
                                        "paper": as_json(paper_e)}}, indent=1))
    write_outputs(out.with_suffix(""), [best_e, one_e, env_e], paper_e, meta)
    print(f"-> {out}, {out.with_suffix('')}/plan.png ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
