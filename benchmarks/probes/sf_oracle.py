"""What each population protocol's training logs can pin: the SF oracle.

For each gyro the oracle knows the simulator's TRUE structure: every SF factor's true
temperature (the weighted mean of its true node temperatures, not the board thermometer),
its polynomial degree, the bias law's node and degree, and (on gyros that draw one) the
true SF hysteresis output as one more column. Only the coefficients are fitted on the
protocol's training logs (the same measured SF targets the trainer fits), and the test log
is scored as the benchmarks score it (test RMS / noise floor):
- `lstsq`: least squares;
- `best`: the best of a few ridge penalties, chosen on the test itself (no method has it);
- `ridge_LAM`: each penalty fixed (a prior, as a method could fix it), and `loo` (protocols
  of several training runs): the penalty whose fits to all runs but one predict the one left
  out best, each in turn (a rule on the training logs alone).
No model built on the board thermometer can know more, so where `best` misses a target the
training logs do not hold the information; where it meets it, the gap is the method's.

`--exact` adds the true SF itself (no fit): near 1.0 x, the floor is the floor. `--bank`
adds where the default's bank loses: `generic_LAM`, the bank's generic law (every feature
with its square and cube, ridge) on the TRUE temperatures of every node (the thermal
network known, the law's form not), `genericx_LAM` the same with every cross term,
`factors_LAM` the generic law on each SF factor's true temperature (the nodes' mixture
known, the degrees not), `bank_SOURCE`, the bank at its prior on the thermometer, the true
board or the true housing temperature, and the bank on the thermometer at lower penalties,
without and with its cross terms (`bank:LAM`, `bankx:LAM`). `--partial` runs the
partial-cycle programs of `make bench-hysteresis` instead of the protocols, `--plan
PROGRAM` a program of `fogsf plan`'s candidates tested as `make bench-plan` tests it.

    python -m benchmarks.probes.sf_oracle --first 1 --n 40 --protocols a,b,e --bank
    python -m benchmarks.probes.sf_oracle --partial --first 1 --n 20 --bank
    python -m benchmarks.probes.sf_oracle --plan "loop3 up 2 / down 1 / up 3, soaks 30 min"
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.population import PROTOCOLS, run_config
from benchmarks.probes import StepScorer, finish, ratio, spread_cells
from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import step_targets
from fogsf.models.structures.lag_bank import BANK_LAMBDA, bank_name, fit_bank
from fogsf.sim.config import SimConfig
from fogsf.sim.effects import EffectContext, apply_effects
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.population import gyro_for_seed
from fogsf.sim.scale_factor import term_temperature


def true_design(r: SimResult, cfg: SimConfig) -> np.ndarray:
    """Columns of the true SF structure: 1, each factor's (T - ref) / 50 to its degree,
    the bias law's node to its degree (a bias reads as SF on a table turning one way at one
    rate, as every population run does) and the Shupe rate when it has one, and the
    effects' SF output (the play: the population's only effect; an effect's bias term is
    not a column)."""
    cols = [np.ones(r.log.time_s.shape[0])]
    for term in cfg.sf.terms:
        d = (term_temperature(r.nodes, term) - term.ref_c) / 50.0
        degree = 3 if term.cube_ppm_per_c3 else (2 if term.quad_ppm_per_c2 else 1)
        cols += [d**k for k in range(1, degree + 1)]
    b = cfg.bias
    d = (np.asarray(r.nodes[b.node]) - b.ref_c) / 50.0
    degree = 3 if b.cube_dph_per_c3 else (2 if b.quad_dph_per_c2 else 1)
    cols += [d**k for k in range(1, degree + 1)]
    if b.shupe_dph_per_c_per_min:
        cols.append(np.gradient(np.asarray(r.nodes[b.node]), cfg.dt_s) * 60.0)
    if cfg.effects:  # every run of a gyro with effects has the column: one design
        ctx = EffectContext(
            r.log.time_s, cfg.dt_s, r.log.table_rate_dps, r.nodes, cfg.thermal.board_node
        )
        sf_fx, _ = apply_effects(ctx, cfg.effects)
        cols.append(sf_fx / 10.0)
    return np.column_stack(cols)


PENALTIES = (0.0, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2)


def ridge(x: np.ndarray, y: np.ndarray, lam: float) -> np.ndarray:
    """Least squares with a ridge of lam (relative to each column's mean square) on every
    column but the constant."""
    scale = np.sqrt(np.mean(x * x, axis=0))
    scale[scale == 0] = 1.0
    xs = x / scale
    pen = np.full(x.shape[1], lam * x.shape[0])
    pen[0] = 0.0
    if lam == 0.0:
        c, *_ = np.linalg.lstsq(xs, y, rcond=None)
    else:
        c = np.linalg.solve(xs.T @ xs + np.diag(pen), xs.T @ y)
    return c / scale


def bank_ratio(train: list[SimResult], test: SimResult, source: str,
               name: str | None = None) -> float:
    """The bank `name` (default: at the prior; least squares, as `fogsf train` fits it), its
    temperature input the log's thermometer (`source` "thermometer") or a true node's
    temperature ("board", "housing"): where the bank loses against the oracle."""
    from fogsf.training.structure import heldout as sh

    def log_of(r: SimResult) -> ChamberLog:
        if source == "thermometer":
            return r.log
        return replace(r.log, temp_c=np.asarray(r.nodes[source], dtype=np.float64))

    full = sh.step_data([log_of(r) for r in train])
    pred = sh.fit_candidate(name or bank_name(), full, np.arange(full.y.size))
    on_test = StepScorer.of(log_of(test), full.fe)
    return on_test(pred(on_test.nt))


BANK_SOURCES = ("thermometer", "board", "housing")


Run = tuple[SimResult, SimConfig]


def true_nodes(r: SimResult, cfg: SimConfig) -> np.ndarray:
    """Every true node temperature of the network, (T - 20) / 50."""
    return np.column_stack([(np.asarray(r.nodes[n.name]) - 20.0) / 50.0 for n in cfg.thermal.nodes])


GENERIC_PENALTIES = (BANK_LAMBDA, 1e-4)


def stacked(train: list[Run], columns: Callable[[SimResult, SimConfig], np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray]:
    """`columns` of every training run and its measured SF targets, at the samples that
    have one, stacked."""
    xs, ys = [], []
    for r, cfg in train:
        y = step_targets(r.log, 1)
        ok = np.isfinite(y)
        xs.append(columns(r, cfg)[ok])
        ys.append(y[ok])
    return np.vstack(xs), np.concatenate(ys)


def factor_temps(r: SimResult, cfg: SimConfig) -> np.ndarray:
    """Every SF factor's true temperature (the weighted mean of its nodes), (T - ref) / 50."""
    return np.column_stack([(term_temperature(r.nodes, t) - t.ref_c) / 50.0
                            for t in cfg.sf.terms])


def generic_ratio(train: list[Run], test: Run, lam: float, cross: bool = False,
                  columns: Callable[[SimResult, SimConfig], np.ndarray] = true_nodes) -> float:
    """The bank's generic law (every feature with its square and cube, ridge at `lam`;
    `cross`: with every cross term) on `columns`, by default the true temperatures of every
    node: the thermal network known, the law's form not."""
    z, y = stacked(train, columns)
    s = float(np.std(y)) or 1.0
    fit = fit_bank(z, y / s, lam, cross=cross)
    return ratio(test[0].log, fit.predict(columns(*test)) * s)


def score(train: list[Run], test: Run, exact: bool, bank: bool) -> dict:
    """The oracle fitted on `train` and scored on `test` (least squares, each of PENALTIES,
    the best of them on the test, the one the training runs choose), and the requested
    comparisons."""
    x, y = stacked(train, true_design)
    r, cfg = test
    xt = true_design(r, cfg)
    by_pen = [ratio(r.log, xt @ ridge(x, y, lam)) for lam in PENALTIES]
    out = {
        "lstsq": by_pen[0],
        "best": min(by_pen),
        "best_penalty": PENALTIES[int(np.argmin(by_pen))],
        **{f"ridge_{lam:g}": v for lam, v in zip(PENALTIES[1:], by_pen[1:], strict=True)},
    }
    if len(train) > 1:  # the penalty chosen by the training runs, each held out in turn
        def held_out(lam: float) -> float:
            err = 0.0
            for k in range(len(train)):
                xk, yk = stacked([t for i, t in enumerate(train) if i != k], true_design)
                xh, yh = stacked([train[k]], true_design)
                err += float(np.sum((xh @ ridge(xk, yk, lam) - yh) ** 2))
            return err

        lam = min(PENALTIES, key=held_out)
        out["loo"] = by_pen[PENALTIES.index(lam)]
    if exact:
        turn = r.log.table_rate_dps + r.log.earth_rate_dps
        out["exact"] = ratio(r.log, r.sf_ppm + r.bias_dps / turn * 1e6)
    if bank:
        for lam in GENERIC_PENALTIES:
            out[f"generic_{lam:g}"] = generic_ratio(train, test, lam)
            out[f"genericx_{lam:g}"] = generic_ratio(train, test, lam, cross=True)
            out[f"factors_{lam:g}"] = generic_ratio(train, test, lam, columns=factor_temps)
        for src in BANK_SOURCES:
            out[f"bank_{src}"] = bank_ratio([t[0] for t in train], r, src)
        for lam in (1e-4, 1e-5):
            for cross in (False, True):
                nm = bank_name(lam, cross)
                out[nm] = bank_ratio([t[0] for t in train], r, "thermometer", nm)
    return out


def run(cfg: SimConfig) -> Run:
    """One run simulated, with its configuration."""
    return simulate(cfg), cfg


def protocol_cases(seed: int, protocols: list[str]) -> dict[str, tuple[list[Run], Run]]:
    """The population protocols' runs on gyro `seed` (as `make bench-population`)."""
    gyro = gyro_for_seed(seed)
    names = sorted({n for p in protocols for n in (*PROTOCOLS[p][0], PROTOCOLS[p][1])})
    runs = {n: run(run_config(gyro, n, seed)) for n in names}
    return {p: ([runs[n] for n in PROTOCOLS[p][0]], runs[PROTOCOLS[p][1]]) for p in protocols}


def partial_case(seed: int, group: str) -> tuple[list[Run], Run]:
    """The partial-cycle programs on gyro `seed`, as `make bench-hysteresis` runs them."""
    from benchmarks.hysteresis import partial_configs

    _, train, test = partial_configs(seed, group)
    return [run(train)], run(test)


def plan_cases(seed: int, program: str) -> dict[str, tuple[list[Run], Run]]:
    """`make bench-plan`'s runs on gyro `seed`: the named program of `fogsf plan`'s
    candidates (its runs' noise seeds as the bench's) and the test loops at every envelope
    rate, one case per rate."""
    from benchmarks.plan import LIMITS, RATES
    from fogsf.plan.evaluate import _test_loop
    from fogsf.plan.programs import candidates
    from fogsf.sim.config import ProfileConfig
    from fogsf.sim.population import run_on_gyro

    found = [c for c in candidates(LIMITS) if c.name == program]
    if not found:
        raise SystemExit(f"no program {program!r} among fogsf plan's candidates")
    gyro = gyro_for_seed(seed)

    def sim(points: tuple, noise: int, name: str) -> Run:
        prof = ProfileConfig(kind="program", points=[list(q) for q in points])
        return run(run_on_gyro(gyro, prof, noise, name))

    train = [sim(r, seed * 1000 + k, f"plan-run{k}") for k, r in enumerate(found[0].runs)]
    return {f"{rate:.3g}": (train, sim(_test_loop(LIMITS, rate), seed * 1000 + 900 + i,
                                       f"plan-test-{rate:.3g}"))
            for i, rate in enumerate(RATES)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.probes.sf_oracle",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: python -m benchmarks.probes.sf_oracle --first 1 --n 20 --protocols a,b,e",
    )
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--protocols", default="a,b,e")
    ap.add_argument(
        "--partial",
        action="store_true",
        help="the partial-cycle programs of make bench-hysteresis instead of protocols: its "
        "groups from --first (n gyros with SF hysteresis, the same without it, n that draw "
        "none)",
    )
    ap.add_argument("--exact", action="store_true", help="also score the true SF itself")
    ap.add_argument(
        "--bank",
        action="store_true",
        help="also where the bank loses: the generic law on the true nodes (with and "
        "without cross terms) and on the true factor temperatures, the bank at the prior on "
        "the thermometer, the true board and the true housing temperature, and at lower "
        "penalties with and without cross terms (several times slower)",
    )
    ap.add_argument("--plan", default=None, metavar="PROGRAM",
                    help="make bench-plan's runs instead: the program of fogsf plan's "
                         "candidates by its name, tested on the loops at every envelope rate")
    ap.add_argument("--out", type=Path, default=Path("out/probe-sf-oracle.json"))
    args = ap.parse_args(argv)
    items: list[tuple[int, str]]
    if args.plan:
        cases = [c for c in plan_cases(args.first, args.plan)]
        items = [(s, "plan") for s in range(args.first, args.first + args.n)]
    elif args.partial:
        from benchmarks.hysteresis import pick_seeds
        from fogsf.sim.population import DEV_SEEDS, EVAL_SEEDS

        seeds = pick_seeds(
            args.first, args.n, EVAL_SEEDS if args.first in EVAL_SEEDS else DEV_SEEDS
        )
        items = [(s, g) for g in ("hyst", "same-flat", "flat") for s in seeds[g]]
        cases = sorted({g for _, g in items})
    else:
        cases = args.protocols.split(",")
        items = [(s, "") for s in range(args.first, args.first + args.n)]
    rows: list[dict] = []
    t0 = time.perf_counter()
    for seed, group in items:
        if group == "plan":
            got = plan_cases(seed, args.plan)
        else:
            got = {group: partial_case(seed, group)} if group else protocol_cases(seed, cases)
        row: dict = {"gyro": seed}
        for c, (train, test) in got.items():
            row[c] = score(train, test, args.exact, args.bank)
        rows.append(row)
        print(
            f"gyro {seed:5d} "
            + " | ".join(
                f"{c} " + " ".join(f"{k} {v:.2f}" for k, v in sc.items() if k != "best_penalty")
                for c, sc in row.items()
                if c != "gyro"
            ),
            flush=True,
        )
    for c in cases:
        sub = [r[c] for r in rows if c in r]
        names = [k for k in sub[0] if k != "best_penalty"]
        print(f"({c}) {len(sub)} gyros; median/p90/worst {spread_cells(sub, names)}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    return finish(rows, str(args.out), t0)


if __name__ == "__main__":
    raise SystemExit(main())
