"""The bank's ridge penalty and cross terms: the prior, fixed lower penalties, the cross terms
at each, and the rule that chooses them.

Least squares only (no LSTM). For each gyro and protocol of `benchmarks.population` (and,
with `--partial`, the partial-cycle programs of `benchmarks.hysteresis`, the hysteresis check
run for each base), prints the test RMS / noise floor of the lag bank at the prior
(`lag_bank.BANK_LAMBDA`) and at every penalty of `structure.penalty.PENALTIES`, each without
and with the cross terms ("x" after the penalty), of the bank
`structure.penalty.choose_penalty` takes ("rule"; the prior where the logs hold fewer than
PENALTY_MIN_FOLDS held-out parts), the number of held-out parts and the bank chosen.
Every case scores the bank, also where `fogsf train` would take physics nodes instead (on
these protocols it keeps the bank on every development gyro of (e), (f) and partial cycles).
Run it on development gyros (the rule is tuned there):

    python -m benchmarks.probes.bank_penalty --first 1 --n 40 --protocols f
    python -m benchmarks.probes.bank_penalty --partial --first 1 --n 20
    python -m benchmarks.probes.bank_penalty --first 1 --n 40 --protocols b,e --min-parts 1
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks.probes import StepScorer, finish, spread_cells
from fogsf.models.structures.lag_bank import BANK_LAMBDA, bank_cross, bank_name, bank_penalty


def case(train: list, test, hysteresis: bool) -> dict:  # noqa: ANN001 - ChamberLogs
    """Every penalty's test ratio (with the hysteresis term where the check keeps it on the
    bank at the prior, as `fogsf train` decides it), the rule's choice, and every penalty's
    held-out parts (mean squared window error per part) for trying other rules."""
    from fogsf.training.structure import heldout as sh
    from fogsf.training.structure import penalty as sp
    from fogsf.training.structure.hysteresis import decide, fit_with_term

    step = sh.choice_step_s(train)
    sd = sh.step_data(train, step)
    if not sd.one_segment:
        sd.fold = sh.part_folds(sd)
    names = {column(lam, x): bank_name(lam, x) for x in (False, True)
             for lam in (BANK_LAMBDA, *sp.PENALTIES)}
    folds = {k: sh.heldout_folds(v, sd) for k, v in names.items()}
    rule = bank_name()
    if not sd.one_segment and sd.n_folds >= sp.PENALTY_MIN_FOLDS:
        pc = sp.choose_penalty(sd, folds[f"{BANK_LAMBDA:g}"])
        rule = pc.name
    used = hysteresis and decide(train, bank_name(), step)["used"]
    if used and bank_cross(rule):  # as `fogsf train`: judged again with the term in
        from fogsf.training.structure.hysteresis import cross_with_term

        if not cross_with_term(train, pc.plain, rule, step)["kept"]:
            rule = pc.plain
    full = sh.step_data(train)
    every = np.arange(full.y.size)
    on_test = StepScorer.of(test, full.fe)
    out: dict = {"parts": sd.n_folds, "term": bool(used), "rule_penalty": bank_penalty(rule),
                 "rule_cross": bank_cross(rule),
                 "part_mse": {k: [float(np.mean(f)) for f in v] for k, v in folds.items()}}
    for key, name in names.items():
        pred = fit_with_term(name, full, every)[0] if used else sh.fit_candidate(name, full,
                                                                                  every)
        out[key] = on_test(pred(on_test.nt))
    out["rule"] = out[column(out["rule_penalty"], out["rule_cross"])]
    return out


def column(lam: float, cross: bool) -> str:
    """The probe's column of the bank at penalty `lam`, with the cross terms if `cross`."""
    return f"{lam:g}" + ("x" if cross else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--protocols", default="b,e,f")
    ap.add_argument("--partial", action="store_true",
                    help="the partial-cycle programs (gyros with and without hysteresis)")
    ap.add_argument("--min-parts", type=int, default=None,
                    help="PENALTY_MIN_FOLDS for this run (1: the rule runs on any logs)")
    ap.add_argument("--share", type=float, default=None,
                    help="PENALTY_WIN_SHARE for this run")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    from fogsf.sim.population import DEV_SEEDS, gyro_for_seed
    from fogsf.training.structure import penalty as structure_penalty
    from fogsf.training.structure.penalty import PENALTIES

    if args.min_parts is not None:
        structure_penalty.PENALTY_MIN_FOLDS = args.min_parts
    if args.share is not None:
        structure_penalty.PENALTY_WIN_SHARE = args.share

    rows: list[dict] = []
    t0 = time.perf_counter()
    if args.partial:
        from benchmarks.hysteresis import partial_runs, pick_seeds

        groups = pick_seeds(args.first, args.n, DEV_SEEDS)
        items = [(s, g) for g in ("hyst", "flat") for s in groups[g]]
        for seed, group in items:
            _, train, test = partial_runs(seed, group)
            rows.append({"seed": seed, "p": f"partial-{group}",
                         **case([train], test, hysteresis=True)})
            print(rows[-1], flush=True)
    else:
        from benchmarks.population import protocol_logs

        for seed in range(args.first, args.first + args.n):
            assert seed in DEV_SEEDS or seed >= 20000
            gyro = gyro_for_seed(seed)
            for p in args.protocols.split(","):
                train, test = protocol_logs(gyro, seed, p)
                rows.append({"seed": seed, "p": p, **case(train, test, hysteresis=p in "ef")})
                print(rows[-1], flush=True)
    names = [column(lam, x) for x in (False, True) for lam in (BANK_LAMBDA, *PENALTIES)]
    names.append("rule")
    for p in sorted({r["p"] for r in rows}):
        sub = [r for r in rows if r["p"] == p]
        cells = spread_cells(sub, names)
        moved = sum(r["rule_penalty"] != BANK_LAMBDA for r in sub)
        cross = sum(r["rule_cross"] for r in sub)
        print(f"({p}) {len(sub)} cases, penalty lowered on {moved}, cross terms on {cross}; "
              f"median/p90/worst {cells}")
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
