"""Probe: the design's prior in the space of responses against the MAP of the parameters.

For each design (development designs by default: tuning belongs there), a fleet of units on
the full program of `make bench-fleet`, the design's prior learned from it
(`fogsf.prior.design_prior.learn`), new units 100.. on a 2 h loop and on one 0.5 C/min ramp,
scored on the test loop (1 C/min up, 1.5 down; test RMS / noise floor):
- `map`: the MAP of the parameters (`prior_map.map_fit`, the fit before the response prior);
- `resp U,P`: the posterior mean response (`prior_function`) with weights LAM_UNITS = U on
  the fleet's responses and LAM_PARAMS = P on the parametric spread; `law` the exported law
  at the module's weights; `law noise N` with the short run's noise variance taken N times
  the unit's own estimate (NOISE_SCALE: `law`);
- `span`: the response prior given the unit's FULL program (the basis's reach);
- `interval held`: units whose law's figure is at or under the interval's upper end, without
  the misfit on the unit's runs, with it, and with INTERVAL_Z^2 x it (`train --prior`'s);
- `oracle`: the design's structure fitted to the unit's full program.

    python -m benchmarks.probes.fleet_response_prior --designs 3,4,10,15,21,22 --fleet 20
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.fleet import FULL, NEW_FIRST, simulate_run
from benchmarks.probes import ratio
from fogsf.logs.measure.metrics import log_metrics
from fogsf.models.reference import expand
from fogsf.prior import design_prior as fp
from fogsf.prior import response_prior as pf
from fogsf.prior.map_estimate import map_fit
from fogsf.prior.unit_fit import fit_unit, step_series
from fogsf.training.with_prior import INTERVAL_Z, law_prediction, test_series

WEIGHTS = ((1.0, 0.0), (1.0, 0.3), (1.0, 1.0), (2.0, 0.3), (0.0, 1.0))
NOISE_SCALES = (1.0, 10.0)


def probe_design(design: int, n_fleet: int, n_new: int) -> dict[str, list[float]]:
    fleet = {f"u{u}": step_series([simulate_run(design, u, r) for r in FULL])
             for u in range(n_fleet)}
    prior = fp.learn(fleet)
    k = prior.k
    print(f"design {design}: {k} nodes, play {prior.as_dict()['play']}", flush=True)
    out: dict[str, list[float]] = {}
    for u in range(NEW_FIRST, NEW_FIRST + n_new):
        test = simulate_run(design, u, "loop_test")
        ts, dec = test_series(test, 5.0, None)

        def score(g: np.ndarray) -> float:
            return ratio(test, expand(g, len(test), dec))  # noqa: B023

        full = step_series([simulate_run(design, u, r) for r in FULL])
        alone_full = fit_unit(full, k, np.exp(prior.mu[:k]), prior.play)
        out.setdefault("oracle", []).append(ratio(test, law_prediction(
            alone_full.theta, k, test, play=prior.play)))
        out.setdefault("span", []).append(score(pf.function_fit(full, prior, alone_full.sigma2)
                                                .predict(ts)))
        for run in ("loop2h", "up05"):
            s = step_series([simulate_run(design, u, run)])
            mf = map_fit(s, prior)
            out.setdefault(f"{run} map", []).append(ratio(test, law_prediction(
                mf.theta, k, test, play=prior.play)))
            ff = pf.function_fit(s, prior, mf.s2)
            law = ratio(test, law_prediction(ff.law(), k, test, play=prior.play))
            out.setdefault(f"{run} law", []).append(law)
            for n in NOISE_SCALES:
                out.setdefault(f"{run} law noise {n:g}", []).append(ratio(test, law_prediction(
                    pf.function_fit(s, prior, mf.s2, noise_scale=n).law(), k, test,
                    play=prior.play)))
            floor2 = log_metrics(test)["noise_floor_ppm"] ** 2
            var, mis = float(np.mean(ff.variance(ts))), ff.misfit_ppm2()
            z2 = INTERVAL_Z**2
            for name, extra in (("interval", 0.0), ("interval+misfit", mis),
                                ("interval+4 misfit", z2 * mis)):
                upper = np.sqrt(1.0 + (z2 * var + extra) / floor2)
                out.setdefault(f"{run} {name} held", []).append(float(law <= upper))
            for w in WEIGHTS:
                out.setdefault(f"{run} resp {w[0]:g},{w[1]:g}", []).append(
                    score(pf.function_fit(s, prior, mf.s2, w).predict(ts)))
        print(f"design {design} unit {u} done", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", default="3,4,10,15,21,22")
    ap.add_argument("--fleet", type=int, default=20, help="units on the full program")
    ap.add_argument("--new", type=int, default=3, help="new units per design")
    args = ap.parse_args(argv)
    rows: dict[str, list[float]] = {}
    for d in (int(x) for x in args.designs.split(",")):
        for key, v in probe_design(d, args.fleet, args.new).items():
            rows.setdefault(key, []).extend(v)
    print(f"designs {args.designs}, fleet of {args.fleet}, {args.new} new units each: "
          "test RMS / floor, median / worst")
    for key in sorted(rows):
        v = np.asarray(rows[key])
        if key.endswith(" held"):
            print(f"  {key:22s} {int(v.sum())} of {v.size}")
        else:
            print(f"  {key:22s} {np.median(v):5.2f} / {v.max():5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
