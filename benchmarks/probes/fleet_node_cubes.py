"""Probe: what the design's structure missed on a 2 h loop: the cubes of its nodes.

The fleet's structure (`fogsf.prior.unit_fit`: T and K first-order lags of T, their
quadratic with every cross term, the cube of T, and now the nodes' cubes) fitted to a unit's
full program (the program of `make bench-fleet`'s fleet) predicts the unit's test loop,
which that program holds; without the nodes' cubes it can miss a 2 h loop at 2 C/min with
15 min soaks by several times the floor, and the unit's short run then pulls the prior's
law away from the test (development designs 5, 11, 12, 23: 4-10 x on the test). Per new
unit (100..) of each design, the structure at K nodes fitted to the full program by
variable projection, with the cube of T only (`base`, the structure before) and with the
cubes of every node as well (`cubes`, the structure `fogsf.fleet` fits; each part's law a
cubic of its own temperature, as the population's SF terms are), scored (test RMS / noise
floor) on the unit's 2 h loop (`loop2h`, never fitted) and on the test loop (`test`).

    python -m benchmarks.probes.fleet_node_cubes --designs 3,5,12,23 --new 2
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.fleet import FULL, NEW_FIRST, simulate_run
from benchmarks.probes import ratio
from fogsf.models.reference import expand
from fogsf.prior.unit_fit import (
    StepSeries,
    all_steps,
    design_matrix,
    fit_taus,
    fit_unit,
    step_series,
)
from fogsf.training.with_prior import test_series


def fit(s: StepSeries, k: int, cubes: bool) -> tuple[np.ndarray, np.ndarray]:
    """(time constants, coefficients) by variable projection from the structure's own fit."""
    taus = fit_taus(s, k, fit_unit(s, k).taus_s, node_cubes=cubes)
    return taus, np.linalg.lstsq(design_matrix(s, taus, node_cubes=cubes), s.y, rcond=None)[0]


def score(log, taus: np.ndarray, coef: np.ndarray, cubes: bool) -> float:  # noqa: ANN001
    s, dec = test_series(log, 5.0, None)
    x = design_matrix(all_steps(s), taus, node_cubes=cubes)
    return ratio(log, expand(x @ coef, len(log), dec))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", default="3,4,5,10,12,19,23")
    ap.add_argument("--new", type=int, default=2, help="new units per design")
    ap.add_argument("--nodes", default="2,3", help="node counts K")
    args = ap.parse_args(argv)
    ks = [int(x) for x in args.nodes.split(",")]
    rows: dict[str, list[float]] = {}
    print("test RMS / noise floor; the structure fitted to the unit's full program")
    for d in (int(x) for x in args.designs.split(",")):
        for u in range(NEW_FIRST, NEW_FIRST + args.new):
            full = step_series([simulate_run(d, u, r) for r in FULL])
            loop, test = simulate_run(d, u, "loop2h"), simulate_run(d, u, "loop_test")
            cells = []
            for k in ks:
                for tag, cubes in (("base", False), ("cubes", True)):
                    taus, coef = fit(full, k, cubes)
                    a, b = score(loop, taus, coef, cubes), score(test, taus, coef, cubes)
                    rows.setdefault(f"K {k} {tag} loop2h", []).append(a)
                    rows.setdefault(f"K {k} {tag} test", []).append(b)
                    cells.append(f"K{k} {tag} loop2h {a:.2f} test {b:.2f}")
            print(f"design {d} unit {u}: " + ", ".join(cells), flush=True)
    print(f"designs {args.designs}, {args.new} new units each: median / worst")
    for key, v in rows.items():
        print(f"  {key:20s} {np.median(v):5.2f} / {np.max(v):5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
