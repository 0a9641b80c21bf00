"""A production line: new units calibrated with their design's prior (`make bench-fleet`).

For each design (a population gyro, `fogsf.sim.fleet_units`; evaluation designs 20000-29999
by default, development 0-9999 with `--seeds dev`, where tuning belongs):
- a fleet of units 0..N-1 on the full program (the envelope of `make bench-population`'s
  protocol f: 0.5 and 2 C/min up-ramps, the 1 up / 2 down loop and the test loop run
  again, 11.75 h), the design's prior learned from the first 5, 10 and 20 of them
  (`fogsf.prior.design_prior.learn`, as `fogsf train --prior` learns it from the database);
- new units (indices from 100, never in the fleet), each on short runs: `up20` (one
  2 C/min up-ramp, 0.75 h), `loop2h` (2 C/min up and down, 15 min soaks, 2 h), `up05` (one
  0.5 C/min up-ramp, 3 h), `loop4h` (the 1 up / 2 down loop with 30 min soaks, 4 h), and
  `full` (the fleet's program), each tested on the test loop (1 C/min up, 1.5 C/min down,
  30 min soaks): test RMS / noise floor;
  - `prior`: the unit's law under the prior (`prior_function.function_fit`, `law`), the
    law `fogsf train --prior` carries in its head (the LSTM on top is left out here: the
    bench scores the least-squares part, which the LSTM's validation keeps unless it does
    better), or `alone` where the unit's data disagree with the design (train --prior
    fits it alone there); on `full` the design's structure fitted to the unit's own
    program (the prior adds nothing there); beside it `map`, the MAP of the parameters
    (`prior_map.map_fit`, the check's fit), and `interval`, the upper end of the interval
    `train --prior` states, over the floor, against the unit's test figure (units that
    agree with the design: the others get none);
  - `default`: `fogsf train` without the prior on `loop2h` and `up05` (its LSTM included);
  - `alone`: the default's least-squares part (no LSTM iterations) on every run, for the
    chamber hours each residual takes;
  - `oracle`: the design's structure fitted to the unit's full program (where the prior's
    structure stops), and on `loop2h` the MAP with the unit's own full-program time
    constants (what the prior reaches when it knows them).
Chamber hours to reach a residual: per residual level, the shortest run whose median over
the new units is at or under it, with the prior (fleet of 20) and alone.

    python -m benchmarks.fleet --seeds dev --designs 2 --new 2 --workers 2
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.population import HI_C, LO_C, run_profile
from fogsf.gsa.executors import add_executor_options, executor_from_args, run_all
from fogsf.logs.measure.metrics import log_metrics
from fogsf.sim.config import ProfileConfig

FULL = ("up05", "up20", "loop_train", "loop_test_again")
RUNS = {"up20": 0.75, "loop2h": 2.0, "up05": 3.0, "loop4h": 4.0, "full": 11.75}  # hours
DEFAULT_ON = ("loop2h", "up05")
FLEETS = (5, 10, 20)
NEW_FIRST = 100
LEVELS = (1.1, 1.2, 1.3, 1.5, 2.0, 3.0)
RUN_OFFSET = {"up05": 1, "up20": 2, "loop_train": 3, "loop_test_again": 4, "loop2h": 5,
              "loop4h": 6, "loop_test": 7}


def profile(name: str) -> ProfileConfig:
    """The chamber program of a run of the bench."""
    if name == "loop2h":  # 2 C/min up and down, 15 min soaks: 2 h
        soak, ramp = 900.0, (HI_C - LO_C) / 2.0 * 60.0
        return ProfileConfig(kind="program", points=[
            [0.0, LO_C], [soak, LO_C], [soak + ramp, HI_C], [2 * soak + ramp, HI_C],
            [2 * soak + 2 * ramp, LO_C]])
    return run_profile("loop_train" if name == "loop4h" else name)


def simulate_run(design: int, unit: int, name: str):  # noqa: ANN201 - ChamberLog
    from fogsf.sim import simulate
    from fogsf.sim.fleet_units import unit_for
    from fogsf.sim.population import run_on_gyro

    seed = int(np.random.SeedSequence([design, unit, RUN_OFFSET[name]]).generate_state(1)[0])
    return simulate(run_on_gyro(unit_for(design, unit), profile(name), seed, name)).log


def fleet_series(design: int, n: int) -> dict:
    """The step series of the design's units 0..n-1 on the full program, by unit name: what
    the design's prior is learned from (`design_prior.learn`)."""
    from fogsf.prior.unit_fit import step_series

    return {f"unit{u:03d}": step_series([simulate_run(design, u, r) for r in FULL])
            for u in range(n)}


def _score(log, theta: np.ndarray, k: int, play=None) -> float:  # noqa: ANN001
    from benchmarks.probes import ratio
    from fogsf.training.with_prior import law_prediction

    return ratio(log, law_prediction(theta, k, log, play=play))


def _interval(ff, test) -> float:  # noqa: ANN001 - FunctionFit, ChamberLog
    """The upper end of the interval `fogsf train --prior` states, over the floor."""
    from fogsf.training.options import TrainOptions
    from fogsf.training.with_prior import prior_interval

    floor = log_metrics(test)["noise_floor_ppm"]
    return prior_interval(ff, test, TrainOptions(model="lag-lstm"), floor)[1] / floor


def _default(logs: list, test, iters: int | None, seed: int) -> float:  # noqa: ANN001
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    opts = TrainOptions(model="lag-lstm", seed=seed, progress=False, workers=1, iters=iters,
                        transfer_check=False)
    with tempfile.TemporaryDirectory() as tmp:
        m, _ = run_training(opts, logs, test, Path(tmp))
    return m["test"]["after"]["rms_ppm"] / m["noise_floor_ppm"]


def bench_design(design: int, fleets: tuple[int, ...], n_new: int, runs: tuple[str, ...],
                 default: bool) -> dict:
    """One design: the fleet, its priors, the new units' figures (one unit of work)."""
    import torch

    from fogsf.prior import design_prior as fp
    from fogsf.prior.map_estimate import map_fit
    from fogsf.prior.response_prior import function_fit
    from fogsf.prior.unit_fit import fit_unit, step_series

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    series = fleet_series(design, max(fleets))
    first = {k: {sn: fit_unit(s, k) for sn, s in series.items()} for k in fp.K_CHOICES}
    priors = {}
    for n in fleets:
        names = sorted(series)[:n]
        priors[n] = fp.learn({sn: series[sn] for sn in names},
                             first={k: {sn: f[sn] for sn in names} for k, f in first.items()})
    out: dict = {"design": design, "fleets": {n: {"k": p.k, "units": len(p.units),
                                                  "left_out": p.left_out,
                                                  "play": p.as_dict()["play"],
                                                  "taus_s": np.exp(p.mu[:p.k]).tolist()}
                                              for n, p in priors.items()},
                 "new": []}
    big = priors[max(fleets)]
    for u in range(NEW_FIRST, NEW_FIRST + n_new):
        test = simulate_run(design, u, "loop_test")
        logs = {r: ([simulate_run(design, u, x) for x in FULL] if r == "full"
                    else [simulate_run(design, u, r)]) for r in runs}
        row: dict = {"unit": u, "prior": {}, "alone": {}, "default": {}, "chi2": {},
                     "share": {}, "map": {}, "interval": {}}
        full_fit = fit_unit(step_series(logs["full"] if "full" in logs else
                                        [simulate_run(design, u, x) for x in FULL]),
                            big.k, np.exp(big.mu[:big.k]), big.play)
        row["oracle_full"] = _score(test, full_fit.theta, big.k, big.play)
        for r, lg in logs.items():
            row["alone"][r] = _default(lg, test, 0, u)
            for n, p in priors.items():
                if r == "full":  # the full program decides the unit: its own fit
                    row["prior"][f"{r}/{n}"] = row["oracle_full"]
                    continue
                ss = step_series(lg)
                mf = map_fit(ss, p)
                ff = function_fit(ss, p, mf.s2)
                # what train --prior delivers: the unit alone where its data disagree
                row["prior"][f"{r}/{n}"] = row["alone"][r] if mf.disagrees else _score(
                    test, ff.law(), p.k, p.play)
                if n == max(fleets):
                    row["chi2"][r] = [mf.chi2, mf.chi2_limit]
                    row["share"][r] = mf.prior_share
                    row["map"][r] = _score(test, mf.theta, p.k, p.play)
                    row["interval"][r] = _interval(ff, test)
            if default and r in DEFAULT_ON:
                row["default"][r] = _default(lg, test, None, u)
        if "loop2h" in logs:  # the MAP knowing the unit's time constants
            tight = fp.DesignPrior(**{**big.__dict__})
            tight.mu = big.mu.copy()
            tight.mu[:big.k] = full_fit.theta[:big.k]
            tight.sigma = big.sigma.copy()
            tight.sigma[:big.k, :] *= 1e-3
            tight.sigma[:, :big.k] *= 1e-3
            mf = map_fit(step_series(logs["loop2h"]), tight)
            row["oracle_taus_loop2h"] = _score(test, mf.theta, big.k, big.play)
        out["new"].append(row)
        print(f"design {design} unit {u}: " + " ".join(
            f"{r} prior {row['prior'][f'{r}/{max(fleets)}']:.2f} alone {row['alone'][r]:.2f}"
            for r in runs), file=sys.stderr, flush=True)
    out["seconds"] = time.perf_counter() - t0
    return out


def _stats(v: list[float]) -> dict:
    a = np.asarray(v, dtype=np.float64)
    return {"median": float(np.median(a)), "worst": float(a.max()), "n": int(a.size)}


def summarise(rows: list[dict], fleets: tuple[int, ...], runs: tuple[str, ...]) -> dict:
    units = [u for d in rows for u in d["new"]]
    s: dict = {"prior": {}, "alone": {}, "default": {}, "hours": {}}
    for r in runs:
        for n in fleets:
            s["prior"][f"{r}/{n}"] = _stats([u["prior"][f"{r}/{n}"] for u in units])
        s["alone"][r] = _stats([u["alone"][r] for u in units])
        if all(r in u["default"] for u in units):
            s["default"][r] = _stats([u["default"][r] for u in units])
    s["oracle_full"] = _stats([u["oracle_full"] for u in units])
    short = [r for r in runs if r != "full"]
    s["map"] = {r: _stats([u["map"][r] for u in units]) for r in short}
    s["interval"] = {}
    for r in short:  # train --prior states an interval where the unit agrees with the design
        agree = [u for u in units if u["chi2"][r][0] <= u["chi2"][r][1]]
        s["interval"][r] = {
            "inside": sum(1 for u in agree if u["prior"][f"{r}/{max(fleets)}"] <= u["interval"][r]),
            "n": len(agree),
            "upper_median": float(np.median([u["interval"][r] for u in agree])) if agree
            else float("nan")}
    if all("oracle_taus_loop2h" in u for u in units):
        s["oracle_taus_loop2h"] = _stats([u["oracle_taus_loop2h"] for u in units])
    s["disagree"] = {r: sum(1 for u in units if u["chi2"][r][0] > u["chi2"][r][1])
                     for r in runs if r != "full"}
    big = max(fleets)
    for level in LEVELS:
        hp = [RUNS[r] for r in runs if s["prior"][f"{r}/{big}"]["median"] <= level]
        ha = [RUNS[r] for r in runs if s["alone"][r]["median"] <= level]
        p, a = (min(hp) if hp else None), (min(ha) if ha else None)
        s["hours"][str(level)] = {"prior": p, "alone": a,
                                  "factor": (a / p) if p and a else None}
    return s


def print_summary(s: dict, fleets: tuple[int, ...], runs: tuple[str, ...], n: int) -> None:
    print(f"test RMS / noise floor (tests 1 C/min up, 1.5 C/min down), median / worst over "
          f"{n} new units")
    head = " ".join(f"{'prior ' + str(f):>14}" for f in fleets)
    print(f"{'run':>8} {'hours':>5} {head} {'alone (LS)':>14} {'default':>14}")
    for r in runs:
        cells = " ".join(f"{s['prior'][f'{r}/{f}']['median']:6.2f}/"
                         f"{s['prior'][f'{r}/{f}']['worst']:<7.2f}" for f in fleets)
        a = s["alone"][r]
        d = s["default"].get(r)
        dc = f"{d['median']:6.2f}/{d['worst']:<7.2f}" if d else f"{'-':>14}"
        print(f"{r:>8} {RUNS[r]:5.2f} {cells} {a['median']:6.2f}/{a['worst']:<7.2f} {dc}")
    o = s["oracle_full"]
    print(f"oracle: the design's structure on the unit's full program {o['median']:.2f} / "
          f"{o['worst']:.2f}" + (f"; loop2h with the unit's own time constants "
                                 f"{s['oracle_taus_loop2h']['median']:.2f} / "
                                 f"{s['oracle_taus_loop2h']['worst']:.2f}"
                                 if "oracle_taus_loop2h" in s else ""))
    print("the MAP of the parameters (the check's fit), median / worst: " + ", ".join(
        f"{r} {v['median']:.2f} / {v['worst']:.2f}" for r, v in s["map"].items()))
    print("units at or under the interval's upper end (fleet of " + str(max(fleets)) + "): "
          + ", ".join(f"{r} {v['inside']}/{v['n']} (upper end {v['upper_median']:.2f} x "
                      "the floor, median)" for r, v in s["interval"].items()))
    print("units whose data disagreed with the design (fitted alone by train --prior): "
          + ", ".join(f"{r} {v}" for r, v in s["disagree"].items()))
    print(f"chamber hours to reach a residual (median, fleet of {max(fleets)}):")
    for level, h in s["hours"].items():
        p = f"{h['prior']:.2f} h" if h["prior"] else "not reached"
        a = f"{h['alone']:.2f} h" if h["alone"] else "not reached"
        f = f" ({h['factor']:.1f} x fewer)" if h["factor"] else ""
        print(f"  {float(level):.1f} x the floor: with the prior {p}, alone {a}{f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.fleet --seeds dev --designs 2 --new 2")
    ap.add_argument("--out", default="out/bench-fleet.json")
    ap.add_argument("--seeds", choices=["dev", "eval"], default="eval",
                    help="design seeds: dev (tune here) or eval (report here)")
    ap.add_argument("--designs", type=int, default=2, help="number of designs")
    ap.add_argument("--first", type=int, default=None, help="first design seed")
    ap.add_argument("--new", type=int, default=3, help="new units per design")
    ap.add_argument("--fleets", default=",".join(map(str, FLEETS)))
    ap.add_argument("--runs", default=",".join(RUNS))
    ap.add_argument("--no-default", action="store_true",
                    help="leave out fogsf train's default (with its LSTM) on the short runs")
    add_executor_options(ap, "designs")
    args = ap.parse_args(argv)
    from fogsf.sim.population import seed_range

    fleets = tuple(int(x) for x in args.fleets.split(","))
    runs = tuple(r for r in args.runs.split(",") if r)
    bad = [r for r in runs if r not in RUNS]
    if bad or any(f < 2 for f in fleets):
        ap.error(f"unknown run {bad} (from {', '.join(RUNS)}) or a fleet under 2 units")
    rng = seed_range(args.seeds)
    first = args.first if args.first is not None else max(rng.start, 1)
    designs = list(range(first, first + args.designs))
    if any(d not in rng for d in designs):
        ap.error(f"designs {designs[0]}..{designs[-1]} leave the {args.seeds} range")
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        rows = run_all(ex, bench_design, designs, fleets, args.new, runs, not args.no_default,
                       desc="designs", unit="design")
    s = summarise(rows, fleets, runs)
    print(f"{args.seeds} designs {designs[0]}-{designs[-1]}, fleets of "
          f"{', '.join(map(str, fleets))} units on the full program")
    print_summary(s, fleets, runs, sum(len(d["new"]) for d in rows))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    seconds = time.perf_counter() - t0
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps({"seeds": args.seeds, "designs": designs, "fleets": fleets,
                               "runs": {r: RUNS[r] for r in runs}, "rows": rows,
                               "summary": s, "seconds": seconds}, indent=2) + "\n")
    tmp.replace(out)
    print(f"-> {out} ({seconds:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
