"""fogsf plan: the chamber program that buys the most accuracy per chamber hour.

Builds candidate chamber programs inside the chamber's limits (one up-ramp; a loop up at
one rate and down at another with soaks; three ramps at three rates; a staircase up and
down with a soak at every level), simulates each on
population gyros (development seeds: the planner is tuned nowhere else), trains the
default model's lag bank on it, and predicts its residual at ramp rates across the
envelope (test loops up and down with soaks, other runs than the program's), as a multiple
of the noise floor: median and p90 over gyros and rates, and the same over the rates that
are not in the program. Programs are ranked by p90, then median. For the best
few and for the paper's protocol (0.5 and 1 C/min up-ramps, two runs) it also gives the
rate-transfer interval's upper end (how sure `fogsf train --test` would be) and which
effects the program lets `fogsf diagnose` tell apart (rules, not measured).

Writes OUT/program.csv (the best program, `time_s,temp_c`: what `fogsf simulate
--program` reads and a chamber controller can load), OUT/table.md (every program
compared), OUT/plan.json and OUT/plan.png (temperature program; predicted residual per
rate, best against the paper's protocol).

With --prior FLEET --target X it plans for a new unit of a design instead: the shortest
candidate program that reaches X times the noise floor for units drawn from the design's
prior (learned from the units in the fleet database; docs/fleet.md).

Examples:
  fogsf plan --range=-40:50 --max-ramp 3 --hours 4.5 --gyros 8 --out plan/
  fogsf plan --prior line.fleet --target 1.3 --range=-40:50 --hours 6 --out plan-unit/
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

from fogsf.cli.arguments import (
    add_earth_options,
    add_log_options,
    positive_int,
    read_logs,
)
from fogsf.diagnose import extend, verdict
from fogsf.errors import UserError
from fogsf.fleet.new_unit import prior_from_store
from fogsf.gsa.executors import add_executor_options, executor_from_args
from fogsf.logs.chamber_log import ChamberLog
from fogsf.plan.evaluate import test_rates
from fogsf.plan.prior_program import shortest, write
from fogsf.plan.programs import Limits, candidates
from fogsf.plan.report import table_md, write_outputs
from fogsf.plan.search import search
from fogsf.sim.config import SimConfig
from fogsf.sim.population import DEV_SEEDS


def _pair(text: str) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO:HI like -40:50, got {text!r}") from None
    if not a < b:
        raise argparse.ArgumentTypeError(f"expected LO < HI, got {text!r}")
    return a, b


def configure(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("the chamber and the budget")
    g.add_argument("--range", type=_pair, default=(-40.0, 50.0), metavar="LO:HI",
                   help="chamber temperature range, C (default -40:50)")
    g.add_argument("--max-ramp", type=float, default=3.0, metavar="C_PER_MIN",
                   help="fastest ramp the chamber holds, C/min (default 3)")
    g.add_argument("--hours", type=float, default=4.5,
                   help="chamber hours the program may take (default 4.5, the paper's)")
    g.add_argument("--envelope-rate", type=_pair, default=(0.2, 2.0), metavar="LO:HI",
                   help="ramp rates the gyro will see in service, C/min (default 0.2:2)")
    g.add_argument("--test-rates", type=int, default=4, metavar="N",
                   help="envelope rates scored, log-spaced, ends included (default 4)")
    p = parser.add_argument_group("the gyros it is planned for")
    p.add_argument("--gyros", type=positive_int, default=24, metavar="N",
                   help="population gyros (development seeds from --first; default 24)")
    p.add_argument("--first", type=int, default=1, metavar="SEED",
                   help="first population seed (default 1; 0 is the default gyro)")
    p.add_argument("--axes", type=positive_int, default=1, metavar="N",
                   help="gyros per IMU sharing the chamber (default 1): each group of N "
                        "consecutive gyros counts once, by its worst axis")
    p.add_argument("--from-logs", nargs="+", type=Path, metavar="LOG",
                   help="plan for gyros fitted to earlier chamber logs (one gyro per log, "
                        "fitted as `fogsf diagnose` fits its base model) instead of the "
                        "population")
    p.add_argument("--interval-gyros", type=int, default=4, metavar="N",
                   help="gyros on which the rate-transfer interval is computed for the best "
                        "programs and the paper's (default 4; 0 skips it)")
    p.add_argument("--top", type=positive_int, default=10,
                   help="programs printed (default 10)")
    f = parser.add_argument_group("a new unit of a design (docs/fleet.md)")
    f.add_argument("--prior", metavar="FLEET",
                   help="plan for a new unit fitted with its design's prior, learned from "
                        "the fleet database FLEET: the shortest candidate program that "
                        "reaches --target for units drawn from the prior")
    f.add_argument("--target", type=float, default=None, metavar="X",
                   help="with --prior: the residual to reach, x the noise floor (median "
                        "over units and envelope rates)")
    f.add_argument("--units", type=positive_int, default=6, metavar="N",
                   help="with --prior: units drawn from the prior (default 6)")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    g = parser.add_argument_group("--from-logs: how each log is fitted (as `fogsf diagnose`)")
    g.add_argument("--window-s", type=float, default=60.0,
                   help="SF window length, s (default 60)")
    add_earth_options(g)
    add_log_options(parser)
    add_executor_options(parser, "the candidate programs' fits")


def run(args: argparse.Namespace) -> int:
    if not 1 <= args.test_rates <= 12:
        raise UserError(f"--test-rates must be 1-12, got {args.test_rates}")
    if args.prior or args.target is not None:
        return run_prior(args)
    seeds = list(range(args.first, args.first + args.gyros))
    if seeds[0] not in DEV_SEEDS or seeds[-1] not in DEV_SEEDS:
        raise UserError(f"--first/--gyros: plan on development seeds ({DEV_SEEDS.start}-"
                        f"{DEV_SEEDS.stop - 1}); evaluation seeds are for benchmarks")
    elo, ehi = args.envelope_rate
    if elo <= 0:
        raise UserError("--envelope-rate: rates must be positive, e.g. 0.2:2")
    limits = Limits(args.range[0], args.range[1], args.max_ramp, args.hours)
    gyros: list = [(s, s) for s in seeds]
    what = (f"{len(seeds)} development gyros ({seeds[0]}-{seeds[-1]})" if len(seeds) > 1
            else f"development gyro {seeds[0]}")
    if args.from_logs:
        fitted = fitted_gyros(read_logs(args, [str(p) for p in args.from_logs], on_disk=True),
                              args.window_s, args.latitude_deg)
        gyros = [(i + 1, g) for i, g in enumerate(fitted)]
        what = f"{len(gyros)} gyros fitted to " + ", ".join(p.name for p in args.from_logs)
    if len(gyros) % args.axes:
        raise UserError(f"--axes {args.axes}: the number of gyros ({len(gyros)}) must be a "
                        "multiple of it")
    if args.axes > 1:
        imus = len(gyros) // args.axes
        what += f", {imus} IMU{'s' if imus > 1 else ''} of {args.axes} axes"
    n_progs = len(candidates(limits))
    if not n_progs:
        unbounded = candidates(replace(limits, hours=72.0))  # the longest --hours allowed
        shortest = min((p.hours for p in unbounded), default=None)
        need = (f": the shortest within {limits.lo_c:g}..{limits.hi_c:g} C at <= "
                f"{limits.max_ramp_c_per_min:g} C/min takes {shortest:.2f} h, so --hours "
                f"{math.ceil(shortest * 10) / 10:g} or more" if shortest else "")
        raise UserError(f"no program fits in {limits.hours:g} h{need}; or raise --max-ramp, "
                        "or narrow --range")
    rates = test_rates(elo, ehi, args.test_rates)
    print(f"{n_progs} candidate programs within {limits.lo_c:g}..{limits.hi_c:g} C, "
          f"<= {limits.max_ramp_c_per_min:g} C/min, <= {limits.hours:g} h; scored at "
          + ", ".join(f"{r:.2g}" for r in rates) + f" C/min on {what}")
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        ranked, paper_s = search(limits, rates, gyros, ex, args.interval_gyros, args.axes,
                                 progress=sys.stderr.isatty())  # a bar on a terminal only
    print(table_md(ranked, paper_s, args.top), end="")
    best = ranked[0]
    meta = {"limits": vars(limits), "envelope_rates": list(rates),
            "gyro_seeds": None if args.from_logs else seeds, "axes": args.axes,
            "from_logs": [str(p) for p in args.from_logs or []],
            "seconds": time.perf_counter() - t0}
    write_outputs(args.out, ranked, paper_s, meta)
    print(f"best: {best.program.name} ({best.program.hours:.2f} h): median {best.median:.2f}, "
          f"p90 {best.p90:.2f} x the noise floor across the envelope; the paper's protocol "
          f"{paper_s.median:.2f} / {paper_s.p90:.2f}")
    print(f"wrote {args.out}/program.csv, table.md, plan.json, plan.png "
          f"({time.perf_counter() - t0:.0f} s)")
    return 0


def fitted_gyros(logs: list[ChamberLog], window_s: float = 60.0,
                 latitude_deg: float | None = None) -> list:
    """One simulator gyro per log: diagnose's base model fitted to it (thermal network,
    SF terms, bias, noise; SF in `window_s` windows, the earth rate from the log or
    `latitude_deg`), for the planner to simulate programs on."""
    out = []
    for log in logs:
        d = verdict.diagnose([log], window_s=window_s, latitude_deg=latitude_deg, effects=[])
        out.append(SimConfig.from_dict(extend.sim_config(d, d.base, 0)))
        print(f"fitted a gyro to {log.path}: nodes at "
              + ", ".join(f"{n.tau_s:.0f} s" for n in out[-1].thermal.nodes[2:]))
    return out


def run_prior(args: argparse.Namespace) -> int:
    """`fogsf plan --prior FLEET --target X`."""

    if not args.prior or args.target is None:
        raise UserError("--prior FLEET and --target X go together")
    if not (math.isfinite(args.target) and args.target > 1.0):
        raise UserError(f"--target must be above 1 (x the noise floor), got {args.target:g}")
    if args.from_logs:
        raise UserError("--prior plans for the design's units: drop --from-logs")
    elo, ehi = args.envelope_rate
    if elo <= 0:
        raise UserError("--envelope-rate: rates must be positive, e.g. 0.2:2")
    limits = Limits(args.range[0], args.range[1], args.max_ramp, args.hours)
    rates = test_rates(elo, ehi, args.test_rates)
    prior = prior_from_store(args.prior)
    print(f"design's prior: {prior.k} physics nodes from {len(prior.units)} units; "
          f"{args.units} units drawn from it, scored at "
          + ", ".join(f"{r:.2g}" for r in rates) + " C/min")
    t0 = time.perf_counter()

    def said(r) -> None:  # noqa: ANN001 - prior_program.PlanResult
        print(f"  {r.program.name:<48} {r.program.hours:5.2f} h: median {r.median:.2f}, "
              f"worst {r.worst:.2f} x the floor", flush=True)

    best, tried = shortest(prior, limits, rates, args.target, args.units, progress=said)
    write(args.out, best, tried, {"target": args.target, "limits": vars(limits),
                                  "envelope_rates": list(rates), "units": args.units,
                                  "fleet_units": prior.units,
                                  "seconds": time.perf_counter() - t0})
    if best is None:
        print(f"no candidate within {limits.hours:g} h reaches {args.target:g} x the floor "
              f"(best median {min(r.median for r in tried):.2f}); raise --hours or the target")
        return 0
    print(f"shortest program reaching {args.target:g} x: {best.program.name} "
          f"({best.program.hours:.2f} h), median {best.median:.2f}, worst {best.worst:.2f}; "
          f"wrote {args.out}/program.csv and plan-prior.json")
    return 0
