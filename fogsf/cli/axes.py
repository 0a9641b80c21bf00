"""`--axis all`: a command run once per axis of a multi-axis log, then one summary table.

Each command that takes it calls `run_all(args, run, COMMAND)` at the top of its own `run`
when `wants_all(args)`. For each axis A present (the log's gyro_A_dps columns and its column
map's, `logio.log_axes_of`; for export, MODEL_DIR's folders A/ holding a model) the
command's `run` is called again on a copy of the arguments with `args.axis = A` and its
per-axis arguments moved aside:

  - a model folder given (replay, export MODEL_DIR) or written (train --out, export --out):
    OUT/A, the folder `--axis A --out OUT/A` would write;
  - a file written (replay --out, --json, --plot; inspect --plot): NAME_A.EXT beside NAME.EXT;
  - a C name (export --name NAME): NAME_A.

What each axis prints comes under a `axis A:` line; the summary table follows, one row per
axis from what the command's run left in `args.axis_result`. The axes of every log must be
the same; `--axis-cosine` (docs/logs.md) gives each axis its own cosine.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from fogsf.cli.arguments import cosine_for, dialect_from_args
from fogsf.errors import UserError
from fogsf.logs.logio import log_axes_of

ALL = "all"


def wants_all(args: argparse.Namespace) -> bool:
    return getattr(args, "axis", None) == ALL


# per-axis arguments: "dir" (OUT/A), "file" (NAME_A.EXT), "name" (NAME_A)
Kind = str


def for_axis(value: str, kind: Kind, axis: str) -> str:
    """The per-axis form of an argument's value (see the module's docstring)."""
    if kind == "dir":
        return str(Path(value) / axis)
    if kind == "file":
        p = Path(value)
        return str(p.with_name(f"{p.stem}_{axis}{p.suffix}"))
    if kind == "name":
        return f"{value}_{axis}"
    raise ValueError(kind)


SF_TITLE = "SF error RMS in ppm (before: about the SF at 20 C or --ref-sf)"
BIAS_TITLE = "the bias in deg/h, STD over the bias windows (the logs measure no SF)"
BIAS_ONLY = "_bias_only"  # a row's marker (not a column): the row is the bias alone


@dataclass(frozen=True)
class Spec:
    """How a command runs per axis."""

    logs: Callable[[argparse.Namespace], list[str]]  # the logs read (empty: MODEL_DIR's axes)
    per_axis: dict[str, Kind]  # args attribute -> kind, for those given
    row: Callable[[dict], dict[str, object]]  # a summary row from args.axis_result
    json_stdout: bool = False  # with --json, stdout is one JSON object: {axis: ...}
    title: str = SF_TITLE


def summary_title(spec_title: str, rows: dict[str, dict[str, object]]) -> str:
    """The summary's title: the spec's, or the bias's when every row is the bias alone (a
    stationary log, a bias-only model: no SF figure to title)."""
    if spec_title == SF_TITLE and rows and all(r.get(BIAS_ONLY) for r in rows.values()):
        return BIAS_TITLE
    return spec_title


def _rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


def _bias_cells(b: dict | None, block: str = "test") -> dict[str, object]:
    """The bias columns of a summary row (deg/h; none when nothing measures the bias)."""
    if b is None:
        return {}
    if "std_dph" in b:  # inspect's bias block
        return {"bias std deg/h": f"{b['std_dph']:.4f}"}
    part = b.get(block) or next((v for v in b.get("train", {}).values() if v), None)
    if not part:
        return {}
    return {"bias before deg/h": f"{part['before']['std_dph']:.4f}",
            "bias after deg/h": f"{part['after']['std_dph']:.4f}"}


def _train_row(m: dict) -> dict[str, object]:
    if m.get("bias_only"):  # stationary logs: no SF figures
        return {"model": m["model"], **_bias_cells(m["bias"]), BIAS_ONLY: True}
    train = m["train"]
    blocks = [train] if "before" in train else list(train.values())
    row: dict[str, object] = {
        "model": m["model"],
        "train before": _rms([b["before"]["rms_ppm"] for b in blocks]),
        "train after": _rms([b["after"]["rms_ppm"] for b in blocks]),
        "noise floor": m["noise_floor_ppm"],
    }
    if "test" in m:
        row.update({"test before": m["test"]["before"]["rms_ppm"],
                    "test after": m["test"]["after"]["rms_ppm"]})
    return {**row, **_bias_cells(m.get("bias"))}


def _inspect_row(s: dict) -> dict[str, object]:
    m = s["metrics"]
    if m is None:  # a stationary log: its bias only
        return {"samples": s["samples"],
                "temp C": "{:.1f} .. {:.1f}".format(*s["temp_range_c"]),
                **_bias_cells(s.get("bias")), BIAS_ONLY: True}
    return {"samples": s["samples"], "temp C": "{:.1f} .. {:.1f}".format(*s["temp_range_c"]),
            "RMS": m["rms_ppm"], "p-p": m["pp_ppm"], "noise floor": m["noise_floor_ppm"],
            "ref SF ratio": f"{s['ref_sf_ratio']:.9f}"}


def _replay_row(r: dict) -> dict[str, object]:
    row: dict[str, object] = {"model": r["model_id"], "out": r["out"]}
    if r["before"] is not None:
        row.update({"before": r["before"]["rms_ppm"], "after": r["after"]["rms_ppm"],
                    "noise floor": r["before"]["noise_floor_ppm"]})
    row.update(_bias_cells(None if r.get("bias") is None else {"test": r["bias"]}))
    flagged = [f"{k} {v}" for k, v in r["flags"].items() if v]
    row["flags"] = ", ".join(flagged) or "none"
    if r.get("bias_only"):
        row[BIAS_ONLY] = True
    return row


def _export_row(r: dict) -> dict[str, object]:
    return {"C model": r["name"], "model": r["model_id"], "out": r["out"],
            "sample rate Hz": f"{r['sample_rate_hz']:.6g}", "D": r["decimation"]}


SPECS: dict[str, Spec] = {
    "train": Spec(lambda a: [*a.train, *([a.test] if a.test else [])], {"out": "dir"},
                  _train_row),
    "inspect": Spec(lambda a: [a.log], {"plot": "file"}, _inspect_row, json_stdout=True),
    "replay": Spec(lambda a: [a.log],
                   {"model": "dir", "out": "file", "json": "file", "plot": "file"},
                   _replay_row),
    "export": Spec(lambda a: [], {"model": "dir", "out": "dir", "name": "name", "blob": "file"},
                   _export_row,
                   title="one C model per axis"),
}


def axes_of_logs(args: argparse.Namespace, paths: list[str]) -> list[str]:
    """The axes every log has (the first log's order); a log without any, or with other
    axes than the first, is refused in one line."""
    if getattr(args, "gyro_column", None) is not None:
        raise UserError("give --axis all or --gyro-column, not both")
    dialect = dialect_from_args(argparse.Namespace(**{**vars(args), "axis": None}))
    found = [(p, log_axes_of(p, dialect)) for p in paths]  # the header (and map) only
    for p, axes in found:
        if not axes:
            raise UserError(f"--axis all: {p} has no per-axis gyro columns (gyro_A_dps, e.g. "
                            "gyro_x_dps); read a one-axis log without --axis")
    first_path, first = found[0]
    for p, axes in found[1:]:
        if axes != first:
            raise UserError(f"--axis all: {p} has axes {', '.join(axes)}, {first_path} "
                            f"{', '.join(first)}: give logs of the same axes")
    return first


def axes_of_model_dir(model_dir: str) -> list[str]:
    """The folders A/ of MODEL_DIR that hold a model (stream.json), sorted."""
    root = Path(model_dir)
    axes = sorted(p.name for p in root.iterdir() if (p / "stream.json").is_file()) \
        if root.is_dir() else []
    if not axes:
        raise UserError(f"--axis all: {model_dir} holds no model folder per axis (A/ with "
                        "stream.json, as `fogsf train --axis all --out` writes)")
    return axes


def axis_args(args: argparse.Namespace, spec: Spec, axis: str) -> argparse.Namespace:
    """A copy of `args` for one axis: args.axis = axis, the per-axis arguments moved aside."""
    out = argparse.Namespace(**vars(args))
    out.axis = axis
    for attr, kind in spec.per_axis.items():
        value = getattr(args, attr, None)
        if value is not None:
            setattr(out, attr, for_axis(str(value), kind, axis))
    return out


def _check_models(args: argparse.Namespace, axes: list[str]) -> None:
    """replay: MODEL_DIR must hold a model per axis of the log."""
    missing = [a for a in axes if not (Path(args.model) / a / "stream.json").is_file()]
    if missing:
        raise UserError(f"--axis all: {args.model} has no model for axis "
                        f"{', '.join(missing)} ({args.model}/A/stream.json, as `fogsf train "
                        "--axis all --out` writes)")


def _check_folders(args: argparse.Namespace, spec: Spec) -> None:
    """A folder argument (OUT of OUT/A) that exists as a file is refused before any work."""
    for attr, kind in spec.per_axis.items():
        value = getattr(args, attr, None)
        if kind == "dir" and value is not None and Path(value).exists() \
                and not Path(value).is_dir():
            raise UserError(f"--axis all: {value} is a file; it takes a folder of one "
                            "folder per axis (A/)")


def _run_axis(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """`run` for one axis; its refusal names the axis."""
    try:
        return run(args)
    except UserError as e:
        raise UserError(f"axis {args.axis}: {e}") from None


def run_all(args: argparse.Namespace, run: Callable[[argparse.Namespace], int],
            command: str) -> int:
    """`run` once per axis (module docstring), then the summary table; the first axis that
    fails stops the run."""
    spec = SPECS[command]
    paths = spec.logs(args)
    axes = axes_of_logs(args, paths) if paths else axes_of_model_dir(args.model)
    if paths and "model" in spec.per_axis:
        _check_models(args, axes)
    for a in axes:  # a per-axis --axis-cosine without this axis: refused before any work
        cosine_for(getattr(args, "axis_cosine", None), a)
    _check_folders(args, spec)
    as_json = spec.json_stdout and getattr(args, "json", False)
    rows, docs = {}, {}
    for a in axes:
        one = axis_args(args, spec, a)
        if as_json:
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                status = _run_axis(run, one)
            docs[a] = json.loads(buf.getvalue())
        else:
            print(f"axis {a}:")
            status = _run_axis(run, one)
        if status:
            return status
        rows[a] = spec.row(one.axis_result)
    if as_json:
        print(json.dumps(docs, indent=2))
    else:
        print(summary_table(rows, summary_title(spec.title, rows)))
    return 0


def _cell(v: object) -> str:
    return f"{v:.2f}" if isinstance(v, float) else str(v)


def summary_table(rows: dict[str, dict[str, object]], title: str) -> str:
    """One line per axis, the columns of the rows (ppm figures to 0.01)."""
    cols: list[str] = []
    for r in rows.values():
        cols += [c for c in r if c not in cols and c != BIAS_ONLY]
    table = [["axis", *cols]] + [[a, *(_cell(r.get(c, "")) for c in cols)]
                                 for a, r in rows.items()]
    widths = [max(len(line[i]) for line in table) for i in range(len(table[0]))]
    text = ["  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w)
                      in enumerate(zip(line, widths, strict=True))) for line in table]
    return "\n".join([f"summary, {title}:", *("  " + t for t in text)])
