"""fogsf diagnose: fit the simulator's physics to measured chamber logs, show what it gets
wrong, name the cause, extend the model and measure the gain.

1. Base model (system identification): the housing temperature from the chamber air (when
   logged), internal nodes as first-order lags of it with time constants profiled over a
   log-spaced grid (linear least squares inside), SF laws in the board and node
   temperatures, the unseen self-heating after a power-on, a constant bias where the rate
   varies. Its residual per window: size, whiteness (Ljung-Box), correlation with
   temperature, dT/dt, time since power-on, elapsed time, table rate, |rate|, sign(rate)
   and temperature x sign(rate).
2. Each catalogue effect (warmup, extra_lag, temp_rate, rate_nonlinearity, asymmetry,
   bias_drift, aging; the simulator's, in its units) is added to the base in turn.
3. Every model is scored on held-out data: contiguous blocks of windows left out in turn
   (or whole logs with --cv runs), significance by a paired sign-flip test over blocks.
4. Names the cause, or none, with its parameters and 95 % intervals, and every further
   cause that wins on held-out blocks over the ones before it (`causes`, forward
   selection). A significant cause is named even when structure remains, if it takes at
   least 80 % of the base's excess held-out variance ("N % of the structure remains").
   Significant: paired sign-flip p < 0.01 over blocks and the held-out weighted SSE lower
   by at least 0.05 noise variances per window. `ambiguous` when the logs cannot tell two
   apart (e.g. an extra thermal lag and a dT/dt term); `unexplained` when structure
   remains. A candidate the logs cannot show at all (asymmetry at one |rate|, a lag on
   steady ramps) is "confounded with the base", with the run that would separate them.
   `unexplained` is also true when the chosen model's held-out residual is not white
   (Ljung-Box p < 1e-6 with at least 10 % of its mean square slow structure), reported with
   its size: the structured share, its RMS in ppm over 5-window means, the p-value.
   A catalogue form that cannot apply to these logs or to the fitted model (e.g. a coil
   effect in a simulation without coil nodes) is skipped and named with the reason
   ("skipped: ..."), never an error for the whole run.
   Noise per window: the window noise at its |table rate| level (about 1/|rate|) plus, in
   quadrature, the base's resolution (2 % of its fitted thermal SF's RMS).
5. Writes the extended model as a simulator configuration (--config-out, and in the JSON as
   extended_model) and simulates it to report how much closer it comes to the logs.

On plateau tables (docs/diagnose.md, "Plateau tables"): the rate terms beyond the
simulator's linear SF (an open-loop FOG's sine, a polynomial, the asymmetry), named.

examples:
  fogsf simulate --scenario paper --ramp-rate 1.0 --out run.csv
  fogsf diagnose run.csv --json diag.json --report diag.md
  fogsf diagnose rig/table.csv --json diag.json
  fogsf diagnose up.csv down.csv --json diag.json --cv runs
  fogsf simulate --config diag.sim.json --out sim.csv      # data from the extended model
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from fogsf.cli.arguments import add_earth_options, add_log_options, read_logs
from fogsf.cli.plateau_commands import any_plateau_table, diagnose_tables
from fogsf.diagnose import extend, report, verdict
from fogsf.errors import UserError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("logs", nargs="+", metavar="LOG.CSV", help="measured chamber logs")
    add_log_options(parser)
    parser.add_argument("--json", metavar="DIAG.JSON",
                        help="write the diagnosis (its keys: docs/diagnose.md)")
    parser.add_argument("--report", metavar="DIAG.MD",
                        help="write a Markdown report with residual plots beside it")
    parser.add_argument("--config-out", metavar="SIM.JSON",
                        help="simulator configuration of the extended model (default: next "
                             "to --json as NAME.sim.json; one per log, NAME.runK.sim.json, "
                             "for the second and later logs)")
    parser.add_argument("--window-s", type=float, default=60.0,
                        help="SF window length, s (default 60)")
    add_earth_options(parser)
    parser.add_argument("--cv", choices=["blocks", "runs"], default="blocks",
                        help="held-out scoring: contiguous blocks of windows (default) or "
                             "leave one log out")
    parser.add_argument("--start", choices=["auto", "warm", "power-on"], default="auto",
                        help="how the logs start (auto: a self-heating rise of the board "
                             "against the chamber air, or at the log's start from the board "
                             "thermometer alone, marks a power-on; the others override)")
    parser.add_argument("--effects", metavar="A,B,...",
                        help="candidates to try (default: the whole catalogue)")
    parser.add_argument("--no-simulate", action="store_true",
                        help="skip simulating the base and extended configurations")
    parser.add_argument("--seed", type=int, default=0, help="seed in the written config")


def run(args: argparse.Namespace) -> int:
    if args.window_s <= 0:
        raise UserError("--window-s must be > 0")
    if any_plateau_table(args, args.logs):
        return diagnose_tables(args)
    logs = read_logs(args, args.logs, on_disk=True)
    effects = [e.strip() for e in args.effects.split(",")] if args.effects else None
    d = verdict.diagnose(logs, window_s=args.window_s, latitude_deg=args.latitude_deg,
                         cv=args.cv, start=args.start, effects=effects,
                         progress=sys.stderr.isatty())
    ext_cfgs, simulation = extend.extended(d, args.seed, compare=not args.no_simulate)
    cfg_path = args.config_out
    if cfg_path is None and args.json:
        cfg_path = str(Path(args.json).with_suffix("")) + ".sim.json"
    if cfg_path:
        simulation = simulation or {}
        simulation["config_paths"] = []
        for i, cfg in enumerate(ext_cfgs):
            p = Path(cfg_path)
            if i > 0:
                p = p.with_name(p.name.removesuffix(".sim.json").removesuffix(".json")
                                + f".run{i + 1}.sim.json")
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(json.dumps(cfg, indent=2) + "\n", encoding="utf-8")
            simulation["config_paths"].append(str(p))
    j = report.to_json(d, ext_cfgs[0], simulation)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(j, indent=2) + "\n", encoding="utf-8")
    if args.report:
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        report.markdown(j, d, Path(args.report), cfg_path)
    print(report.summary_text(j))
    return 0
