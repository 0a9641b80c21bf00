"""Would a per-feature range clamp help protocols (c) and (d)? (development gyros only)

The lag bank extrapolates its cubics where a test drives lag states outside the training
range (a down-ramp from a hot soak after up-ramp training). This fits the bank by least
squares as the default does and predicts the test log with each feature z clamped to its
training range [min, max] before the polynomial (every term, or the squares and cubes
only, the linear terms extrapolating), against no clamp: test RMS / noise floor.
A probe for the kernel change, not the kernel change.

    python -m benchmarks.probes.clamp_probe --first 1 --n 16
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from benchmarks.population import protocol_logs
from benchmarks.probes.structure_rules import bank_inputs, ratio
from fogsf.models.structures.lag_bank import fit_bank, n_curved
from fogsf.sim.population import DEV_SEEDS, gyro_for_seed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=16)
    ap.add_argument("--protocols", default="a,b,c,d,e")
    args = ap.parse_args(argv)
    seeds = range(args.first, args.first + args.n)
    if any(s not in DEV_SEEDS for s in seeds):
        ap.error("development seeds only")
    protocols = [p for p in args.protocols.split(",") if p]
    kinds = ("none", "clamp", "curved")
    res: dict[str, dict[str, list[float]]] = {p: {k: [] for k in kinds} for p in protocols}
    for seed in seeds:
        gyro = gyro_for_seed(seed)
        for p in protocols:
            train, test = protocol_logs(gyro, seed, p)
            ti, z, y, zt = bank_inputs(train, test)
            bank = fit_bank(z, y, curved=n_curved())
            lo, hi = z.min(axis=0), z.max(axis=0)
            zc = np.clip(zt, lo, hi)
            curved = (bank.intercept + zt @ bank.lin + (zc * zc) @ bank.quad
                      + (zc * zc * zc) @ bank.cube)
            for name, pred in (("none", bank.predict(zt)), ("clamp", bank.predict(zc)),
                               ("curved", curved)):
                res[p][name].append(ratio(test, pred * ti.scale + ti.offset))
        print(f"gyro {seed:>4} " + " ".join(
            f"{p}: " + "/".join(f"{res[p][k][-1]:.2f}" for k in kinds) for p in protocols),
            flush=True)
    print(f"development gyros {seeds.start}-{seeds.stop - 1}, test RMS / noise floor, "
          "median / p90 / worst: no clamp | every term clamped | curved terms clamped")
    for p in protocols:
        cells = []
        for name in kinds:
            v = np.asarray(res[p][name])
            cells.append(f"{np.median(v):.2f} / {np.percentile(v, 90):.2f} / {v.max():.1f}")
        print(f"  ({p}) " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
