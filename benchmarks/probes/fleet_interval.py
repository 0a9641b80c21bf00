"""Probe: how tight `fogsf train --prior --test`'s interval can be made and still hold.

Per design (`make bench-fleet`'s: a fleet of 20 units on the full program, its prior) and
new unit on each short run, against its test loop: the actual test RMS over the floor, the
interval's upper end as `train --prior` states it now (`with_prior.prior_interval`: the
floor and INTERVAL_Z^2 (mean_t var_t + m)), and the quantiles of the same quantity read
from posterior draws of the unit's test response instead of its mean variance: e = B z, z
~ N(0, the posterior covariance), top_q = sqrt(floor^2 + quantile_q(mean_t e_t^2) + c m).
Writes every unit's figures to JSON; `--rules` prints, per rule, how many units each
interval holds and how many it brings within 2 x their actual figure, and, were the
posterior exact, the share of units the tightest top holding 90 % could bring within 2 x.

    python -m benchmarks.probes.fleet_interval --designs 3,4,10,15 --out out/probe-interval.json
    python -m benchmarks.probes.fleet_interval --rules out/probe-interval.json
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from benchmarks.fleet import NEW_FIRST, _score, fleet_series, simulate_run
from fogsf.logs.measure.metrics import log_metrics

RUNS = ("up20", "loop2h", "up05", "loop4h")
DRAWS = 4000
QUANTILES = (0.8, 0.9, 0.95)


def probe_design(design: int, n_fleet: int, n_new: int, runs: tuple[str, ...]) -> list[dict]:
    import torch

    from fogsf.prior import design_prior as fp
    from fogsf.prior.map_estimate import map_fit
    from fogsf.prior.response_prior import function_fit
    from fogsf.prior.unit_fit import step_series
    from fogsf.training.with_prior import INTERVAL_Z, test_series

    torch.set_num_threads(1)
    prior = fp.learn(fleet_series(design, n_fleet))
    rows = []
    for u in range(NEW_FIRST, NEW_FIRST + n_new):
        test = simulate_run(design, u, "loop_test")
        floor = log_metrics(test)["noise_floor_ppm"]
        ts, _ = test_series(test, 5.0, None)
        for r in runs:
            ss = step_series([simulate_run(design, u, r)])
            mf = map_fit(ss, prior)
            if mf.disagrees:  # train --prior states no interval there
                continue
            ff = function_fit(ss, prior, mf.s2)
            _, b = ff.basis(ts)
            ev, vec = np.linalg.eigh(ff.a_cov)
            root = vec * np.sqrt(np.maximum(ev, 0.0))
            z = np.random.default_rng(u).standard_normal((DRAWS, root.shape[1]))
            e2 = np.mean((z @ root.T @ b.T) ** 2, axis=1)
            var = float(np.mean(ff.variance(ts)))
            row = {"design": design, "unit": u, "run": r, "floor_ppm": floor,
                   "actual": _score(test, ff.law(), prior.k, prior.play),
                   "mean_var_ppm2": var, "misfit_ppm2": ff.misfit_ppm2(),
                   "z": INTERVAL_Z,
                   "e2_quantiles": {str(q): float(np.quantile(e2, q)) for q in QUANTILES},
                   "exact_tight": exact_tight(floor, e2)}
            rows.append(row)
            print(f"design {design} unit {u} {r}: actual {row['actual']:.2f}", file=sys.stderr,
                  flush=True)
    return rows


def exact_tight(floor: float, e2: np.ndarray) -> float:
    """Were the posterior exact: the chance that the tightest top holding 90 % (the 90 %
    quantile of the test RMS it implies) is within 2 x the unit's actual test RMS."""
    a = np.sqrt(floor**2 + e2)
    return float(np.mean(a >= np.quantile(a, 0.9) / 2))


def top(row: dict, rule: str, c: float) -> float:
    """A rule's upper end over the floor: `now` (Z^2 (var + c m)) or `qXX` (draws)."""
    f2 = row["floor_ppm"] ** 2
    m = c * row["misfit_ppm2"]
    if rule == "now":
        return float(np.sqrt(f2 + row["z"] ** 2 * (row["mean_var_ppm2"] + m)) / row["floor_ppm"])
    return float(np.sqrt(f2 + row["e2_quantiles"][rule[1:]] + m) / row["floor_ppm"])


def print_rules(rows: list[dict]) -> None:
    runs = sorted({r["run"] for r in rows})
    rules = [("now", 1.0)] + [(f"q{q}", c) for q in QUANTILES for c in (1.0, 4.0)]
    print(f"{len(rows)} units x runs: per rule, held / within 2 x (all), then per run")
    for rule, c in rules:
        held = [r["actual"] <= top(r, rule, c) for r in rows]
        tight = [top(r, rule, c) <= 2 * r["actual"] for r in rows]
        per = ", ".join(
            f"{k} {sum(h for h, r in zip(held, rows, strict=True) if r['run'] == k)}/"
            f"{sum(t for t, r in zip(tight, rows, strict=True) if r['run'] == k)}" for k in runs)
        print(f"  {rule:6s} m x{c:g}: held {sum(held)}/{len(rows)}, within 2 x {sum(tight)};"
              f" {per}")
    if all("exact_tight" in r for r in rows):
        print("were the posterior exact, the share of units the tightest 90 % top brings within"
              " 2 x: " + ", ".join(
                  f"{k} {np.mean([r['exact_tight'] for r in rows if r['run'] == k]):.2f}"
                  for k in runs))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", choices=("dev", "eval"), default="dev")
    ap.add_argument("--designs", default="3,4")
    ap.add_argument("--fleet", type=int, default=20)
    ap.add_argument("--new", type=int, default=3)
    ap.add_argument("--out", default="out/probe-interval.json")
    ap.add_argument("--rules", metavar="JSON", help="print the rules on a written JSON")
    args = ap.parse_args(argv)
    if args.rules:
        with open(args.rules) as f:
            print_rules(json.load(f))
        return 0
    designs = [int(x) for x in args.designs.split(",")]
    if args.seeds == "dev" and any(d >= 10000 for d in designs):
        ap.error("development designs are 0-9999")
    rows = [row for d in designs for row in probe_design(d, args.fleet, args.new, RUNS)]
    with open(args.out, "w") as f:
        json.dump(rows, f, indent=1)
    print_rules(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
