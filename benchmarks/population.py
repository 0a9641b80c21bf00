"""Compensation on gyros it was not tuned on (`make bench-population`).

Gyros come from the population (`fogsf.sim.population`): development seeds 0-9999 (tune
there), evaluation seeds 20000-29999 (report there, never tune). For each gyro and each
protocol, every model is trained on the protocol's training logs and scored on its test log
(RMS and STD after compensation as multiples of the test log's noise floor); gsa-lstm, at a
small budget (3 agents x 2 iterations, 20-step fitness, 100-step final training), runs on
protocol a only (its search reaches 3 x 256 LSTMs: minutes a protocol on 2 cores), hyst-off
(the default without its hysteresis check) on e and f only (ramps never reach the check):

  a  train 0.5 C/min up-ramp                  test 1 C/min up-ramp (the paper)
  b  train 0.5 and 2 C/min up-ramps           test 1 C/min up-ramp
  c  train 0.5 and 2 C/min up-ramps           test 1 C/min down-ramp
  d  train 0.5 and 2 C/min up-ramps           test a slow cycle with soaks (0.5 C/min,
                                              45 min soaks, -40..50 C)
  e  train one loop: 1 C/min up, 2 C/min down, 30 min soaks (3.75 h)
                                              test 1 C/min up, 1.5 C/min down, 30 min soaks;
                                              its training log is scored too (e-train)
  f  the envelope: 0.5 and 2 C/min up-ramps,  test as (e)
     e's training loop and e's test program
     run again (other noise): training holds
     every test condition (the model's capacity)

All runs are -40..50 C, warm start, table at a constant 10 deg/s. The default model is what
`fogsf train` uses without --model. Its rate-transfer interval (metrics.json
`rate_transfer.rms_interval_ppm`) is checked against the error it actually leaves: the
coverage is the share of (gyro, protocol) cases inside it.

Gyros are independent work: they run on the project's executor (local processes by
default, `--dask SCHEDULER_ADDRESS` for a cluster).

    python -m benchmarks.population --seeds eval --n 12 --out out/bench-population.json
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
from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.population import OUTSIDE_FORMS

PROTOCOLS = {
    "a": (("up05",), "up10"),
    "b": (("up05", "up20"), "up10"),
    "c": (("up05", "up20"), "down10"),
    "d": (("up05", "up20"), "slowcycle"),
    "e": (("loop_train",), "loop_test"),
    # the envelope: the training logs hold every condition of the test (its program run
    # again with other noise) besides ramps at other rates: what the model can reach
    "f": (("up05", "up20", "loop_train", "loop_test_again"), "loop_test"),
}
# default: what `fogsf train` fits without --model (lag-lstm, its structure chosen by the
# training logs, a hysteresis term when they ask for it); bank, node, physics2: lag-lstm with
# its physics part forced and no hysteresis term (`--structure bank --hysteresis off`, the
# lag bank; `node`, one effective node; `physics --nodes 2`); hyst-off: the default with
# `--hysteresis off`
MODELS = ("poly", "polyrate", "default", "bank", "node", "physics2", "hyst-off", "gsa-lstm")
# the default model with its physics part or its hysteresis term forced (`fogsf train ...`)
FORCED = {"bank": {"structure": "bank", "hysteresis": "off"},
          "node": {"structure": "node", "hysteresis": "off"},
          "physics2": {"structure": "physics", "nodes": 2, "hysteresis": "off"},
          "hyst-off": {"hysteresis": "off"}}
# only logs that turn back in temperature reach the hysteresis check: on the ramps of (a)-(d)
# hyst-off is the default
HYST_OFF_PROTOCOLS = ("e", "f")
# GSA's search space reaches 3 x 256 LSTMs: even this budget takes minutes a protocol on
# 2 cores, so gsa-lstm runs on the paper's protocol (a) only
GSA_SMALL = {"gsa_agents": 3, "gsa_iters": 2, "gsa_fitness_iters": 20, "iters": 100}
GSA_PROTOCOLS = ("a",)
# models that run on some protocols only (the others on every one)
ONLY_ON = {"gsa-lstm": GSA_PROTOCOLS, "hyst-off": HYST_OFF_PROTOCOLS}
LO_C, HI_C = -40.0, 50.0


def _loop(up: float, down: float, soak_s: float = 1800.0) -> list[list[float]]:
    t1 = soak_s
    t2 = t1 + (HI_C - LO_C) / up * 60.0
    t3 = t2 + soak_s
    t4 = t3 + (HI_C - LO_C) / down * 60.0
    return [[0.0, LO_C], [t1, LO_C], [t2, HI_C], [t3, HI_C], [t4, LO_C], [t4 + soak_s, LO_C]]


def run_profile(name: str) -> ProfileConfig:
    """The chamber program of one named run."""
    ramps = {"up05": 0.5, "up10": 1.0, "up20": 2.0}
    if name in ramps:
        return ProfileConfig(kind="ramp", start_c=LO_C, stop_c=HI_C,
                             rate_c_per_min=ramps[name])
    if name == "down10":
        return ProfileConfig(kind="ramp", start_c=HI_C, stop_c=LO_C, rate_c_per_min=1.0)
    if name == "slowcycle":
        return ProfileConfig(kind="cycle", start_c=LO_C, stop_c=HI_C, rate_c_per_min=0.5,
                             soak_s=2700.0, cycles=1)
    if name == "loop_train":
        return ProfileConfig(kind="program", points=_loop(1.0, 2.0))
    if name in ("loop_test", "loop_test_again"):
        return ProfileConfig(kind="program", points=_loop(1.0, 1.5))
    raise ValueError(f"unknown run {name!r}")


RUN_SEED_OFFSET = {"up05": 1, "up10": 2, "up20": 3, "down10": 4, "slowcycle": 5,
                   "loop_train": 6, "loop_test": 7, "loop_test_again": 8}


def run_config(gyro: SimConfig, name: str, gyro_seed: int) -> SimConfig:
    from fogsf.sim.population import run_on_gyro

    return run_on_gyro(gyro, run_profile(name), gyro_seed * 16 + RUN_SEED_OFFSET[name], name)


def runs_for(gyro: SimConfig, gyro_seed: int, protocols: tuple[str, ...] | list[str]
             ) -> dict:
    """Every run the protocols need (training and test), simulated once on `gyro`."""
    from fogsf.sim import simulate

    needed = sorted({r for p in protocols for r in (*PROTOCOLS[p][0], PROTOCOLS[p][1])})
    return {r: simulate(run_config(gyro, r, gyro_seed)).log for r in needed}


def protocol_logs(gyro: SimConfig, gyro_seed: int, protocol: str) -> tuple[list, object]:
    """A protocol's training logs and its test log, simulated on `gyro`."""
    train_names, test_name = PROTOCOLS[protocol]
    logs = runs_for(gyro, gyro_seed, [protocol])
    return [logs[r] for r in train_names], logs[test_name]


def _train_options(model: str, seed: int):  # noqa: ANN202 - TrainOptions, imported late
    from fogsf.training.options import DEFAULT_MODEL, TrainOptions

    kind = DEFAULT_MODEL if model == "default" or model in FORCED else model
    extra: dict = GSA_SMALL if kind == "gsa-lstm" else dict(FORCED.get(model, {}))
    # the rate-transfer interval is the default model's; the others skip that check
    return TrainOptions(model=kind, seed=seed, progress=False, workers=1,
                        transfer_check=model == "default", **extra)


def bench_gyro(gyro_seed: int, models: tuple[str, ...], protocols: tuple[str, ...],
               outside: str | None = None) -> dict:
    """Every model on every protocol for one population gyro (one unit of work); `outside`:
    the gyro given that form outside the population's (`population.outside_form`)."""
    import torch

    from fogsf.sim.population import gyro_for_seed, outside_form
    from fogsf.training.train import run_training

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    gyro = gyro_for_seed(gyro_seed)
    if outside:
        gyro = outside_form(gyro, gyro_seed, outside)
    logs = runs_for(gyro, gyro_seed, protocols)
    out: dict = {"gyro_seed": gyro_seed, "gyro": gyro.scenario, "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for p in protocols:
            train_names, test_name = PROTOCOLS[p]
            case: dict = {}
            for model in models:
                if p not in ONLY_ON.get(model, (p,)):
                    continue
                opts = _train_options(model, gyro_seed)
                m, _ = run_training(opts, [logs[r] for r in train_names], logs[test_name],
                                    Path(tmp) / f"{p}-{model}")
                floor = m["noise_floor_ppm"]
                after = m["test"]["after"]
                row = {"model": m["model"], "rms_ppm": after["rms_ppm"],
                       "std_ppm": after["std_ppm"], "noise_floor_ppm": floor,
                       "ratio": after["rms_ppm"] / floor, "std_ratio": after["std_ppm"] / floor,
                       "before_rms_ppm": m["test"]["before"]["rms_ppm"],
                       "train_seconds": m["train_seconds"]}
                if "structure_choice" in m:
                    row["structure"] = m["structure_choice"]["chosen"]
                if model == "default":
                    rt = m["rate_transfer"]
                    lo, hi = rt["rms_interval_ppm"]
                    row["interval_ppm"] = [lo, hi]
                    row["inside"] = bool(lo <= after["rms_ppm"] <= hi)
                    row["model_spread_max_ppm"] = rt["model_spread_max_ppm"]
                    row["structure_spread_ppm"] = rt["structure_spread_ppm"]
                    row["one_segment"] = rt["one_segment"]
                    row["lag_excursion_c"] = rt["lag_excursion_c"]
                    row["upper_over_actual"] = hi / after["rms_ppm"]
                    # the multiple of D this case needs to fall inside (calibration,
                    # `training.interval.rate_transfer`)
                    excess = max(0.0, after["rms_ppm"] ** 2 - floor**2) ** 0.5
                    d = (rt["model_spread_max_ppm"] if rt["one_segment"]
                         else max(rt["structure_spread_ppm"].values()))
                    row["k_needed"] = excess / max(d, 1e-9)
                if p == "e":
                    tr = m["train"]["after"]
                    row["train_ratio"] = tr["rms_ppm"] / m["train"]["before"]["noise_floor_ppm"]
                case[model] = row
            out["cases"][p] = case
    out["seconds"] = time.perf_counter() - t0
    return out


def _stats(v: list[float]) -> dict:
    a = np.asarray(v, dtype=np.float64)
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)),
            "worst": float(a.max()), "n": int(a.size)}


def summarise(rows: list[dict], models: tuple[str, ...], protocols: tuple[str, ...]) -> dict:
    summary: dict = {}
    for p in protocols:
        for model in models:
            r = [g["cases"][p][model] for g in rows if model in g["cases"][p]]
            if not r:
                continue
            summary[f"{p}/{model}"] = {"ratio": _stats([x["ratio"] for x in r]),
                                       "std_ratio": _stats([x["std_ratio"] for x in r])}
        if p == "e" and "default" in models:
            summary["e-train/default"] = {"ratio": _stats(
                [g["cases"]["e"]["default"]["train_ratio"] for g in rows])}
    if "default" in models:
        cases = [g["cases"][p]["default"] for g in rows for p in protocols]
        inside = [c["inside"] for c in cases]
        summary["interval_coverage"] = {"inside": int(sum(inside)), "cases": len(inside),
                                        "share": float(np.mean(inside))}
        for one in (True, False):
            part = [c for c in cases if c["one_segment"] == one]
            if part:
                summary["interval_coverage"]["one_segment" if one else "several"] = {
                    "inside": int(sum(c["inside"] for c in part)), "cases": len(part),
                    "k_needed_p90": float(np.percentile([c["k_needed"] for c in part], 90)),
                    "upper_over_actual_median": float(np.median(
                        [c["upper_over_actual"] for c in part]))}
    return summary


def plot(rows: list[dict], protocols: tuple[str, ...], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    x = np.arange(len(rows))
    width = 0.8 / len(protocols)
    for i, p in enumerate(protocols):
        ax.bar(x + i * width, [g["cases"][p]["default"]["ratio"] for g in rows], width,
               label=f"({p}) test {PROTOCOLS[p][1]}, train {'+'.join(PROTOCOLS[p][0])}")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x + 0.4 - width / 2, [str(g["gyro_seed"]) for g in rows], rotation=60,
                  fontsize=7)
    ax.set_xlabel("population gyro (seed)")
    ax.set_ylabel("test RMS / noise floor")
    ax.set_yscale("log")
    ax.set_title("default model, per gyro and protocol")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def print_table(summary: dict, models: tuple[str, ...], protocols: tuple[str, ...]) -> None:
    print(f"{'protocol':>9} | " + " | ".join(f"{m:>20}" for m in models))
    print(f"{'':>9} | " + " | ".join(f"{'median  p90  worst':>20}" for _ in models))
    for p in protocols:
        cells = []
        for m in models:
            if f"{p}/{m}" not in summary:
                cells.append("-")
                continue
            s = summary[f"{p}/{m}"]["ratio"]
            cells.append(f"{s['median']:>6.2f} {s['p90']:>5.2f} {s['worst']:>6.2f}")
        print(f"{p:>9} | " + " | ".join(f"{c:>20}" for c in cells))
    if "e-train/default" in summary:
        s = summary["e-train/default"]["ratio"]
        print(f"{'e-train':>9} | default on its own training log: median {s['median']:.2f}, "
              f"worst {s['worst']:.2f}")
    if "interval_coverage" in summary:
        c = summary["interval_coverage"]
        print(f"interval coverage (default model): {c['inside']}/{c['cases']} "
              f"({100 * c['share']:.0f} %)")
        for part in ("one_segment", "several"):
            if part in c:
                q = c[part]
                said = "one ramp" if part == "one_segment" else "several ramps"
                print(f"  training logs with {said}: {q['inside']}/"
                      f"{q['cases']} inside, upper end / actual error median "
                      f"{q['upper_over_actual_median']:.2f}; the multiple of D 90 % of "
                      f"these cases need: {q['k_needed_p90']:.2f} (calibrate on dev seeds "
                      "only)")


def magnitudes(seeds: list[int]) -> dict:
    """The population's SF error before compensation on the paper's 1 C/min run (RMS and
    max|e| about the SF at 20 C) and its noise floor, and its structural mix."""
    from fogsf.logs.measure.metrics import log_metrics
    from fogsf.sim import simulate
    from fogsf.sim.population import gyro_for_seed

    rms, peak, floor, kinds = [], [], [], []
    for s in seeds:
        gyro = gyro_for_seed(s)
        m = log_metrics(simulate(run_config(gyro, "up10", s)).log)
        rms.append(m["rms_ppm"])
        peak.append(m["max_abs_ppm"])
        floor.append(m["noise_floor_ppm"])
        kinds.append(gyro.scenario.split(":", 1)[1])
    pct = (10, 50, 90)
    return {"gyros": len(seeds), "first": seeds[0],
            "rms_ppm_p10_50_90": [float(x) for x in np.percentile(rms, pct)],
            "max_abs_ppm_p10_50_90": [float(x) for x in np.percentile(peak, pct)],
            "noise_floor_ppm_p10_50_90": [float(x) for x in np.percentile(floor, pct)],
            "kinds": {k: kinds.count(k) for k in sorted(set(kinds))}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.population --seeds dev --n 4 --models "
               "poly,default --protocols a,b --out out/bench-population-dev.json")
    ap.add_argument("--out", default="out/bench-population.json")
    ap.add_argument("--seeds", choices=["dev", "eval"], default="eval",
                    help="seed range: dev (tune here) or eval (report here)")
    ap.add_argument("--n", type=int, default=12, help="number of gyros")
    ap.add_argument("--first", type=int, default=None,
                    help="first gyro seed (default: the range's first, skipping the default "
                         "gyro's 0)")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--protocols", default=",".join(PROTOCOLS))
    ap.add_argument("--magnitudes", action="store_true",
                    help="only print the population's SF error before compensation at 1 C/min "
                         "(RMS, max|e|: 10/50/90th percentiles), noise floor and mix")
    ap.add_argument("--outside", default=None, choices=OUTSIDE_FORMS,
                    help="give every gyro a form outside the population's: sensor (the "
                         "thermometer behind the board) or vent (a part an SF factor reads "
                         "behind the chamber air), docs/population.md")
    add_executor_options(ap)
    args = ap.parse_args(argv)

    from fogsf.sim.population import seed_range

    if args.outside and args.magnitudes:
        ap.error("--magnitudes describes the population as drawn: drop --outside")

    models = tuple(m for m in args.models.split(",") if m)
    protocols = tuple(p for p in args.protocols.split(",") if p)
    bad = [m for m in models if m not in MODELS] + [p for p in protocols if p not in PROTOCOLS]
    if bad:
        ap.error(f"unknown model or protocol: {', '.join(bad)}")
    rng = seed_range(args.seeds)
    first = args.first if args.first is not None else max(rng.start, 1)
    seeds = [s for s in range(first, first + args.n)]
    if any(s not in rng for s in seeds):
        ap.error(f"seeds {seeds[0]}..{seeds[-1]} leave the {args.seeds} range {rng}")
    if args.magnitudes:
        print(json.dumps(magnitudes(seeds), indent=2))
        return 0
    t0 = time.perf_counter()
    with executor_from_args(args) as ex:
        rows = run_all(ex, bench_gyro, list(seeds), models, protocols, args.outside,
                       desc="gyros", unit="gyro")
    rows.sort(key=lambda r: r["gyro_seed"])
    for g in rows:
        cells = " ".join(f"{p}:{g['cases'][p][m]['ratio']:.2f}"
                         + (f"({g['cases'][p][m]['structure']})"
                            if "structure" in g["cases"][p][m] else "")
                         for p in protocols for m in models if m == "default")
        print(f"gyro {g['gyro_seed']:>5} {g['gyro']:<28} default {cells}")
    summary = summarise(rows, models, protocols)
    print(f"test RMS / noise floor over {len(rows)} {args.seeds} gyros "
          f"(seeds {seeds[0]}-{seeds[-1]})"
          + (f", each with the outside form {args.outside}" if args.outside else ""))
    print_table(summary, models, protocols)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    seconds = time.perf_counter() - t0
    out.write_text(json.dumps({"seeds": args.seeds, "gyro_seeds": seeds, "models": models,
                               "outside": args.outside,
                               "protocols": {p: PROTOCOLS[p] for p in protocols},
                               "rows": rows, "summary": summary, "seconds": seconds},
                              indent=2) + "\n")
    if "default" in models:
        plot(rows, protocols, out.with_suffix(".png"))
    print(f"-> {out} ({seconds:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
