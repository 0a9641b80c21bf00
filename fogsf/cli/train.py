"""fogsf train: fit a scale-factor compensation model on chamber logs.

Models: poly (polynomial in T), polyrate (T and a filtered dT/dt), mlp (the paper's MLP),
lstm (the paper's LSTM, Table 1: 2 x 200, batch 32, lr 0.02), lag-lstm (the default: a
physics part fitted by least squares, plus a 1 x 16 LSTM on what it leaves; the physics part
is chosen by the training logs, by held-out prediction of their parts, among physics nodes
with 1-3 nodes (first-order lags of T with identified time constants, a quadratic with cross
terms) and the lag bank (T and its lags at 11 time constants from 60 s to 2 h, ridge with a
fixed prior); `--structure` to give it, `node` for one or two effective nodes T_eff = w T +
(1 - w) lag(T, tau); a hysteresis term when logs that turn back in temperature ask for it,
`--hysteresis`), gsa-lstm (GSA tunes batch size, layers, hidden units, learning rate
and (tau, w) of T_eff on the validation part of the training logs). The rule's tolerance was
chosen on development gyros of the population (docs/decisions.md); train on two or more ramp
rates (or one log with up- and down-ramps at different rates and soaks): one rate leaves the
lags undetermined, and with --test the rate-transfer check says how far (an interval for the
RMS error on the test log).

Every model uses only what firmware has (board thermometer and time) and predicts the SF
error in ppm vs nominal, causally. The part --val-chunk of each training log is held out
for model selection; the test log is never used for fitting or selection. Writes
OUT/metrics.json (before/after metrics on test and train logs, parameter count, weight
bytes) and, for the LSTM models, the firmware artifact (stream.json, stream_weights.npz)
that `fogsf export` reads.

With --prior FLEET the unit is fitted under its design's prior, learned from the units
already in the fleet database (docs/fleet.md, "The design's prior"); --unit SN records it.
On plateau tables (a rig's means per rate plateau) it fits the plateau model: the SF as a
function of rate and temperature (docs/train.md, "Plateau tables").

Examples:
  fogsf simulate --scenario paper --ramp-rate 0.5 --out run05.csv  # 2.0, 1.0: run20, run10
  fogsf train --train run05.csv --train run20.csv --test run10.csv --out models/m
  fogsf train --prior line.fleet --unit SN0042 --train short.csv --test test.csv --out m42
  fogsf train --train rig/run1.csv --test rig/run2.csv --out models/plat
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fogsf.cli.arguments import (
    add_log_options,
    add_metric_options,
    non_negative_int,
    positive_float,
    positive_int,
    read_logs,
)
from fogsf.cli.axes import run_all, wants_all
from fogsf.cli.plateau_commands import any_plateau_table, train_tables
from fogsf.errors import UserError
from fogsf.fleet.kept_model import retry_command
from fogsf.fleet.new_unit import train_on_prior
from fogsf.gsa.executors import add_executor_options
from fogsf.models.structures.lag_bank import BANK_LSTM_INPUTS, bank_spec
from fogsf.training.bias.model import bias_lines
from fogsf.training.interval.transfer import spans_ramp_rates
from fogsf.training.metrics_file import Metrics, from_json, to_json
from fogsf.training.options import DEFAULT_MODEL, MODELS, STRUCTURES, TrainOptions
from fogsf.training.rate.plateau_train import metrics_lines
from fogsf.training.results import BiasOnlyMetrics, PlateauMetrics
from fogsf.training.structure.choice import choice_message
from fogsf.training.structure.hysteresis import choice_line
from fogsf.training.train import train_model
from fogsf.training.with_prior import prior_lines


def _chunk(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError("expected LO:HI fractions, e.g. 0.4:0.6") from None
    return lo, hi


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--train", action="append", required=True, metavar="LOG.csv",
                        help="training log (repeat for several)")
    parser.add_argument("--test", metavar="LOG.csv", help="test log, never used for fitting")
    parser.add_argument("--model", choices=MODELS, default=DEFAULT_MODEL,
                        help=f"model family (default {DEFAULT_MODEL})")
    parser.add_argument("--out", required=True, help="model directory to write")
    parser.add_argument("--seed", type=int, default=0, help="seed (same seed, same model)")
    parser.add_argument("--model-step-s", type=positive_float, default=5.0, metavar="S",
                        help="seconds per model step (default 5: 50 samples at 10 Hz, 500 at "
                             "100 Hz); the model runs at any sample rate with this step")
    parser.add_argument("--val-chunk", type=_chunk, default=(0.4, 0.6), metavar="LO:HI",
                        help="part of each training log held out for validation "
                             "(fractions of its length; default 0.4:0.6)")
    add_metric_options(parser)
    parser.add_argument("--ref-sf", type=positive_float, default=None, metavar="RATIO",
                        help="reference SF ratio (vs nominal) of the before-metrics instead "
                             "of the training logs' SF at 20 C (needed when they never pass "
                             "20 C: take ref_sf_ratio from `fogsf inspect --json` of a run of "
                             "the same gyro that does)")
    add_log_options(parser)
    parser.add_argument("--rate-tau-s", type=float, default=120.0,
                        help="time constant of the dT/dt filter (default 120 s)")
    parser.add_argument("--structure", choices=STRUCTURES, default=None,
                        help="lag-lstm's physics part: auto (default: chosen by the training "
                             "logs, by held-out prediction of their parts, among physics nodes "
                             "with 1-3 nodes and the bank; docs/train.md), physics (--nodes "
                             "first-order lags of T with identified time constants, a quadratic "
                             "with cross terms), bank (T and its lags at 11 time constants from "
                             "60 s to 2 h, cubic up to 2000 s and linear beyond, ridge with one "
                             "fixed prior) or node (one or two effective nodes with a cubic, "
                             "--nodes)")
    parser.add_argument("--nodes", type=int, choices=(1, 2, 3), default=None,
                        help="nodes of --structure physics (1-3, default 1) or node (1-2)")
    parser.add_argument("--poly-degree", type=int, default=3, help="poly/polyrate degree")
    parser.add_argument("--node", type=float, nargs=2, default=None,
                        metavar=("TAU_S", "W"),
                        help="effective sensing temperature T_eff = W*T + (1-W)*lag(T, TAU_S) "
                             "for lag-lstm (default: identified from the training logs)")
    parser.add_argument("--hysteresis", choices=("auto", "on", "off"), default="auto",
                        help="lag-lstm (bank or physics nodes): a play (backlash) term for "
                             "rate-independent SF hysteresis; auto (default): when the "
                             "training logs turn back in temperature and their held-out "
                             "blocks predict 10 %% better with it; on: always; off: never "
                             "(docs/train.md, \"Hysteresis\")")
    g = parser.add_argument_group("LSTM (defaults: lstm = paper Table 1, others 1 x 16)")
    g.add_argument("--layers", type=positive_int)
    g.add_argument("--hidden", type=positive_int)
    g.add_argument("--batch-size", type=positive_int)
    g.add_argument("--lr", type=positive_float)
    g.add_argument("--iters", type=non_negative_int, help="training iterations (batches)")
    g.add_argument("--lstm-inputs", type=positive_int, metavar="N",
                   help="lag-lstm (bank or physics nodes): the LSTM reads the first N "
                        f"features (T, then the fastest lags; default {BANK_LSTM_INPUTS}, "
                        f"{bank_spec().n_features} = all of the bank's): "
                        "4 x hidden input weights per feature in the firmware's flash")
    g.add_argument("--lstm-window", type=positive_int, metavar="STEPS",
                   help="model steps per LSTM training window (default 256, 21 min at "
                        "5 s steps; larger than a log: whole logs)")
    g = parser.add_argument_group("GSA (gsa-lstm)")
    g.add_argument("--gsa-agents", type=positive_int, default=8)
    g.add_argument("--gsa-iters", type=positive_int, default=8)
    g.add_argument("--gsa-fitness-iters", type=positive_int, default=80,
                   help="training iterations of each fitness evaluation")
    g.add_argument("--gsa-space", choices=("paper", "extended"), default="extended",
                   help="paper: Table 1's four; extended: also tau and w of T_eff")
    g.add_argument("--gsa-paper-constants", action="store_true",
                   help="G0=100, alpha=20 (the paper's); default: normalised box, G0=3, "
                        "alpha=2, which beats random search at budgets of tens of iterations")
    add_executor_options(parser, "gsa-lstm's fitness evaluations")
    g = parser.add_argument_group("the design's prior (docs/fleet.md)")
    g.add_argument("--prior", metavar="FLEET",
                   help="fit the unit under its design's prior, learned from the units in "
                        "the fleet database FLEET (a file, or a postgresql:// URL): its "
                        "response drawn around the fleet's units', carried by physics nodes; "
                        "fitted alone when its data disagree with the design")
    g.add_argument("--unit", metavar="SN",
                   help="with --prior: record the unit in FLEET under this name")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    if getattr(args, "unit", None) and wants_all(args):
        raise UserError("--unit records one unit's axis in the fleet: give one --axis, not "
                        "all")
    if wants_all(args):  # OUT/A per axis, then one summary
        return run_all(args, run, "train")
    if args.unit and not args.prior:
        raise UserError("--unit records the unit in a fleet: give --prior FLEET too (or use "
                        "fogsf fleet add)")
    if args.prior and (args.model != "lag-lstm" or args.structure or args.nodes or args.node):
        raise UserError("--prior fits the default model (lag-lstm) on the design's physics "
                        "nodes: drop --model, --structure, --nodes and --node")
    if any_plateau_table(args, args.train + ([args.test] if args.test else [])):
        return train_tables(args)
    train_logs = read_logs(args, args.train, on_disk=True, training=True)
    test_log = read_logs(args, [args.test], on_disk=True)[0] if args.test else None
    opts = train_options(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    if args.prior:
        content = train_on_prior(args.prior, getattr(args, "unit", None), opts, train_logs,
                                 test_log, out, _retry(args))
        m = from_json(content)
        print(format_metrics(m))
        print("\n".join(textwrap.fill(x, 96) for x in prior_lines(content["prior"])))
    else:
        m, _ = train_model(opts, train_logs, test_log, out)
        content = to_json(m)
        print(format_metrics(m))
    args.axis_result = content
    print(f"wrote {out}/metrics.json" + (" and the firmware artifact (fogsf export "
                                         f"{out} --out build/...)" if m.exportable else ""))
    return 0


def _retry(args: argparse.Namespace) -> str | None:
    """`fleet add` with this command's unit, logs and options, recording the model kept in
    --out (`kept_model.retry_command`); None without the arguments as given."""
    argv = list(getattr(args, "_argv", None) or [])
    if "train" not in argv:
        return None
    return retry_command([args.prior, *argv[argv.index("train") + 1:]], ("--prior", "--out"),
                         args.out)


def train_options(args: argparse.Namespace) -> TrainOptions:
    """The training options of `fogsf train`'s arguments (`fogsf fleet add` takes the same)."""
    return TrainOptions(
        model=args.model, model_step_s=args.model_step_s, seed=args.seed,
        val_chunk=args.val_chunk, window_s=args.window_s, latitude_deg=args.latitude_deg,
        settle_s=args.settle_s,
        rate_tau_s=args.rate_tau_s, poly_degree=args.poly_degree,
        node=tuple(args.node) if args.node else None, nodes=args.nodes or 1,
        structure=args.structure or ("node" if args.nodes or args.node else "auto"),
        hysteresis=args.hysteresis,
        layers=args.layers, hidden=args.hidden, batch_size=args.batch_size, lr=args.lr,
        iters=args.iters, lstm_window=args.lstm_window, lstm_inputs=args.lstm_inputs,
        gsa_agents=args.gsa_agents,
        gsa_iters=args.gsa_iters,
        gsa_fitness_iters=args.gsa_fitness_iters, gsa_space=args.gsa_space,
        gsa_paper_constants=args.gsa_paper_constants,
        workers=args.workers, dask=args.dask, ref_sf=args.ref_sf,
        progress=not args.no_progress and sys.stderr.isatty(),
    )


def format_metrics(metrics: Metrics | Mapping[str, Any]) -> str:
    """What `fogsf train` prints of a sample-log model's metrics (or metrics.json's content)."""
    m = from_json(metrics) if isinstance(metrics, Mapping) else metrics
    if isinstance(m, PlateauMetrics):
        return "\n".join(metrics_lines(m))
    if isinstance(m, BiasOnlyMetrics):
        return "\n".join([f"model {m.model} (bias only: the logs are stationary, they "
                          f"measure no SF): {m.params} parameters, features "
                          f"{', '.join(m.features)}, trained in "
                          f"{m.train_seconds:.1f} s", *bias_lines(m.bias)])
    lines = [f"model {m.model}: {m.params} parameters ({m.weights_bytes} bytes), "
             f"features {', '.join(m.features)}, trained in {m.train_seconds:.1f} s"]
    row = "  {:<16} {:>9} {:>9} {:>9} {:>9}"
    lines.append(row.format("SF error, ppm", "max|e|", "p-p", "RMS", "STD"))
    blocks = [("train" if len(m.train) == 1 else f"train {i}", s)
              for i, s in enumerate(m.train)]
    blocks += [("test", m.test)] if m.test is not None else []
    for name, block in blocks:
        for when, b in (("before", block.before), ("after", block.after)):
            lines.append(row.format(f"{name} {when}", f"{b['max_abs_ppm']:.2f}",
                                    f"{b['pp_ppm']:.2f}", f"{b['rms_ppm']:.2f}",
                                    f"{b['std_ppm']:.2f}"))
    lines.append(f"  noise floor {m.noise_floor_ppm:.2f} ppm ({m.window_s:g} s windows)")
    if m.bias is not None:
        lines += bias_lines(m.bias)
    if m.structure_choice is not None:
        lines.append(textwrap.fill(choice_message(m.structure_choice), 96))
    if m.hysteresis_choice is not None:
        lines.append(textwrap.fill(choice_line(m.hysteresis_choice), 96))
    if m.rate_transfer is not None:
        lines.append(textwrap.fill(m.rate_transfer.message(), 96))
    elif not spans_ramp_rates(list(m.train_ramp_rates_c_per_min)):
        rates = ", ".join(f"{r:.2g}" for r in m.train_ramp_rates_c_per_min)
        lines.append(textwrap.fill(
            f"note: the training logs hold one ramp rate ({rates} C/min): at other rates the "
            "compensation is an extrapolation that the data cannot check (give --test LOG "
            "to measure how far equally good models disagree there)", 96))
    return "\n".join(lines)
