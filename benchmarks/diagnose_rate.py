"""Success rate of `fogsf diagnose` over many seeded cases (make bench-diagnose).

Cases (fogsf.diagnose.cases.planted, ranges stated there), on the gyro population
(fogsf.sim.population; `--gyros default`: the default gyro only, as before): every form
variant of the catalogue effects (cases.VARIANTS) and the lag / dT/dt terms planted at 3-20x
the noise floor (visible part), two effects at once (cases.PAIRS), nulls (one of the
effects' setups, and a +/- 10, 50, 100, 200 deg/s table), out-of-catalogue effects
(humidity, supply step, periodic), ramp-only and short-soak lag / dT/dt runs; half the logs
without chamber_c. Seeds: `--seeds-from dev` (fogsf.sim.population.DEV_SEEDS, for tuning)
or `eval` (EVAL_SEEDS, for reporting only). For each case: right or wrong by `case_judge.judge`,
and the figures behind it. Prints a table and writes JSON.

    python -m benchmarks.diagnose_rate --seeds-from eval --seeds 10 --out out/bench-diagnose.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import judge as case_judge
from fogsf.diagnose.cases import kinds as case_kinds
from fogsf.diagnose.cases import planted as cases

Job = tuple[str, str, str, int, bool]  # kind, name, variant, seed, population gyro


def one(job: Job) -> dict[str, Any]:
    from fogsf.diagnose import extend, report, verdict

    kind, name, variant, seed, population = job
    t0 = time.time()
    case = (cases.draw_population(kind, name, variant, seed) if population
            else cases.draw(kind, name, seed))
    name = f"{name}:{variant}" if variant and kind == "effect" else (
        f"{name}+{variant}" if kind == "two" else name)
    try:
        logs, truth = case_build.build(case)
        d = verdict.diagnose(logs)
        ext_cfgs, simulation = extend.extended(d)  # as `fogsf diagnose` does
    except Exception as e:  # a crash is a wrong answer, with its reason
        return {"kind": kind, "name": name, "seed": seed, "ok": False,
                "reason": f"error: {e}", "cause": None, "causes": [], "unexplained": False,
                "ambiguous": [], "case": case.describe(), "multiple": case.multiple,
                "structure": {}, "seconds": time.time() - t0, "significant": [],
                "params": {}, "truth": dict(case.params), "p_values": {}}
    j = report.to_json(d, ext_cfgs[0], simulation)
    o = case_judge.judge_report(case, truth, j)
    return {"kind": kind, "name": name, "seed": seed, "ok": o.ok, "reason": o.reason,
            "cause": j["cause"], "causes": j["causes"], "unexplained": j["unexplained"],
            "ambiguous": j["ambiguous"],
            "case": case.describe(), "multiple": case.multiple_reached or case.multiple,
            "structure": j["structure"], "seconds": time.time() - t0,
            "significant": [c["effect"] for c in j["candidates"] if c["significant"]],
            "params": {c["effect"]: c["params"] for c in j["candidates"]
                       if c["effect"] in (j["causes"] or [case.name])},
            "truth": case.params,
            "p_values": {c["effect"]: c.get("p_value") for c in j["candidates"]}}


def jobs(seeds: int, first_seed: int) -> list[Job]:
    """The default gyro's bench (as before this population bench)."""
    out: list[Job] = []
    for i in range(seeds):
        s = first_seed + i
        out += [("effect", e, "", s, False) for e in cases.CATALOGUE_EFFECTS]
        out += [("null", "", "", 1000 + s, False), ("null", "", "", 2000 + s, False)]
        out += [("ooc", k, "", s, False) for k in cases.OOC_KINDS]
        out += [("ramp_only", k, "", s, False) for k in ("temp_rate", "extra_lag")]
        out += [("short_soak", k, "", s, False) for k in ("temp_rate", "extra_lag")]
    return out


def population_jobs(seeds: range) -> list[Job]:
    """24 cases per population gyro: 12 form variants, the lag, dT/dt and hysteresis terms,
    one pair, two nulls, four out-of-catalogue effects (the mode hop among them), one
    ramp-only and one short-soak
    run."""
    out: list[Job] = []
    for s in seeds:
        out += [("effect", e, v, s, True) for e, vs in cases.VARIANTS.items() for v in vs]
        out += [("effect", e, "", s, True) for e in ("extra_lag", "temp_rate", "hysteresis")]
        a, b = cases.PAIRS[s % len(cases.PAIRS)]
        out.append(("two", a, b, s, True))
        out += [("null", "", "", s, True), ("null", "mixed", "", s, True)]
        out += [("ooc", k, "", s, True) for k in cases.OOC_KINDS]
        k = ("temp_rate", "extra_lag")[s % 2]
        out += [("ramp_only", k, "", s, True), ("short_soak", k, "", s, True)]
    return out


def group(job: Job) -> str:
    """The summary group a job lands in (as `summarise` names them)."""
    kind, name, variant, _, _ = job
    name = f"{name}:{variant}" if variant and kind == "effect" else (
        f"{name}+{variant}" if kind == "two" else name)
    return f"{kind}:{name}" if name else kind


def _strength_within(eff: list[dict[str, Any]], name: str, tol: float) -> int:
    """Cases of `name` named with the strength in ppm/(C/min) within `tol` (printed beside the
    housing coupling the bench judges temp_rate on: docs/diagnose.md)."""
    n = 0
    for r in eff:
        p = r.get("params", {}).get(name, {})
        if r["name"] == name and r["cause"] == name and "strength" in r["truth"] and p:
            true, est = float(r["truth"]["strength"]), float(p["strength_ppm_per_c_per_min"])
            n += abs(est - true) <= tol * abs(true)
    return n


def summarise(results: list[dict[str, Any]]) -> dict[str, Any]:
    by: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in results:
        by[f"{r['kind']}:{r['name']}" if r["name"] else r["kind"]].append(r)
    groups = {k: {"cases": len(v), "right": sum(r["ok"] for r in v),
                  "rate": sum(r["ok"] for r in v) / len(v)} for k, v in sorted(by.items())}
    eff = [r for r in results if r["kind"] == "effect"]
    def planted(r: dict[str, Any]) -> str:  # "aging:settling" -> "aging"
        return str(r["name"]).split(":")[0]

    wrong_cause = [r for r in eff if r["cause"] not in (None, planted(r))]
    null = [r for r in results if r["kind"] == "null"]
    two = [r for r in results if r["kind"] == "two"]
    ooc = [r for r in results if r["kind"] == "ooc"]
    ramp = [r for r in results if r["kind"] == "ramp_only"]
    short = [r for r in results if r["kind"] == "short_soak"]

    def rate(rs: list[dict[str, Any]]) -> float:
        return sum(r["ok"] for r in rs) / len(rs) if rs else float("nan")

    return {
        "groups": groups,
        "temp_rate_strength_within_50pct": _strength_within(eff, "temp_rate", 0.5),
        "temp_rate_coil_behind_housing": sum(
            r["truth"].get("housing_ppm_per_c", 0) != 0 for r in eff if planted(r) == "temp_rate"),
        "effects_right_rate": rate(eff),
        "effects_wrong_cause": len(wrong_cause),
        "effects_ambiguous": sum(r["cause"] is None and planted(r) in r["ambiguous"]
                                 for r in eff),
        "null_false_causes": sum(r["cause"] is not None for r in null),
        "null_cases": len(null),
        "null_flagged_unexplained": sum(r["unexplained"] for r in null),
        "effects_right_rate_without_temp_rate": rate([r for r in eff
                                                      if planted(r) != "temp_rate"]),
        "null_mixed_cases": sum(r["name"] == "mixed" for r in null),
        "null_mixed_flagged_unexplained": sum(r["unexplained"] for r in null
                                              if r["name"] == "mixed"),
        "two_effects_both_named_rate": rate(two),
        "ooc_right_rate": rate(ooc),
        "ooc_named_catalogue_cause": sum(r["cause"] is not None for r in ooc),
        "ramp_only_no_guess_rate": rate(ramp),
        "short_soak_right_or_ambiguous_rate": rate(short),
        "short_soak_wrong_cause": sum(r["cause"] not in (None, r["name"]) for r in short),
        "mode_hop_cases": sum(r["name"] == "mode_hop" for r in ooc),
        "mode_hop_unexplained": sum(r["unexplained"] for r in ooc if r["name"] == "mode_hop"),
        "mode_hop_faint": sum(r["name"] == "mode_hop" and not r["unexplained"]
                              and r["multiple"] < case_kinds.MODE_HOP_MIN_VISIBLE
                              for r in ooc),
        "mode_hop_named_cause": sum(r["cause"] is not None for r in ooc
                                    if r["name"] == "mode_hop"),
        "coil_pair_right": sum(r["ok"] for r in eff if r["name"] == "bias_drift:coil_pair"),
        "coil_pair_cases": sum(r["name"] == "bias_drift:coil_pair" for r in eff),
        "errors": sum(str(r["reason"]).startswith("error:") for r in results),
        "all_right_rate": rate(results),
        "cases": len(results),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example (development gyros 100-101, 40 cases, about 20 s):\n"
               "  python -m benchmarks.diagnose_rate --seeds-from dev --seeds 2 "
               "--out out/bench-diagnose-dev.json")
    ap.add_argument("--out", default="out/bench-diagnose.json")
    ap.add_argument("--seeds", type=int, default=10, help="gyros (population) or seeds per "
                    "case kind (default gyro)")
    ap.add_argument("--seeds-from", choices=["dev", "eval"], default="eval",
                    help="population seed range: dev (tuning) or eval (reporting)")
    ap.add_argument("--first-seed", type=int, default=None,
                    help="first seed (default: the range's first + 100 for dev, its first "
                         "for eval; 100 for --gyros default)")
    ap.add_argument("--gyros", choices=["population", "default"], default="population")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", action="append", default=[], metavar="PREFIX",
                    help="run only the cases whose group (e.g. effect:temp_rate, null, "
                         "ooc:humidity) starts with PREFIX (repeatable; for investigation)")
    args = ap.parse_args(argv)
    if args.gyros == "default":
        todo = jobs(args.seeds, 100 if args.first_seed is None else args.first_seed)
    else:
        from fogsf.sim.population import seed_range

        rng = seed_range(args.seeds_from)
        first = args.first_seed if args.first_seed is not None else (
            rng.start + (100 if args.seeds_from == "dev" else 0))
        if first not in rng or first + args.seeds - 1 not in rng:
            ap.error(f"--first-seed {first} with --seeds {args.seeds} leaves the "
                     f"{args.seeds_from} range {rng.start}-{rng.stop - 1}")
        todo = population_jobs(range(first, first + args.seeds))
    if args.only:
        todo = [j for j in todo if any(group(j).startswith(p) for p in args.only)]
    t0 = time.time()
    results: list[dict[str, Any]] = []
    from tqdm import tqdm

    with ProcessPoolExecutor(args.jobs) as ex:
        for r in tqdm(ex.map(one, todo, chunksize=2), total=len(todo), desc="cases"):
            results.append(r)
    s = summarise(results)
    s["seconds"] = time.time() - t0
    s["command"] = " ".join(["python -m benchmarks.diagnose_rate", *(argv or sys.argv[1:])])
    for k, g in s["groups"].items():
        print(f"{k:28s} {g['right']:3d}/{g['cases']:3d} right ({100 * g['rate']:.0f}%)")
    print(f"planted effects named right (name, parameter, significant): "
          f"{100 * s['effects_right_rate']:.1f}% "
          f"({100 * s['effects_right_rate_without_temp_rate']:.1f}% without temp_rate)")
    n_tr = s["groups"].get("effect:temp_rate", {}).get("cases", 0)
    print(f"temp_rate: strength within 50 % in {s['temp_rate_strength_within_50pct']} of "
          f"{n_tr} (judged on the housing coupling; {s['temp_rate_coil_behind_housing']} "
          "with a coil node behind the housing)")
    print(f"planted effects: {s['effects_wrong_cause']} wrong causes named, "
          f"{s['effects_ambiguous']} left ambiguous (the planted one among them)")
    print(f"null cases: {s['null_false_causes']} false causes in {s['null_cases']} "
          f"({s['null_flagged_unexplained']} flagged unexplained; mixed-rate: "
          f"{s['null_mixed_flagged_unexplained']} of {s['null_mixed_cases']})")
    print(f"two effects at once: {100 * s['two_effects_both_named_rate']:.1f}% both named")
    print(f"out-of-catalogue: {100 * s['ooc_right_rate']:.1f}% unexplained with no cause "
          f"({s['ooc_named_catalogue_cause']} named a catalogue cause)")
    print(f"mode hop (SF step with hysteresis): {s['mode_hop_unexplained']} of "
          f"{s['mode_hop_cases']} reported unexplained ({s['mode_hop_faint']} unflagged under "
          f"{case_kinds.MODE_HOP_MIN_VISIBLE:g}x the floor), {s['mode_hop_named_cause']} named a "
          "catalogue cause")
    print(f"coil bias on a log pair without chamber air: {s['coil_pair_right']} of "
          f"{s['coil_pair_cases']} named bias_drift alone within 30 %")
    print(f"runs ended by an error: {s['errors']}")
    print(f"ramp-only lag / dT/dt: {100 * s['ramp_only_no_guess_rate']:.1f}% no guess")
    print(f"short-soak lag / dT/dt: {100 * s['short_soak_right_or_ambiguous_rate']:.1f}% right "
          f"or ambiguous ({s['short_soak_wrong_cause']} named the other one)")
    for r in results:
        if not r["ok"]:
            print(f"  wrong: {r['case']}: {r['reason']}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"summary": s, "results": results}, indent=1) + "\n",
                              encoding="utf-8")
    print(f"-> {args.out} ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
