"""GSA at hyper-parameter-search budgets: which settings to use for a few hundred evaluations.

Rashedi's G0 = 100, alpha = 20 are tuned for T = 1000 iterations on boxes 2.56..200 wide;
a GSA-LSTM search runs tens of iterations over the paper's Table 1 space (batch size,
layers, hidden units: ints; learning rate: log-real). This benchmark draws synthetic
problems over exactly that space (each parameter scaled to [0, 1], ints rounded as GSA
rounds them) and compares, at the same number of fitness evaluations:

- random search (uniform in the same search box),
- GSA with the defaults (search coordinates as they are, G0 = 100, alpha = 20),
- GSA with ``normalize=True`` (every parameter mapped to [0, 1]) and several G0, alpha.

Problems: a bowl sum (u - c)^2 and a rotated ellipsoid (condition 100), random centre c,
each drawn from a seeded generator. Figure: the best fitness found, mean and median over
problems (the optimum is 0 up to integer rounding).

    python -m benchmarks.probes.gsa_short_budget [--problems 40] [--budgets 8x8 10x20 20x30]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from fogsf.gsa.optimizer import Param, Space, minimize

SPACE = [Param("batch_size", 8, 256, "int"), Param("layers", 1, 4, "int"),
         Param("hidden", 8, 256, "int"), Param("lr", 1e-4, 1e-1, "log-real")]
LOW = np.array([8.0, 1.0, 8.0, -4.0])
HIGH = np.array([256.0, 4.0, 256.0, -1.0])


class Problem:
    """f(values) on the unit-scaled parameters; picklable, vectorised over agents."""

    def __init__(self, kind: str, rng: np.random.Generator) -> None:
        self.kind = kind
        self.centre = rng.random(4)
        q, _ = np.linalg.qr(rng.normal(size=(4, 4)))
        scales = np.logspace(0, 1, 4) if kind == "ellipsoid" else np.ones(4)   # cond 100
        self.a = q * scales if kind == "ellipsoid" else np.eye(4)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        z = np.array(values, dtype=np.float64)
        z[:, 3] = np.log10(z[:, 3])
        u = (z - LOW) / (HIGH - LOW)
        return np.sum(((u - self.centre) @ self.a) ** 2, axis=1)


def random_search(problem: Problem, n_evals: int, seed: int) -> float:
    space = Space(SPACE)
    u = np.random.default_rng(seed).random((n_evals, space.dim))
    return float(problem(space.decode(space.lo + u * (space.hi - space.lo))).min())


VARIANTS: list[tuple[str, dict]] = [
    ("GSA defaults (raw, G0=100, alpha=20)", {}),
    ("GSA normalize, G0=100, alpha=20", {"normalize": True}),
    ("GSA normalize, G0=1, alpha=5", {"normalize": True, "g0": 1.0, "alpha": 5.0}),
    ("GSA normalize, G0=3, alpha=5", {"normalize": True, "g0": 3.0, "alpha": 5.0}),
    ("GSA normalize, G0=3, alpha=2", {"normalize": True, "g0": 3.0, "alpha": 2.0}),
    ("GSA normalize, G0=3, alpha=10", {"normalize": True, "g0": 3.0, "alpha": 10.0}),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.probes.gsa_short_budget",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=40, help="problems per kind (40)")
    ap.add_argument("--budgets", nargs="+", default=["8x8", "10x20", "20x30"],
                    help="AGENTSxITERATIONS budgets (8x8 10x20 20x30)")
    ap.add_argument("--seed", type=int, default=7, help="seed of the problem draw (7)")
    ap.add_argument("--out", default="out/gsa_short_budget.json", help="JSON output path")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    problems = [Problem(kind, rng) for kind in ("bowl", "ellipsoid")
                for _ in range(args.problems)]
    rows = []
    for budget in args.budgets:
        n_agents, n_iters = (int(v) for v in budget.lower().split("x"))
        runs = {"random search": [random_search(p, n_agents * n_iters, 1000 + i)
                                  for i, p in enumerate(problems)]}
        for name, kw in VARIANTS:
            runs[name] = [minimize(p, SPACE, n_agents=n_agents, n_iters=n_iters, seed=1000 + i,
                                   vectorized=True, progress=False, **kw).best_fitness
                          for i, p in enumerate(problems)]
        print(f"\n{n_agents} agents x {n_iters} iterations = {n_agents * n_iters} evaluations, "
              f"{len(problems)} problems (bowl + ellipsoid)")
        print(f"  {'method':<40} {'mean':>8} {'median':>8} {'bowl':>8} {'ellips.':>8}")
        for name, vals in runs.items():
            v = np.asarray(vals)
            half = args.problems
            row = {"budget": budget, "method": name, "mean": float(v.mean()),
                   "median": float(np.median(v)), "bowl_mean": float(v[:half].mean()),
                   "ellipsoid_mean": float(v[half:].mean())}
            rows.append(row)
            print(f"  {name:<40} {row['mean']:>8.4f} {row['median']:>8.4f} "
                  f"{row['bowl_mean']:>8.4f} {row['ellipsoid_mean']:>8.4f}")
    wall = time.perf_counter() - t0
    print(f"wall time {wall:.1f} s")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"problems_per_kind": args.problems, "seed": args.seed,
                               "wall_s": wall, "rows": rows}, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
