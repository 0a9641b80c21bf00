"""`fogsf train`, `replay` and `diagnose` on plateau tables (docs/train.md and
docs/diagnose.md, "Plateau tables"): the model of the SF as a function of rate and
temperature, the plateaus corrected by the compiled kernel one row per plateau, and the rate
terms the tables show beyond the simulator's gyro."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.cli.arguments import cosine_for, dialect_from_args
from fogsf.diagnose.rate_terms import FOUND_GAIN, RateDiagnosis, diagnose_rate
from fogsf.errors import UserError
from fogsf.logs.plateau_table import PlateauTable, is_plateau_table, read_plateau_table
from fogsf.logs.read.parquet_log import is_parquet, write_columns
from fogsf.logs.writer import write_rows
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_NAMES
from fogsf.training.metrics_file import to_json
from fogsf.training.rate.plateau_model import PlateauFit, PlateauRows, choice_rows
from fogsf.training.rate.plateau_train import (
    check_static,
    metrics_lines,
    rms_dph,
    rows_of,
    save_plateau_model,
    train_plateaus,
)
from fogsf.training.results import PlateauMetrics

# the options of a sample log's training that a plateau model has no use for
TRAIN_ONLY_SAMPLES = ("prior", "unit", "structure", "nodes", "node", "ref_sf")


def any_plateau_table(args: argparse.Namespace, paths: list[str]) -> bool:
    """True when one of `paths` is a plateau table; then all must be (one line, exit 2)."""
    dialect = dialect_from_args(args)
    kinds = {p: is_plateau_table(p, dialect) for p in paths}
    if any(kinds.values()) and not all(kinds.values()):
        tables = [p for p, k in kinds.items() if k]
        samples = [p for p, k in kinds.items() if not k]
        raise UserError(f"{tables[0]} is a plateau table and {samples[0]} a sample log: train "
                        "on one kind (a plateau model has no time series for a sample log's "
                        "dynamics)")
    return any(kinds.values())


def read_tables(args: argparse.Namespace, paths: list[str]) -> list[PlateauTable]:
    out = []
    for p in paths:
        t = read_plateau_table(p, dialect_from_args(args))
        if t.read_notes:
            print(f"fogsf: read {t.path}: {'; '.join(t.read_notes)}", file=sys.stderr)
        out.append(t)
    return out


def _cosine(args: argparse.Namespace) -> float:
    return cosine_for(getattr(args, "axis_cosine", None), getattr(args, "axis", None))


def refuse_sample_options(args: argparse.Namespace, allowed: tuple[str, ...] = ()) -> None:
    """One line, exit 2, for a sample log's training option given with plateau tables
    (`allowed`: those the caller takes for itself)."""
    given = [o for o in TRAIN_ONLY_SAMPLES if o not in allowed and getattr(args, o, None)]
    given += ["hysteresis"] if getattr(args, "hysteresis", "auto") != "auto" else []
    if given:
        raise UserError(f"--{given[0].replace('_', '-')} is for sample logs: a plateau table "
                        "trains the plateau model (docs/train.md, \"Plateau tables\")")


def fit_tables(args: argparse.Namespace, out: Path, allowed: tuple[str, ...] = ()
               ) -> tuple[list[PlateauTable], PlateauTable | None, PlateauFit, PlateauMetrics]:
    """The plateau model of `args.train`'s tables (scored on `args.test`'s), saved into `out`
    and its figures printed, as `fogsf train` fits it; `allowed`: sample-log options the
    caller takes for itself (fleet add's --unit)."""
    refuse_sample_options(args, allowed)
    train = read_tables(args, args.train)
    test = read_tables(args, [args.test])[0] if args.test else None
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    fit, metrics = train_plateaus(train, test, args.latitude_deg, _cosine(args))
    save_plateau_model(fit, metrics, out)
    print("\n".join(metrics_lines(metrics)))
    return train, test, fit, metrics


def train_tables(args: argparse.Namespace) -> int:
    """`fogsf train --train TABLE ... [--test TABLE] --out DIR` on plateau tables."""
    out = Path(args.out)
    _, _, _, metrics = fit_tables(args, out)
    args.axis_result = to_json(metrics)
    print(f"wrote {out}/metrics.json and the firmware artifact (fogsf export {out} --out "
          "build/...)")
    return 0


def kernel_rows(kernel: Kernel, temp_c: np.ndarray, gyro_dps: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(corrected, flags) per row, each from a fresh state: a static model's output for a
    sample at that temperature (`plateau_train.correct_rows` in numpy)."""
    out = np.empty(len(temp_c))
    flags = np.zeros(len(temp_c), np.uint32)
    for i in range(len(temp_c)):
        c, _, f = kernel.run(temp_c[i:i + 1], gyro_dps[i:i + 1])
        out[i], flags[i] = c[0], f[0]
    return out, flags


def replay_table(args: argparse.Namespace) -> int:
    """`fogsf replay MODEL TABLE --out CSV`: one row per plateau, its columns and
    gyro_corrected_dps and flags; before and after against the rate each plateau sensed."""
    model = StreamModel.load(args.model)
    check_static(model, args.model)
    table = read_tables(args, [args.log])[0]
    build = build_kernel(model, root=args.build_dir, cc=args.cc)
    corrected, flags = kernel_rows(Kernel(model, build), table.temp_c, table.gyro_dps)
    cols = {"time_s": table.time_s, "duration_s": table.duration_s,
            "table_rate_dps": table.table_rate_dps, "gyro_dps": table.gyro_dps,
            "temp_c": table.temp_c, "gyro_corrected_dps": corrected,
            "flags": flags.astype(np.float64)}
    _write(Path(args.out), cols)
    print(f"kernel {build.shared} (model {model.model_id}); corrected {len(table)} plateaus "
          f"of {table.path}; wrote {args.out}")
    counts = {name: int(np.count_nonzero(flags & bit)) for bit, name in FLAG_NAMES.items()}
    flagged = {k: v for k, v in counts.items() if v}
    print("flags: " + (", ".join(f"{k} {v}" for k, v in flagged.items()) if flagged
                       else "none"))
    keep = table.measures
    rate = (table.table_rate_dps + table.earth(args.latitude_deg, _cosine(args)))[keep]
    before, after = rms_dph(table.gyro_dps[keep] - rate), rms_dph(corrected[keep] - rate)
    print(f"plateaus' error against the rate each sensed (table + earth): before "
          f"{before:.2f} deg/h RMS, after {after:.2f} deg/h RMS")
    args.axis_result = {"model_id": model.model_id, "plateaus": len(table),
                        "before_dph": before, "after_dph": after, "flags": flagged}
    return 0


def _write(path: Path, cols: dict[str, np.ndarray]) -> None:
    if is_parquet(path):
        write_columns(path, cols)
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    names = list(cols)
    fmts = ["%.3f", "%.3f", "%.10g", "%.12g", "%.6f", "%.12g", "%d"]
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(names) + "\n")
        write_rows(f, np.column_stack([cols[n] for n in names]), fmts)


def diagnose_tables(args: argparse.Namespace) -> int:
    """`fogsf diagnose TABLE ...`: the rate terms the tables show beyond the simulator's
    linear SF, named, and the plateau model's gain (docs/diagnose.md, "Plateau tables")."""
    tables = read_tables(args, args.logs)
    unused = [o for o, v in (("--report", args.report), ("--config-out", args.config_out),
                             ("--effects", args.effects), ("--cv", args.cv != "blocks"),
                             ("--start", args.start != "auto")) if v]
    if unused:
        print(f"fogsf: {', '.join(unused)} not used: a plateau table", file=sys.stderr)
    rows = rows_of(tables, args.latitude_deg, _cosine(args))
    fs = float(np.max(np.abs(rows.rate_dps)))
    t_ref = round(0.5 * (float(rows.temp_c.min()) + float(rows.temp_c.max())), 1)
    d = diagnose_rate(choice_rows(rows, fs, t_ref), fs, allow=rows.rates_measured >= 2)
    lines = diagnosis_lines(d, tables, rows)
    print("\n".join(lines))
    j = {"plateau_table": True, "base_dph": d.base_dph,
         "named": [asdict(t) for t in d.named],
         "steps": [[asdict(t) for t in step] for step in d.steps],
         "nonlinearity_form": d.nonlinearity_form, "asymmetry": d.asymmetry,
         "model_form": d.model_form, "model_dph": d.model_dph,
         "rate_part_measured": d.rate_part_measured}
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(j, indent=2) + "\n", encoding="utf-8")
    args.axis_result = j
    return 0


def diagnosis_lines(d: RateDiagnosis, tables: list[PlateauTable], rows: PlateauRows
                    ) -> list[str]:
    names = ", ".join(t.path for t in tables)
    out = [f"{names}: {len(rows)} plateaus, {rows.temp_c.min():.1f} .. "
           f"{rows.temp_c.max():.1f} C, |rate| to {np.max(np.abs(rows.rate_dps)):.4g} deg/s",
           f"  the simulator's gyro (SF linear in rate; bias and SF polynomials of T): "
           f"held-out {d.base_dph:.2f} deg/h RMS"]
    if not d.rate_part_measured:
        out.append("  the tables hold one |rate| only: no rate term can be told from the SF")
        return out
    for k, step in enumerate(d.steps):
        onto = "to the base" if k == 0 else "to those named"
        out.append(f"  step {k + 1}, each term added {onto} (held-out deg/h RMS): "
                   + ", ".join(f"{t.term} {t.heldout_dph:.2f}" for t in step))
    if not d.named:
        out.append(f"  named: none (no term lowers the held-out RMS {FOUND_GAIN:g} times)")
    for t in d.named:
        what = {"sine": "rate nonlinearity: an open-loop FOG's sine",
                "odd polynomial": "rate nonlinearity: a polynomial (closed-loop)",
                "asymmetry": "asymmetry between + and - rates",
                "even terms": "even rate terms"}[t.term]
        extra = (f" (phase at full scale {t.phase_rad:.3f} rad, moving "
                 f"{t.phase_ppm_per_c:+.0f} ppm/C)" if t.phase_rad is not None else "")
        out.append(f"  named: {what}{extra}, held-out {t.heldout_dph:.2f} deg/h RMS")
    out.append(f"  extended model (what fogsf train fits: {d.model_form}): held-out "
               f"{d.model_dph:.2f} deg/h RMS, {d.base_dph / d.model_dph:.3g}x below the "
               "simulator's")
    return out
