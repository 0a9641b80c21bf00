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

`--interval`: how tight an interval on the test RMS can be when the posterior is exactly
right. The unit's test error is then a draw e ~ N(0, P) (P the posterior covariance of its
test response); its test RMS over the floor A = sqrt(A0^2 + mean(e^2) / floor^2), A0 the
ratio with the exact truth removed. The tightest top that holds with 90 % is A's 90 %
quantile q; the chance that it is within 2 x the actual is P(A >= q / 2), averaged over
the units: the share of units any interval holding 90 % can bring within 2 x.

    python -m benchmarks.probes.fleet_bayes_oracle --designs 20000,20001 --units 60
    python -m benchmarks.probes.fleet_bayes_oracle --designs 20000,20001 --interval
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.fleet import NEW_FIRST, RUN_OFFSET, profile, simulate_run
from benchmarks.probes import ratio
from fogsf.logs.measure.metrics import log_metrics
from fogsf.models.reference import expand
from fogsf.prior.unit_fit import step_series
from fogsf.training.with_prior import test_series

ORACLE_FIRST = 1000
RUNS = ("loop2h", "up05")
DRAWS = 4000  # posterior draws of a unit's test error (--interval)


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


def interval_limit(test, clean: np.ndarray, pred: np.ndarray, cov: np.ndarray,  # noqa: ANN001
                   dec: int, seed: int) -> tuple[float, float]:
    """(the 90 % quantile of the unit's test ratio over the actual ratio, the chance that
    quantile is within 2 x the ratio) under the exact posterior: see the module's text."""
    floor = log_metrics(test)["noise_floor_ppm"]
    a0 = ratio(test, expand(clean, len(test), dec))
    ev, vec = np.linalg.eigh(0.5 * (cov + cov.T))
    root = vec * np.sqrt(np.maximum(ev, 0.0))
    e = np.random.default_rng(seed).standard_normal((DRAWS, root.shape[1])) @ root.T
    a = np.sqrt(a0**2 + np.mean(e**2, axis=1) / floor**2)
    q = float(np.quantile(a, 0.9))
    return q / ratio(test, expand(pred, len(test), dec)), float(np.mean(a >= q / 2))


def probe_design(design: int, n_units: int, n_new: int, interval: bool = False
                 ) -> dict[str, list[float]]:
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
            if interval:
                pa = np.linalg.inv(ds @ ds.T / s2 + np.eye(n_units))
                n = min(ts.rows.size, mt.size)
                cov = np.zeros((ts.rows.size, ts.rows.size))
                cov[:n, :n] = (dt.T @ pa @ dt)[:n, :n]
                clean = _fit(ts.rows.size, clean_steps(design, u, "loop_test"))
                top, tight = interval_limit(test, clean, pred, cov, dec, u)
                out.setdefault(f"{run} top/actual", []).append(top)
                out.setdefault(f"{run} P(top<=2x)", []).append(tight)
    print(f"design {design}: " + ", ".join(f"{r} " + " ".join(f"{v:.2f}" for v in out[r])
                                           for r in RUNS), flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", default="20000,20001")
    ap.add_argument("--units", type=int, default=60, help="noise-free units of the design")
    ap.add_argument("--new", type=int, default=3, help="new units per design")
    ap.add_argument("--interval", action="store_true",
                    help="also the tightest interval holding 90 %% under the exact posterior")
    args = ap.parse_args(argv)
    rows: dict[str, list[float]] = {}
    for d in (int(x) for x in args.designs.split(",")):
        for key, v in probe_design(d, args.units, args.new, args.interval).items():
            rows.setdefault(key, []).extend(v)
    print(f"designs {args.designs}, the linear Bayes estimate under {args.units} noise-free "
          "units: test RMS / floor, median / worst")
    for key, v in rows.items():
        if key.endswith("x)"):  # a chance per unit: its mean is the share of units
            print(f"  {key:20s} mean {np.mean(v):5.2f} (min {min(v):.2f})")
        else:
            print(f"  {key:20s} {np.median(v):5.2f} / {max(v):5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
