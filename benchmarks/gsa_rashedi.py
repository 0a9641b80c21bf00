"""GSA against Rashedi et al. (2009) Table 4: F1..F7, N=50 agents, n=30 dimensions,
T=1000 iterations, mean best-so-far over 30 runs.

    python -m benchmarks.gsa_rashedi                    # the full Table 4 budget
    python -m benchmarks.gsa_rashedi --runs 5 --iters 200 --functions F1 F6

Prints ours beside the paper's figures, writes JSON (default out/gsa_rashedi.json) and a
plot of the mean best-so-far curves beside it. Runs are spread over local processes.
"""

from __future__ import annotations

import argparse
import json
import time
from functools import partial
from pathlib import Path

import numpy as np

from fogsf.gsa.executors import add_executor_options, default_workers, executor_from_args
from fogsf.gsa.optimizer import BOUNDS, Param, minimize
from fogsf.gsa.testfunctions import FUNCTIONS


def one_run(key: str, run: int, seed: int, n_agents: int, dim: int, n_iters: int,
            bounds: str) -> tuple[float, list[float]]:
    """One GSA run on one function: (best fitness, best-so-far curve)."""
    tf = FUNCTIONS[key]
    fn = tf.fn
    if tf.noisy:
        fn = partial(tf.fn, rng=np.random.default_rng([seed, run, 7]))
    space = [Param(f"x{i}", tf.low, tf.high) for i in range(dim)]
    res = minimize(fn, space, n_agents=n_agents, n_iters=n_iters, seed=[seed, run],
                   vectorized=True, progress=False, bounds=bounds)
    return res.best_fitness, res.best_curve


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.gsa_rashedi",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=30, help="independent runs per function (30)")
    ap.add_argument("--iters", type=int, default=1000, help="iterations T (1000)")
    ap.add_argument("--agents", type=int, default=50, help="agents N (50)")
    ap.add_argument("--dim", type=int, default=30, help="dimensions n (30)")
    ap.add_argument("--functions", nargs="+", default=list(FUNCTIONS), choices=list(FUNCTIONS),
                    metavar="F", help="which of F1..F7 (all)")
    ap.add_argument("--bounds", choices=BOUNDS, default="reflect",
                    help="how agents are kept in the box (reflect)")
    ap.add_argument("--seed", type=int, default=2009, help="base seed (2009)")
    add_executor_options(ap)
    ap.add_argument("--out", default="out/gsa_rashedi.json", help="JSON output path")
    ap.add_argument("--no-plot", action="store_true", help="skip the curve plot")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    jobs = [(k, r) for k in args.functions for r in range(args.runs)]
    results: dict[str, list[tuple[float, list[float]]]] = {k: [] for k in args.functions}
    from tqdm import tqdm

    with executor_from_args(args) as ex:
        call = partial(one_run, seed=args.seed, n_agents=args.agents, dim=args.dim,
                       n_iters=args.iters, bounds=args.bounds)
        if ex is None:
            outs = (call(k, r) for k, r in jobs)
        else:
            outs = (f.result() for f in [ex.submit(call, k, r) for k, r in jobs])
        for (k, _), out in tqdm(zip(jobs, outs, strict=True), total=len(jobs), unit="run",
                                desc="GSA F1-F7"):
            results[k].append(out)
    wall = time.perf_counter() - t0

    rows = []
    print(f"\nGSA, N={args.agents}, n={args.dim}, T={args.iters}, {args.runs} runs, "
          f"bounds={args.bounds}, seed={args.seed}: mean best-so-far (Rashedi 2009 Table 4)")
    print(f"{'':3} {'function':<20} {'paper':>10} {'ours mean':>11} {'median':>10} "
          f"{'std':>10} {'worst':>10}")
    for k in args.functions:
        best = np.array([b for b, _ in results[k]])
        curve = np.mean([c for _, c in results[k]], axis=0)
        tf = FUNCTIONS[k]
        row = {"function": k, "name": tf.name, "bounds": [tf.low, tf.high],
               "paper_mean": tf.paper_mean, "mean": float(best.mean()),
               "median": float(np.median(best)), "std": float(best.std(ddof=1))
               if best.size > 1 else 0.0, "best": float(best.min()),
               "worst": float(best.max()), "runs": best.tolist(),
               "mean_curve": curve.tolist()}
        rows.append(row)
        print(f"{k:3} {tf.name:<20} {tf.paper_mean:>10.3g} {row['mean']:>11.3g} "
              f"{row['median']:>10.3g} {row['std']:>10.3g} {row['worst']:>10.3g}")
    where = f"Dask at {args.dask}" if args.dask else \
        f"{args.workers or default_workers()} local worker(s)"
    print(f"wall time {wall:.1f} s with {where}")

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    settings = {"n_agents": args.agents, "dim": args.dim, "n_iters": args.iters,
                "runs": args.runs, "bounds": args.bounds, "seed": args.seed,
                "g0": 100.0, "alpha": 20.0, "final_kbest": 1, "wall_s": wall}
    out.write_text(json.dumps({"settings": settings, "functions": rows}, indent=1) + "\n")
    print(f"wrote {out}")
    if not args.no_plot:
        print(f"wrote {plot_curves(rows, out.with_suffix('.png'), settings)}")
    return 0


def plot_curves(rows: list[dict], path: Path, settings: dict) -> Path:
    """Mean best-so-far vs iteration per function, with the paper's final figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(rows)
    cols = min(4, n)
    fig, axes = plt.subplots((n + cols - 1) // cols, cols, figsize=(3.2 * cols, 2.6 *
                             ((n + cols - 1) // cols)), dpi=110, squeeze=False)
    for ax, row in zip(axes.flat, rows, strict=False):
        c = np.asarray(row["mean_curve"])
        it = np.arange(1, c.size + 1)
        ax.plot(it, c, lw=1.5, label="ours")
        ax.axhline(row["paper_mean"], color="C3", ls="--", lw=1, label="Rashedi 2009")
        if (c > 0).all():
            ax.set_yscale("log")
        elif (c >= 0).all():
            ax.set_yscale("symlog", linthresh=1.0)
            ax.set_ylim(bottom=0.0)
        ax.set_title(f"{row['function']} {row['name']}", fontsize=9)
        ax.set_xlabel("iteration", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    axes.flat[0].legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle(f"GSA mean best-so-far, N={settings['n_agents']}, n={settings['dim']}, "
                 f"{settings['runs']} runs", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


if __name__ == "__main__":
    raise SystemExit(main())
