"""The hysteresis check's held-out gain against what the term does on the test, least squares.

For development gyros with and without SF hysteresis (`benchmarks.hysteresis`'s groups and
partial-cycle programs), the structure the default takes on `partial_train` (`bank`: the
logs hold several segments) is fitted with and without the hysteresis term on every step,
and both predict `partial_test`; the check's held-out RMS with and without the term
(`training.structure.hysteresis.decide`) is recorded beside the two test ratios. Then, per
threshold on the held-out gain, how many gyros of each group keep the term and what the
test ratio does: what `HYST_GAIN` trades.

    python -m benchmarks.probes.hysteresis_gain --first 1 --n 40 --out out/hyst-gain.json
    python -m benchmarks.probes.hysteresis_gain --analyse out/hyst-gain.json
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from benchmarks.hysteresis import partial_runs, pick_seeds
from benchmarks.probes import StepScorer, finish

BASE = "bank"
THRESHOLDS = (0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.40)


def one(item: tuple[int, str]) -> dict:
    from fogsf.training.structure.heldout import fit_candidate, step_data
    from fogsf.training.structure.hysteresis import decide, fit_with_term

    seed, group = item
    _, train, test = partial_runs(seed, group)
    d = decide([train], BASE, 5.0)
    sd = step_data([train])
    every = np.arange(sd.y.size)
    on_test = StepScorer.of(test, sd.fe)
    out = {"seed": seed, "group": group, "without_heldout": d["heldout_rms_ppm"]["without"],
           "with_heldout": d["heldout_rms_ppm"]["with"]}
    for name, pred in (("without", fit_candidate(BASE, sd, every)),
                       ("with", fit_with_term(BASE, sd, every)[0])):
        out[name] = on_test(pred(on_test.nt))
    print(out, flush=True)
    return out


def analyse(rows: list[dict]) -> None:
    for g in ("hyst", "flat"):
        sub = [r for r in rows if r["group"] == g]
        gain = np.array([1 - r["with_heldout"] / r["without_heldout"] for r in sub])
        w, wo = np.array([r["with"] for r in sub]), np.array([r["without"] for r in sub])
        print(f"{g}: {len(sub)} gyros; test ratio without the term {np.median(wo):.3f} / "
              f"{wo.max():.3f}, always with it {np.median(w):.3f} / {w.max():.3f}")
        for t in THRESHOLDS:
            keep = gain > t
            r = np.where(keep, w, wo)
            worse = np.sum(keep & (w > 1.05 * wo))
            print(f"  gain > {t:.2f}: kept {keep.sum():3d}, median / worst {np.median(r):.3f} "
                  f"/ {r.max():.3f}, kept and > 5 % worse than without: {worse}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=12, help="gyros per group")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None)
    ap.add_argument("--analyse", default=None)
    args = ap.parse_args(argv)
    if args.analyse:
        with open(args.analyse) as fh:
            analyse(json.load(fh))
        return 0
    seeds = pick_seeds(args.first, args.n, range(0, 10_000))
    items = [(s, "hyst") for s in seeds["hyst"]] + [(s, "flat") for s in seeds["flat"]]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as ex:
        rows = list(ex.map(one, items))
    analyse(rows)
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
