"""fogsf fleet: the units of one design, calibrated together, in one database.

FLEET is an SQLite file (`add` and `add-many` create it; the other actions need it) or a
postgresql:// URL that several chambers share (the password in PGPASSWORD or ~/.pgpass).
`add` trains a unit exactly as `fogsf train` does (the same options; on a rate table's
plateau tables, the plateau model: `fleet.plateau_unit`) and records it: its
logs (path, sha256, rows, span, ramp rates), its model (id, what it was fitted with, the
parameters the design's prior needs), its figures and interval, the fogsf version and the
time, in one transaction (a killed add leaves the database as it was). `add-many` adds the
units of a manifest in parallel; `list` and `remove` what the title says; `check` names the
units unlike the line; `report` writes a static HTML report (docs/fleet.md); `--spec-ppm X`
(list, report) says of each unit within spec, out of spec or unsure. list, check and report
live in `cli.fleet_views`. `add --model-dir DIR` records the model a training kept in DIR
(the unit's logs given as for add) without training again (`fleet.kept_model`): the
retry a failed add names.

Examples:
  fogsf fleet add line.fleet --unit SN001 --train SN001_loop.csv --test SN001_test.csv
  fogsf fleet add line.fleet --unit SN001 --train SN001_loop.csv --model-dir models/SN001
  fogsf fleet add-many line.fleet units.csv --workers 4
  fogsf fleet list line.fleet
  fogsf fleet check line.fleet --json outliers.json
  fogsf fleet report line.fleet --out report/ --spec-ppm 12
  fogsf fleet export line.fleet --out blocks/
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fogsf.cli import fleet_export
from fogsf.cli import train as train_cli
from fogsf.cli.arguments import cosine_for, read_logs
from fogsf.cli.fleet_views import run_check, run_list, run_report
from fogsf.cli.main import OneLineParser, build_parser, main
from fogsf.cli.plateau_commands import (
    any_plateau_table,
    fit_tables,
    read_tables,
    refuse_sample_options,
)
from fogsf.cli.train import format_metrics, train_options
from fogsf.errors import UserError
from fogsf.fleet import kept_model
from fogsf.fleet.batch import run_local
from fogsf.fleet.check import DEFAULT_FALSE_ALARM
from fogsf.fleet.faults import db_faults
from fogsf.fleet.lease import BatchLease, check_batch, is_lease_id
from fogsf.fleet.manifest import ManifestRow, read_manifest
from fogsf.fleet.names import check_unit_name, masked, shown
from fogsf.fleet.new_unit import refuse_stationary
from fogsf.fleet.plateau_unit import plateau_record
from fogsf.fleet.records import UnitRecord, recorded_options, structure_of, unit_record
from fogsf.fleet.store import fleet_exists, open_store
from fogsf.gsa.executors import default_workers, open_executor
from fogsf.scratch import temp_dir
from fogsf.training.train import run_training

FLEET_HELP = ("the fleet: an SQLite file or a postgresql:// URL (its password from "
              "PGPASSWORD or ~/.pgpass, not the URL)")


def configure(parser: argparse.ArgumentParser) -> None:

    sub = parser.add_subparsers(dest="fleet_command", metavar="ACTION", required=True,
                                parser_class=OneLineParser)

    p = _action(sub, "add", "train a unit as `fogsf train` does and record it",
                "fogsf fleet add line.fleet --unit SN001 --train SN001_loop.csv "
                "--test SN001_test.csv --out models/SN001")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    train_cli.configure(p)
    for action in p._actions:  # the model folder is an output the fleet does not need
        if action.dest == "out":
            action.required = False
            action.help = "model folder to keep (default: none, the database holds the unit)"
        if action.dest == "unit":  # train's --unit (with --prior): here it is required
            action.required = True
            action.help = "the unit's serial number"
    if "--unit" not in p._option_string_actions:
        p.add_argument("--unit", required=True, metavar="SN", help="the unit's serial number")
    p.add_argument("--replace", action="store_true",
                   help="record the unit again if FLEET already has it")
    p.add_argument("--model-dir", default=None, metavar="DIR",
                   help="record the model a training kept in DIR (fleet add --out, fogsf "
                        "train --out) without training again: the same logs and options as "
                        "it was trained with, checked (the retry a failed add prints)")
    p.add_argument("--batch", default=None, help=argparse.SUPPRESS)  # add-many's lease id
    p.set_defaults(_fleet_run=run_add)

    p = _action(sub, "add-many", "add the units of a manifest, several at once",
                "fogsf fleet add-many line.fleet units.csv --workers 4")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    p.add_argument("manifest", metavar="MANIFEST.csv",
                   help="columns unit, train (logs separated by ';'), test and out (both "
                        "optional); relative paths are read from the manifest's folder")
    p.add_argument("--train-options", default="", metavar='"OPTIONS"',
                   help='`fogsf train` options for every unit, e.g. "--structure physics '
                        '--nodes 2 --seed 1"')
    p.add_argument("--replace", action="store_true", help="record units FLEET has again")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="units trained at once in local processes (default: one per core; "
                        "1 = one after another)")
    p.add_argument("--dask", default=None, metavar="SCHEDULER_ADDRESS",
                   help="train them on a Dask cluster instead, e.g. tcp://10.0.0.5:8786 "
                        "(its workers need fogsf and must reach the logs and FLEET)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(_fleet_run=run_add_many)

    p = _action(sub, "list", "the fleet's units and their figures",
                "fogsf fleet list line.fleet --json")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    p.add_argument("--json", action="store_true", help="every record as JSON on stdout")
    _spec_option(p)
    p.set_defaults(_fleet_run=run_list)

    p = _action(sub, "remove", "remove a unit (its model folder stays)",
                "fogsf fleet remove line.fleet SN001")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    p.add_argument("unit", metavar="SN", help="the unit's serial number")
    p.set_defaults(_fleet_run=run_remove)


    p = _action(sub, "check", "name the units unlike the line, and why",
                "fogsf fleet check line.fleet --json outliers.json")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    p.add_argument("--json", metavar="F", default=None,
                   help='write {"outliers": [{"unit": SN, "why": ...}], ...} to F')
    p.add_argument("--false-alarm", type=float, default=DEFAULT_FALSE_ALARM, metavar="P",
                   help="chance that a line of normal units gives any flag (default "
                        f"{DEFAULT_FALSE_ALARM:g}); Bonferroni over parameters and units")
    p.set_defaults(_fleet_run=run_check)

    p = _action(sub, "report", "a static HTML report of the fleet (opens from disk)",
                "fogsf fleet report line.fleet --out report/ && xdg-open report/index.html")
    p.add_argument("fleet", metavar="FLEET", help=FLEET_HELP)
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write")
    p.add_argument("--false-alarm", type=float, default=DEFAULT_FALSE_ALARM, metavar="P",
                   help=f"the check's false-alarm rate (default {DEFAULT_FALSE_ALARM:g})")
    _spec_option(p)
    p.set_defaults(_fleet_run=run_report)

    fleet_export.configure(_action(sub, "export", "one calibration block per unit and a "
                                   "manifest (firmware: docs/firmware.md)",
                                   fleet_export.EXAMPLE), FLEET_HELP)


def _spec_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--spec-ppm", type=float, default=None, metavar="X",
                   help="each unit within spec (the interval training stated for its test "
                        "RMS tops at or under X ppm), out of spec (its bottom over X) or "
                        "unsure")


def _action(sub: argparse._SubParsersAction, name: str, help_text: str, example: str
            ) -> argparse.ArgumentParser:
    return sub.add_parser(name, help=help_text, description=help_text + ".",
                          epilog=f"Example:\n  {example}",
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def run(args: argparse.Namespace) -> int:
    try:
        with db_faults(masked(args.fleet)):  # a database's fault: one line, exit status 2
            return int(args._fleet_run(args) or 0)
    except BrokenPipeError:  # the reader went (`fogsf fleet list | head`): stop quietly
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # stdout is no file (captured): nothing to silence
            pass
        return 141  # a shell's status for a writer its pipe's reader left (128 + SIGPIPE)


# --- add ------------------------------------------------------------------------------------

def run_add(args: argparse.Namespace) -> int:

    check_unit_name(args.unit)  # before anything is opened or trained
    if args.batch is not None and not is_lease_id(args.batch):
        raise UserError(f"--batch {args.batch!r} names no batch (add-many's own option; "
                        "the LSTM's batch size is --batch-size): the unit is not recorded")
    if getattr(args, "prior", None):
        raise UserError("fleet add trains the unit alone, as `fogsf train` does; to fit it "
                        "under the design's prior and record it: fogsf train --prior FLEET "
                        "--unit SN ...")
    kept = args.model_dir
    if kept and args.out and Path(args.out).resolve() != Path(kept).resolve():
        raise UserError(f"--out {args.out} is a folder to train into and --model-dir {kept} "
                        "the model a training kept: give one of them")
    # A unit already there is refused before training; the fleet is created only to record
    # the unit, so that a refused add leaves no empty fleet behind.
    if fleet_exists(args.fleet):
        with open_store(args.fleet, "create") as store:
            if store.has(args.unit) and not args.replace:
                raise UserError(f"unit {shown(args.unit)} is already in {store.location} "
                                "(--replace to record it again, or `fogsf fleet remove`)")
    tables = any_plateau_table(args, args.train + ([args.test] if args.test else []))
    if kept:  # the folder checked before the logs are read
        model = kept_model.read_kept(kept, plateau_logs=tables)
        record = _kept_tables(args, model) if tables else _kept_logs(args, model)
    else:
        with temp_dir("fleet-") as tmp:
            out = Path(args.out) if args.out else tmp
            if out.exists() and not out.is_dir():
                raise UserError(f"--out {out} exists and is not a directory")
            record = _fit_tables(args, out) if tables else _fit_logs(args, out)
            if args.out:  # what a retry with --model-dir checks its logs and options against
                kept_model.write_kept(out, record)
    try:
        with db_faults(masked(args.fleet)), open_store(args.fleet, "create") as store:
            # a unit of a batch (any --batch given) is recorded only while its batch runs
            store.add(record, replace=args.replace, guard=None if args.batch is None else
                      lambda s: check_batch(s, args.batch))
            n = len(store.units())
    except UserError as e:  # the hour of training is not lost with the record
        if kept:
            raise UserError(f"{e}; not recorded (the model stays in {kept})") from None
        raise UserError(f"{e}; the trained model is kept in {args.out}; record it without "
                        f"training again: {_retry(args)}" if args.out else
                        f"{e}; not recorded (--out DIR keeps the trained model)") from None
    print(f"recorded unit {record.unit} in {store.location} ({n} unit{'s' if n != 1 else ''}); "
          f"structure {structure_of(record)}"
          + (f", model in {args.out}" if args.out and not kept else "")
          + (f", model in {kept} (recorded from it, not trained)" if kept else ""))
    return 0


def _retry(args: argparse.Namespace) -> str:
    """The add that records the model kept: --model-dir for --out, add-many's lease left out."""
    argv = list(getattr(args, "_argv", None) or ["fleet", "add", args.fleet, "--unit", args.unit])
    return kept_model.retry_command(argv[argv.index("add") + 1:], ("--batch", "--out"),
                                    args.out)


def _fit_logs(args: argparse.Namespace, out: Path) -> UnitRecord:
    """The unit trained on sample logs as `fogsf train` trains it, into `out`; its record."""
    train_logs = read_logs(args, args.train, on_disk=True, training=True)
    refuse_stationary(train_logs)
    test_log = read_logs(args, [args.test], on_disk=True)[0] if args.test else None
    opts = train_options(args)
    metrics, fitted = run_training(opts, train_logs, test_log, out)
    print(format_metrics(metrics))
    return unit_record(args.unit, train_logs, test_log, metrics, fitted, out,
                       recorded_options(opts), keep_dir=bool(args.out))


def _fit_tables(args: argparse.Namespace, out: Path) -> UnitRecord:
    """The unit's plateau model fitted on its plateau tables as `fogsf train` fits it, into
    `out`; its record (`fleet.plateau_unit`)."""
    train, test, fit, metrics = fit_tables(args, out, allowed=("unit",))
    return plateau_record(args.unit, train, test, fit.model, metrics, out,
                          _plateau_options(args), keep_dir=bool(args.out))


def _plateau_options(args: argparse.Namespace) -> dict[str, Any]:
    return {"latitude_deg": args.latitude_deg,
            "axis_cosine": cosine_for(getattr(args, "axis_cosine", None),
                                      getattr(args, "axis", None))}


def _kept_logs(args: argparse.Namespace, model: kept_model.KeptModel) -> UnitRecord:
    """The unit's record from the model in --model-dir and its sample logs, not trained."""
    train_logs = read_logs(args, args.train, on_disk=True, training=True)
    test_log = read_logs(args, [args.test], on_disk=True)[0] if args.test else None
    record = kept_model.kept_record(args.unit, train_logs, test_log, model,
                                    recorded_options(train_options(args)))
    print(format_metrics(model.metrics))
    return record


def _kept_tables(args: argparse.Namespace, model: kept_model.KeptModel) -> UnitRecord:
    """The unit's record from the plateau model in --model-dir and its tables."""
    refuse_sample_options(args, allowed=("unit",))  # as the add that trains refuses them
    train = read_tables(args, args.train)
    test = read_tables(args, [args.test])[0] if args.test else None
    record = kept_model.kept_plateau_record(args.unit, train, test, model, _plateau_options(args))
    print(format_metrics(model.metrics))
    return record


def add_one(argv: list[str]) -> tuple[int, str]:
    """One unit of add-many, in a worker: `fogsf fleet add ARGV`; (exit status, what it
    printed)."""
    import contextlib
    import io


    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        try:
            code = main(["fleet", "add", *argv])
        except SystemExit as e:  # argparse's refusal of an option
            code = int(e.code or 0) if not isinstance(e.code, str) else 2
    return code, buf.getvalue()


def run_add_many(args: argparse.Namespace) -> int:

    rows = read_manifest(args.manifest)
    extra = shlex.split(args.train_options)
    for bad in ("--unit", "--train", "--test", "--out"):
        if bad in extra:
            raise UserError(f"--train-options: {bad} comes from the manifest's columns")
    _, unknown = build_parser(("fleet",)).parse_known_args(  # as each unit's add reads them
        ["fleet", "add", "F", "--unit", "U", "--train", "T", *extra])
    if unknown:
        raise UserError(f"--train-options: fleet add knows no {' '.join(unknown)}")
    workers = default_workers() if args.workers is None else args.workers
    if workers < 1:
        raise UserError(f"--workers must be at least 1, got {workers}")
    have: set[str] = set()
    where = masked(args.fleet)  # the password masked: the URL itself is never printed
    if fleet_exists(args.fleet):  # else the batch's lease creates it, after every refusal
        with open_store(args.fleet, "create") as store:  # migrated before the workers
            have = {r.unit for r in store.units()}
    clash = [r.unit for r in rows if r.unit in have]
    if clash and not args.replace:
        raise UserError(f"{args.manifest}: {len(clash)} unit(s) already in {where}: "
                        f"{', '.join(clash[:5])} (--replace to record them again)")
    failed: list[str] = []

    def said(r: ManifestRow, code: int, text: str) -> None:  # each unit as it ends
        last = [ln for ln in text.strip().splitlines() if ln.strip()]
        if code == 0:
            print(f"{r.unit}: {last[-1] if last else 'recorded'}", flush=True)
        else:
            failed.append(r.unit)
            print(f"{r.unit}: FAILED: {last[-1] if last else f'exit status {code}'}",
                  flush=True)

    from tqdm import tqdm

    # The batch's lease: a unit whose batch is gone (this process killed) is not recorded.
    with BatchLease(args.fleet) as lease, \
            tqdm(total=len(rows), desc="units", unit="unit",
                 disable=args.no_progress or not sys.stderr.isatty()) as bar:
        argvs = [_unit_argv(args, r, extra, lease.id) for r in rows]

        def done(i: int, code: int, text: str) -> None:
            said(rows[i], code, text)
            bar.update()

        if args.dask:
            _run_dask(args.dask, argvs, done)
        elif workers == 1:  # here, one after another: nothing outlives this process
            for i, argv in enumerate(argvs):
                done(i, *add_one(argv))
        else:  # children that die with this process (fleet.batch)
            run_local(argvs, workers, done)
    print(f"{len(rows) - len(failed)} of {len(rows)} units recorded in {where}")
    if failed:
        raise UserError(f"{len(failed)} unit(s) not recorded: {', '.join(failed)}")
    return 0


def _unit_argv(args: argparse.Namespace, r: ManifestRow, extra: list[str], batch: str
               ) -> list[str]:
    """`fogsf fleet add` arguments of one manifest row."""
    argv = [args.fleet, "--unit", r.unit, "--workers", "1", "--no-progress", *extra]
    for t in r.train:
        argv += ["--train", t]
    argv += ["--test", r.test] if r.test else []
    argv += ["--out", r.out] if r.out else []
    return argv + (["--replace"] if args.replace else []) + ["--batch", batch]


def _run_dask(address: str, argvs: list[list[str]], done: Callable[[int, int, str], None]
              ) -> None:
    """The units on a Dask cluster. Units not started when this process goes are
    forgotten with its client (the scheduler drops a lost client's futures); a unit
    already training finishes there, and its batch's lease refuses it."""
    from concurrent.futures import as_completed

    with open_executor(dask=address) as ex:
        assert ex is not None
        futs = {ex.submit(add_one, argv): i for i, argv in enumerate(argvs)}
        try:
            for f in as_completed(futs):
                done(futs[f], *f.result())
        finally:  # an error or Ctrl-C here: the rest is not run
            for f in futs:
                f.cancel()


# --- remove ----------------------------------------------------------------------------------

def run_remove(args: argparse.Namespace) -> int:

    with open_store(args.fleet, "write") as store:  # the fleet first: swapped arguments
        store.remove(args.unit)
        n = len(store.units())
    print(f"removed unit {args.unit} from {store.location} ({n} units left)")
    return 0
