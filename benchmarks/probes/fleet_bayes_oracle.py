"""Probe (an oracle): how far a new unit's short run can go with the design's TRUE unit prior.

The simulator knows how units of a design vary (`fogsf.sim.fleet_units`). N units of the
design (indices from 1000, never a bench's) are simulated without noise on the short run
and on the test loop of `make bench-fleet`: their exact SF error per 5 s step, as a
function of the chamber program. The new unit's test response is predicted from its
noisy short run by the best linear estimator under that sample of the true prior (the
Gaussian posterior with the N units' mean and covariance, the noise variance known
exactly): no structure, no fit of the fleet, no misfit. It does not use the unit's own
board temperature (a nonlinear estimator could do better), so it is a reference, not a
bound. It tunes nothing: it runs on evaluation designs too.

    python -m benchmarks.probes.fleet_bayes_oracle --designs 20000,20001 --units 60
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.fleet import NEW_FIRST, RUN_OFFSET, profile, simulate_run
from benchmarks.probes import ratio
from fogsf.models.reference import expand
from fogsf.prior.unit_fit import step_series
from fogsf.training.with_prior import test_series

ORACLE_FIRST = 1000
RUNS = ("loop2h", "up05")


def clean_steps(design: int, unit: int, name: str) -> np.ndarray:
    """The unit's exact SF error per model step on run `name` (no noise of any kind)."""
    from fogsf.sim import simulate
    from fogsf.sim.fleet_units import unit_for
    from fogsf.sim.population import run_on_gyro

    cfg = unit_for(design, unit)
    cfg.noise.arw_deg_per_sqrt_h = cfg.noise.pulse_arcsec = 0.0
    cfg.noise.temp_noise_c = cfg.noise.temp_lsb_c = 0.0
    seed = int(np.random.SeedSequence([design, unit, RUN_OFFSET[name]]).generate_state(1)[0])
    return step_series([simulate(run_on_gyro(cfg, profile(name), seed, name)).log]).y


def _fit(n: int, series: np.ndarray) -> np.ndarray:
    out = np.zeros(n)
    m = min(n, series.size)
    out[:m] = series[:m]
    return out


def probe_design(design: int, n_units: int, n_new: int) -> dict[str, list[float]]:
    units = range(ORACLE_FIRST, ORACLE_FIRST + n_units)
    test_y = np.stack([clean_steps(design, u, "loop_test") for u in units])
    mt = test_y.mean(axis=0)
    dt = (test_y - mt) / np.sqrt(n_units - 1)
    out: dict[str, list[float]] = {}
    for run in RUNS:
        ys = np.stack([clean_steps(design, u, run) for u in units])
        ms = ys.mean(axis=0)
        ds = (ys - ms) / np.sqrt(n_units - 1)
        for u in range(NEW_FIRST, NEW_FIRST + n_new):
            test = simulate_run(design, u, "loop_test")
            ts, dec = test_series(test, 5.0, None)
            y = _fit(ms.size, step_series([simulate_run(design, u, run)]).y)
            s2 = float(np.var(y - _fit(ms.size, clean_steps(design, u, run))))
            a = np.linalg.solve(ds @ ds.T / s2 + np.eye(n_units), ds @ (y - ms) / s2)
            pred = _fit(ts.rows.size, mt + dt.T @ a)
            out.setdefault(run, []).append(ratio(test, expand(pred, len(test), dec)))
    print(f"design {design}: " + ", ".join(f"{r} " + " ".join(f"{v:.2f}" for v in out[r])
                                           for r in RUNS), flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", default="20000,20001")
    ap.add_argument("--units", type=int, default=60, help="noise-free units of the design")
    ap.add_argument("--new", type=int, default=3, help="new units per design")
    args = ap.parse_args(argv)
    rows: dict[str, list[float]] = {}
    for d in (int(x) for x in args.designs.split(",")):
        for key, v in probe_design(d, args.units, args.new).items():
            rows.setdefault(key, []).extend(v)
    print(f"designs {args.designs}, the linear Bayes estimate under {args.units} noise-free "
          "units: test RMS / floor, median / worst")
    for key, v in rows.items():
        print(f"  {key:8s} {np.median(v):5.2f} / {max(v):5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
