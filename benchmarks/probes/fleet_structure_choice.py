"""Probe: which rule should choose the design's node count K, scored on new units' short runs.

For each design (development designs by default), the fleet and new units of
`fleet_down_ramps`; the design's prior learned at every K of `design_prior.K_CHOICES`
(forced), each new unit's short runs fitted under it (the law `train --prior` exports) and
scored on the test loop (whole loop; down-ramp). Beside them, per K, the scores a rule can
read from the fleet alone:
- `insample`: `choose_k`'s (the median over units of the window misfit of each unit's fit
  on its own full program);
- `loo`: leave one log out: each of the first `--loo-units` units fitted at K on all its
  logs but one (from its full-program fit's time constants), the held-out log's window
  misfit; summed over held-out logs, the median over units (`loo_c`: the held-out
  residual's mean taken out first: a log's offset is no structure);
- per held-out log too (`loo_<log>`), so that a rule on one log (the fastest) is read off;
- `ins_<log>`: `insample` on one log of the full program.
Every rule (the smallest K within a tolerance of the best score) is then a lookup into the
per-K test scores: printed per rule, with `oracle` (the K whose loop2h test is best per
design; no rule can read it).

    python -m benchmarks.probes.fleet_structure_choice --designs 3,4,10,15,17,19,21,22
"""

from __future__ import annotations

import json
import time

import numpy as np

from benchmarks.fleet import FULL, NEW_FIRST, fleet_series, simulate_run
from benchmarks.probes.fleet_down_ramps import RUNS, line_options, report, score_prior
from fogsf.prior import design_prior as fp
from fogsf.prior.unit_fit import StepSeries, UnitFit, fit_unit, step_series, window_means

TOLERANCES = (0.0, 0.02, 0.03, 0.05, 0.1)


def log_subset(series: StepSeries, keep: list[int]) -> StepSeries:
    """The unit's step series on the logs `keep` only (indices into its logs)."""
    sizes = [t.size for t in series.t_rel]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    ys, rows, base = [], [], 0
    for i in keep:
        m = (series.rows >= starts[i]) & (series.rows < starts[i + 1])
        ys.append(series.y[m])
        rows.append(series.rows[m] - starts[i] + base)
        base += sizes[i]
    return StepSeries([series.t_rel[i] for i in keep], np.concatenate(ys),
                      np.concatenate(rows), series.step_s)


def held_out(series: StepSeries, fit: UnitFit, k: int) -> tuple[list[float], list[float]]:
    """Per log: the window misfit (ppm^2) of the unit refitted at K without that log on the
    log itself, and the same with the held-out residual's mean taken out."""
    n = len(series.t_rel)
    raw, centred = [], []
    for i in range(n):
        train = log_subset(series, [j for j in range(n) if j != i])
        test = log_subset(series, [i])
        f = fit_unit(train, k, fit.taus_s)
        r = test.y - fp.predict(test, f.theta, k)
        means, _ = window_means(r, test.step_s)
        raw.append(float(np.mean(means**2)))
        centred.append(float(np.mean((means - means.mean()) ** 2)))
    return raw, centred


def in_sample(series: StepSeries, fit: UnitFit, k: int) -> list[float]:
    """Per log: the window misfit (ppm^2) of the unit's own full-program fit on that log."""
    out = []
    for i in range(len(series.t_rel)):
        test = log_subset(series, [i])
        means, _ = window_means(test.y - fp.predict(test, fit.theta, k), test.step_s)
        out.append(float(np.mean(means**2)))
    return out


def new_scores(prior: fp.DesignPrior, new: list[dict]) -> list[dict]:
    """`fleet_down_ramps.score_prior`'s rows, the whole loop and its down-ramp kept."""
    return [{k: r[k] for k in ("unit", "run", "all", "down")} for r in score_prior(prior, new)]


def probe_design(design: int, n_fleet: int, n_new: int, loo_units: int) -> dict:
    t0 = time.perf_counter()
    series = fleet_series(design, n_fleet)
    t1 = time.perf_counter()
    first = {k: {sn: fit_unit(s, k) for sn, s in series.items()} for k in fp.K_CHOICES}
    k_now, insample = fp.choose_k(series, first)
    per_log = {k: [in_sample(series[sn], first[k][sn], k) for sn in sorted(series)]
               for k in fp.K_CHOICES}
    t2 = time.perf_counter()
    names = sorted(series)[:loo_units]
    loo: dict[int, dict] = {}
    for k in fp.K_CHOICES:
        per = [held_out(series[sn], first[k][sn], k) for sn in names]
        loo[k] = {"raw": [p[0] for p in per], "centred": [p[1] for p in per]}
    t3 = time.perf_counter()
    new = [{"unit": u, "test": simulate_run(design, u, "loop_test"),
            **{r: step_series([simulate_run(design, u, r)]) for r in RUNS}}
           for u in range(NEW_FIRST, NEW_FIRST + n_new)]
    tests, plays = {}, {}
    for k in fp.K_CHOICES:
        prior = fp.learn(series, k, first)
        plays[k] = prior.as_dict()["play"]
        tests[k] = new_scores(prior, new)
    out = {"design": design, "k_now": k_now, "insample": insample, "loo": loo,
           "per_log": per_log,
           "tests": tests, "plays": plays,
           "seconds": {"sim": t1 - t0, "first_fits": t2 - t1,
                       "loo": t3 - t2, "total": time.perf_counter() - t0}}
    sc = scores(out)
    print(f"design {design}: K now {k_now}; " + "; ".join(
        f"{name} " + " ".join(f"{s:.3g}" for s in v.values()) for name, v in sc.items())
        + f" ({out['seconds']['total']:.0f} s, loo {t3 - t2:.0f} s, fits {t2 - t1:.0f} s)",
        flush=True)
    for k in fp.K_CHOICES:
        print(f"  K {k} play {plays[k]}: " + " ".join(
            f"{x['run']} {x['all']:.2f} ({x['down']:.2f})" for x in tests[k]), flush=True)
    return out


def scores(d: dict) -> dict[str, dict[int, float]]:
    """Each rule's score per K for a design's results (lower better)."""
    ks = [int(k) for k in d["loo"]]
    loo = {int(k): v for k, v in d["loo"].items()}
    out = {"insample": {int(k): float(v) for k, v in d["insample"].items()},
           "loo": {k: float(np.median(np.sum(loo[k]["raw"], axis=1))) for k in ks},
           "loo_c": {k: float(np.median(np.sum(loo[k]["centred"], axis=1))) for k in ks}}
    for i, name in enumerate(FULL):
        out[f"loo_{name}"] = {k: float(np.median(np.asarray(loo[k]["raw"])[:, i]))
                              for k in ks}
    if "per_log" in d:  # in sample, per log of the full program
        pl = {int(k): np.asarray(v) for k, v in d["per_log"].items()}
        for i, name in enumerate(FULL):
            out[f"ins_{name}"] = {k: float(np.median(pl[k][:, i])) for k in ks}
    return out


def pick(score: dict[int, float], tol: float) -> int:
    best = min(score.values())
    return min(k for k, s in score.items() if s <= best * (1.0 + tol))


def table(results: list[dict]) -> None:
    rules: dict[str, list[int]] = {}
    for name in scores(results[0]):
        for tol in TOLERANCES:
            rules[f"{name}@{tol:g}"] = [pick(scores(d)[name], tol) for d in results]
    for k in fp.K_CHOICES:
        rules[f"K={k}"] = [k for _ in results]
    rules["oracle"] = [min(fp.K_CHOICES, key=lambda k, d=d: float(np.median(
        [x["all"] for x in d["tests"][k] if x["run"] == "loop2h"])) + float(np.max(
            [x["all"] for x in d["tests"][k] if x["run"] == "loop2h"]))) for d in results]
    print("test RMS / floor, median / worst over the new units (whole loop), per rule; "
          "the K it picks per design")
    for rule, ks in rules.items():
        cells = []
        for r in RUNS:
            a = np.asarray([x["all"] for d, k in zip(results, ks, strict=True)
                            for x in d["tests"][k] if x["run"] == r])
            cells.append(f"{r} {np.median(a):.2f} / {a.max():.2f}")
        print(f"  {rule:24s} {', '.join(cells)}  K {''.join(str(k) for k in ks)}")


def _loaded(d: dict) -> dict:
    """A design's results read back from --out's JSON (its K keys as ints again)."""
    return {**d, **{key: {int(k): v for k, v in d[key].items()}
                    for key in ("insample", "loo", "tests", "plays", "per_log") if key in d}}


def main(argv: list[str] | None = None) -> int:
    ap = line_options(__doc__)
    ap.add_argument("--loo-units", type=int, default=fp.PLAY_UNITS,
                    help="units whose logs are held out one at a time")
    ap.add_argument("--again", nargs="+", default=None,
                    help="the table again from earlier --out files (no fits)")
    args = ap.parse_args(argv)
    if args.again:
        results = [_loaded(d) for f in args.again for d in json.load(open(f))]
    else:
        results = [probe_design(int(d), args.fleet, args.new, args.loo_units)
                   for d in args.designs.split(",")]
    return report(args, results, lambda: table(results))


if __name__ == "__main__":
    raise SystemExit(main())
