"""Probe: which step of the fit under the design's prior loses what a short run holds.

For each design (development designs by default), the fleet and the new units of
`fleet_down_ramps` (fleet on the full program of `make bench-fleet`, new units 100..),
each new unit's short runs fitted under the prior, scored on the test loop as
`fleet_down_ramps` scores it (whole loop and per segment). Variants, each one step away
from what `train --prior` exports (`law`: `function_fit(...).law()` at NOISE_SCALE):
- `post`: the posterior mean response read on the test log directly (no law refitted);
- `map`: the MAP of the parameters (`map_fit`);
- `ns1`, `ns2`, `ns6`, `ns10`: the law at a noise scale of 1, 2, 6, 10;
- `D`, `J`: the basis of the units' deviations only, the Jacobian's only;
- `lp1`, `lu03`: the weights (LAM_UNITS, LAM_PARAMS) at (1, 1) and (0.3, 0.3);
- `tn1`, `tn3` (`--true-noise`): the law at the run's true noise variance (from its
  noise-free twin) times 1 and 3; `s2_ratio` the unit's estimate (`map_fit`) over it;
- `own_run`, `law_run` (`--true-noise`): on the short run itself, what the design's
  structure fitted to the unit's full program leaves, and the exported law (over the floor);
- `lawown`: the law fitted to the posterior mean on the unit's own runs only (no reference);
- `lawmap`: the law's fit started from the MAP's time constants as well (the better kept);
- `lawtest` (an oracle): the law fitted to the posterior mean on the test loop itself (what
  the law's form loses where the posterior mean is right);
- `own`, `bayes` (`--bayes N`): the references of `fleet_down_ramps`.
`--k K`: the design's structure at K nodes whatever `learn` would choose.

    python -m benchmarks.probes.fleet_prior_steps --designs 3,4,10,15,17,19,21,22
    python -m benchmarks.probes.fleet_prior_steps --designs 19,15,17,3 --runs loop2h,up05 \\
        --true-noise
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks.fleet import FULL, NEW_FIRST, fleet_series, simulate_run
from benchmarks.probes.fleet_down_ramps import (
    bayes_rows,
    line_options,
    own_fit,
    report,
    split,
)
from fogsf.models.reference import expand
from fogsf.prior import design_prior as fp
from fogsf.prior.map_estimate import map_fit
from fogsf.prior.response_prior import FunctionFit, function_fit
from fogsf.prior.unit_fit import StepSeries, all_steps, fit_unit, step_series
from fogsf.training.with_prior import law_prediction, test_series

RUNS = ("loop2h", "up05", "up20", "loop4h")
VARIANTS = ("own", "bayes", "law", "post", "map", "ns1", "ns2", "ns6", "ns10", "D", "J",
            "lp1", "lu03", "tn1", "tn3", "lawown", "lawmap", "lawtest",
            "own_run", "law_run", "s2_ratio")


def _law_on(ff: FunctionFit, runs: list[np.ndarray], starts: list[np.ndarray]) -> np.ndarray:
    """The design's structure fitted to the posterior mean on `runs` (temperature series at
    the fit's step), from each start in `starts`; the fit with the least SSE."""
    p = ff.prior
    ref = all_steps(StepSeries(runs, np.zeros(0), np.zeros(0, dtype=np.int64), ff.own.step_s))
    ref.y = ff.predict(ref)
    fits = [fit_unit(ref, p.k, np.exp(s), p.play) for s in starts]
    return min(fits, key=lambda f: f.sse).theta


def true_noise(design: int, unit: int, run: str, series: StepSeries) -> float:
    """The variance of the run's noise per step (the run less its noise-free twin)."""
    from benchmarks.probes.fleet_bayes_oracle import _fit, clean_steps

    return float(np.var(series.y - _fit(series.y.size, clean_steps(design, unit, run))))


def unit_rows(prior: fp.DesignPrior, u: dict, run: str, design: int = -1
              ) -> dict[str, dict]:
    """Every variant's split on the unit's test loop for its run `run` (`design` >= 0: the
    `tn` variants too, at the run's true noise)."""
    ss, test = u[run], u["test"]
    ts, dec = test_series(test, ss.step_s, None)
    k, play = prior.k, prior.play

    def law(theta: np.ndarray) -> dict:
        return split(test, law_prediction(theta, k, test, ss.step_s, play))

    def post(ff: FunctionFit) -> dict:
        return split(test, expand(ff.predict(ts), len(test), dec))

    mf = map_fit(ss, prior)
    ff = function_fit(ss, prior, mf.s2)
    if "logs" in u:  # on the run itself: the unit's own structure, and the exported law
        lg = u["logs"][run]
        out_run = {f"{n}_run": {"all": split(lg, law_prediction(th, k, lg, ss.step_s, play))[
            "all"]} for n, th in (("own", u["own_theta"]), ("law", ff.law()))}
    out = {"law": law(ff.law()), "post": post(ff), "map": law(mf.theta)}
    for name, kw in (("ns1", {"noise_scale": 1.0}), ("ns2", {"noise_scale": 2.0}),
                     ("ns6", {"noise_scale": 6.0}), ("ns10", {"noise_scale": 10.0}),
                     ("D", {"lam": (1.0, 0.0)}), ("J", {"lam": (0.0, 0.3)}),
                     ("lp1", {"lam": (1.0, 1.0)}), ("lu03", {"lam": (0.3, 0.3)})):
        out[name] = law(function_fit(ss, prior, mf.s2, **kw).law())
    if "logs" in u:
        out.update(out_run)
    if design >= 0:
        s2 = true_noise(design, u["unit"], run, ss)
        out["s2_ratio"] = {"all": mf.s2 / s2}  # the estimate over the truth
        for name, ns in (("tn1", 1.0), ("tn3", 3.0)):
            out[name] = law(function_fit(ss, prior, s2, noise_scale=ns).law())
    ref = list(prior.reference.t_rel) if prior.reference is not None else []
    mu_t = prior.mu[:k]
    if run == "loop2h":  # the law's own variants: one run is enough to see them
        out["lawown"] = law(_law_on(ff, list(ss.t_rel), [mu_t]))
        out["lawmap"] = law(_law_on(ff, ref + list(ss.t_rel), [mu_t, mf.theta[:k]]))
        out["lawtest"] = law(_law_on(ff, list(ts.t_rel), [mu_t]))
    for v in out.values():
        v.setdefault("down", float("nan"))
        v["disagrees"] = bool(mf.disagrees)
    return out


def probe_design(design: int, n_fleet: int, n_new: int, runs: tuple[str, ...],
                 n_bayes: int, noise: bool = False, k: int | None = None) -> dict:
    t0 = time.perf_counter()
    series = fleet_series(design, n_fleet)
    prior = fp.learn(series, k)
    new = [{"unit": u, "test": simulate_run(design, u, "loop_test"),
            "full": step_series([simulate_run(design, u, r) for r in FULL]),
            **{r: step_series([simulate_run(design, u, r)]) for r in runs}}
           for u in range(NEW_FIRST, NEW_FIRST + n_new)]
    variants: dict[str, list[dict]] = {}
    for u in new:
        if noise:  # the diagnostics on the run itself
            u["logs"] = {r: simulate_run(design, u["unit"], r) for r in runs}
            u["own_theta"] = fit_unit(u["full"], prior.k, np.exp(prior.mu[:prior.k]),
                                      prior.play).theta
        for r in runs:
            for v, row in unit_rows(prior, u, r, design if noise else -1).items():
                variants.setdefault(v, []).append({"unit": u["unit"], "run": r, **row})
    own = own_fit(prior, new)
    variants["own"] = [{**x, "run": r} for x in own[::2] for r in runs]
    if n_bayes:
        variants["bayes"] = bayes_rows(design, new, n_bayes)
    out = {"design": design, "k": prior.k, "play": prior.as_dict()["play"],
           "variants": variants, "seconds": time.perf_counter() - t0}
    print(f"design {design}: K {prior.k}, play {out['play']} ({out['seconds']:.0f} s)",
          flush=True)
    for v in VARIANTS:
        if v in variants:
            print(f"  {v:9s} " + " ".join(f"{x['run']} {x['all']:.2f} (down {x['down']:.2f})"
                                          for x in variants[v]), flush=True)
    return out


def table(results: list[dict], runs: tuple[str, ...]) -> None:
    print("test RMS / floor, median / worst over the new units (whole loop; down-ramp)")
    for r in runs:
        for v in VARIANTS:
            rows = [x for d in results for x in d["variants"].get(v, []) if x["run"] == r]
            if not rows:
                continue
            a = np.asarray([x["all"] for x in rows])
            d = np.asarray([x["down"] for x in rows])
            print(f"  {r:6s} {v:9s} {np.median(a):.2f} / {a.max():.2f}; down "
                  f"{np.median(d):.2f} / {d.max():.2f}")


def main(argv: list[str] | None = None) -> int:
    ap = line_options(__doc__)
    ap.add_argument("--runs", default=",".join(RUNS))
    ap.add_argument("--true-noise", action="store_true",
                    help="the `tn` variants (the run's true noise; a noise-free twin each)")
    ap.add_argument("--k", type=int, default=None,
                    help="the design's node count (default: as `learn` chooses it)")
    args = ap.parse_args(argv)
    runs = tuple(args.runs.split(","))
    results = [probe_design(int(d), args.fleet, args.new, runs, args.bayes, args.true_noise,
                             args.k)
               for d in args.designs.split(",")]
    return report(args, results, lambda: table(results, runs))


if __name__ == "__main__":
    raise SystemExit(main())
