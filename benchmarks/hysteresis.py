"""SF hysteresis: the default (its hysteresis term when the logs ask for it) against the same
model without the term and with it always (`make bench-hysteresis`).

Gyros come from the population (`fogsf.sim.population`): a share draws a play
operator of the coil temperature in its SF (`hysteresis_for_seed`: widths 4-10 C,
strengths 3-8 ppm/C). Every model trains on the partial-cycle program `partial_train`
(reversals inside -40..50 C, legs at 2 and 0.75 C/min, 6.3 h) and is tested on
`partial_test` (other turns, 1 C/min, 5.8 h; `fogsf.sim.partial_cycles`), scored as
the test RMS after compensation over the noise floor. Three groups of gyros:

  hyst       the first N gyros from --first that draw hysteresis
  same-flat  the same gyros without their hysteresis (the ceiling the term aims at)
  flat       the first N gyros from --first that draw none (the term must not hurt them)

Models: `auto` (lag-lstm, the structure chosen by the logs, the hysteresis term when the
logs' held-out blocks say so: what `fogsf train` fits by default), `off` (the same with
`--hysteresis off`) and `on` (`--hysteresis on`: the term always, what it can
capture when the check does not hold it back). With --kernel, the first case whose `auto`
model carries the play is trained again and replayed through
the C kernel (its SF output must equal the numpy reference bit for bit, and the ratio is
reported from the kernel's output).

Tune on development gyros (--seeds dev), report on evaluation gyros (--seeds eval):

    python -m benchmarks.hysteresis --seeds eval --n 12 --out out/bench-hysteresis.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fogsf.gsa.executors import add_executor_options, executor_from_args, run_all

MODELS = {"auto": "auto", "off": "off", "on": "on"}
GROUPS = ("hyst", "same-flat", "flat")
TRAIN_OFFSET, TEST_OFFSET = 8, 9  # run seeds gyro_seed * 16 + offset (population's: 1-7)


def partial_configs(seed: int, group: str) -> tuple:
    """The gyro of `seed` (with its SF hysteresis for group "hyst", without for the others)
    and its runs of the partial-cycle training and test programs: (gyro, train config, test
    config)."""
    from fogsf.sim.partial_cycles import PARTIAL_TEST, PARTIAL_TRAIN
    from fogsf.sim.population import gyro_for_seed, run_on_gyro

    gyro = gyro_for_seed(seed, hysteresis=group == "hyst")
    train, test = (run_on_gyro(gyro, prog.profile(), seed * 16 + off, prog.name)
                   for prog, off in ((PARTIAL_TRAIN, TRAIN_OFFSET), (PARTIAL_TEST, TEST_OFFSET)))
    return gyro, train, test


def partial_runs(seed: int, group: str) -> tuple:
    """`partial_configs` simulated: (gyro, train log, test log)."""
    from fogsf.sim import simulate

    gyro, train, test = partial_configs(seed, group)
    return gyro, simulate(train).log, simulate(test).log


def case(item: tuple[int, str], kernel: bool = False) -> dict:
    """Every model on one (gyro seed, group) (one unit of work)."""
    import torch

    from fogsf.sim.population import hysteresis_for_seed
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    torch.set_num_threads(1)
    seed, group = item
    t0 = time.perf_counter()
    gyro, train, test = partial_runs(seed, group)
    h = hysteresis_for_seed(seed)
    out: dict = {"gyro_seed": seed, "group": group, "gyro": gyro.scenario,
                 "hysteresis": ({"strength_ppm_per_c": h.strength, **h.params}
                                if h is not None and group == "hyst" else None),
                 "models": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name, mode in MODELS.items():
            opts = TrainOptions(model="lag-lstm", seed=seed, progress=False, workers=1,
                                transfer_check=False, hysteresis=mode)
            m, fitted = run_training(opts, [train], test, Path(tmp) / name)
            floor = m["noise_floor_ppm"]
            row = {"ratio": m["test"]["after"]["rms_ppm"] / floor, "noise_floor_ppm": floor,
                   "structure": m.get("structure_choice", {}).get("chosen", "given"),
                   "hysteresis_choice": m.get("hysteresis_choice"),
                   "train_seconds": m["train_seconds"]}
            if kernel and name == "auto" and fitted.stream_model is not None:
                row["kernel"] = kernel_check(fitted.stream_model, test, floor)
            out["models"][name] = row
    out["seconds"] = time.perf_counter() - t0
    return out


def kernel_check(model, log, floor: float) -> dict:  # noqa: ANN001 - StreamModel, ChamberLog
    """The model through the C kernel over the test log: bit-for-bit SF against the numpy
    reference, and the test ratio from the kernel's own SF output."""
    from fogsf.bindings.kernel import Kernel
    from fogsf.logs.measure.metrics import log_metrics
    from fogsf.models import reference

    kern = Kernel(model)
    corrected, sf, _ = kern.run(log.temp_c, log.gyro_dps)
    ref = reference.replay(model, log.temp_c, log.gyro_dps)
    same = bool(np.array_equal(sf.view(np.uint32), ref.sf_ppm.view(np.uint32)))
    m = log_metrics(log, correction_ppm=sf.astype(np.float64))
    return {"bit_exact": same, "ratio": m["rms_ppm"] / floor, "n_plays": model.n_plays}


def pick_seeds(first: int, n: int, rng: range) -> dict[str, list[int]]:
    """The first n gyros from `first` with hysteresis, and the first n without."""
    from fogsf.sim.population import hysteresis_for_seed

    with_h: list[int] = []
    without: list[int] = []
    for s in range(first, rng.stop):
        (with_h if hysteresis_for_seed(s) is not None else without).append(s)
        if len(with_h) >= n and len(without) >= n:
            break
    return {"hyst": with_h[:n], "same-flat": with_h[:n], "flat": without[:n]}


def summarise(rows: list[dict]) -> dict:
    out: dict = {}
    for g in GROUPS:
        for name in MODELS:
            r = [x["models"][name]["ratio"] for x in rows if x["group"] == g]
            if r:
                out[f"{g}/{name}"] = {"median": float(np.median(r)), "worst": float(max(r)),
                                      "n": len(r)}
        used = [bool((x["models"]["auto"]["hysteresis_choice"] or {}).get("used"))
                for x in rows if x["group"] == g]
        if used:
            out[f"{g}/term_used"] = {"cases": len(used), "used": int(sum(used))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.hysteresis --seeds dev --n 4 "
               "--out out/bench-hysteresis-dev.json")
    ap.add_argument("--out", default="out/bench-hysteresis.json")
    ap.add_argument("--seeds", choices=["dev", "eval"], default="eval",
                    help="seed range: dev (tune here) or eval (report here)")
    ap.add_argument("--n", type=int, default=12, help="gyros per group")
    ap.add_argument("--first", type=int, default=None,
                    help="first gyro seed (default: the range's first, skipping the default "
                         "gyro's 0)")
    ap.add_argument("--groups", default=",".join(GROUPS))
    ap.add_argument("--kernel", action="store_true",
                    help="replay the first hyst gyro's default model through the C kernel")
    add_executor_options(ap, "gyros")
    args = ap.parse_args(argv)

    from fogsf.sim.population import seed_range

    groups = [g for g in args.groups.split(",") if g]
    if any(g not in GROUPS for g in groups) or args.n < 1:
        ap.error(f"--groups must be among {', '.join(GROUPS)} and --n >= 1")
    rng = seed_range(args.seeds)
    first = args.first if args.first is not None else max(rng.start, 1)
    if first not in rng:
        ap.error(f"--first {first} is outside the {args.seeds} range {rng}")
    seeds = pick_seeds(first, args.n, rng)
    items = [(s, g) for g in groups for s in seeds[g]]
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        rows = run_all(ex, case, items, False, desc="cases", unit="case")
    if args.kernel:  # the first case whose default carries the play, else the first hyst one
        used = [i for i, r in enumerate(rows)
                if (r["models"]["auto"]["hysteresis_choice"] or {}).get("used")]
        pick = used[:1] or [i for i, it in enumerate(items) if it[1] == "hyst"][:1]
        for i in pick:
            rows[i] = case(items[i], kernel=True)
    for r in rows:
        cells = "  ".join(f"{k} {v['ratio']:.3f}" for k, v in r["models"].items())
        term = (r["models"]["auto"]["hysteresis_choice"] or {}).get("term", {})
        print(f"gyro {r['gyro_seed']:>5} {r['group']:<9} {cells}  "
              f"{term.get('form', '')}", flush=True)
    summary = summarise(rows)
    print(f"test RMS / noise floor, trained on partial_train, tested on partial_test "
          f"({args.seeds} gyros from {first})")
    for key, s in summary.items():
        if key.endswith("term_used"):
            print(f"  {key:<22} term used in {s['used']} of {s['cases']}")
        else:
            print(f"  {key:<22} median {s['median']:.3f}  worst {s['worst']:.3f}  (n={s['n']})")
    kern = [r["models"]["auto"]["kernel"] for r in rows if "kernel" in r["models"]["auto"]]
    for k in kern:
        print(f"  C kernel replay: bit-exact {k['bit_exact']}, ratio {k['ratio']:.3f}, "
              f"{k['n_plays']} play(s)")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    seconds = time.perf_counter() - t0
    out.write_text(json.dumps({"seeds": args.seeds, "first": first, "groups": seeds,
                               "rows": rows, "summary": summary, "seconds": seconds},
                              indent=2) + "\n")
    print(f"-> {out} ({seconds:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
