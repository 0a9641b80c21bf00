"""fogsf fleet list, check and report: what the fleet's database says of its units.

`check` and `report` read the check's result from the fleet's cache when the fleet is at
the state it was computed at (`fleet.check.checked`); `--spec-ppm X` (list, report) says
of each unit within spec, out of spec or unsure (`fleet.records.spec_verdict`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
from collections import Counter
from pathlib import Path

from fogsf.errors import UserError
from fogsf.fleet.check import checked
from fogsf.fleet.names import shown
from fogsf.fleet.plateau_unit import is_plateau_unit
from fogsf.fleet.records import UnitRecord, spec_verdict, structure_of
from fogsf.fleet.report import check_out_dir, write_report
from fogsf.fleet.store import open_store


def _fmt(x: object, spec: str = ".2f") -> str:
    return format(x, spec) if isinstance(x, (int, float)) and math.isfinite(x) else "-"


def json_safe(x: object) -> object:
    """NaN and infinities as null (strict JSON)."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    return x


def _cell(name: str, width: int) -> str:
    """A unit's name in a table cell: escaped when a database an older fogsf wrote holds
    a name the rule now refuses (a newline would forge a row), cut to the column."""
    text = name if name.isprintable() else shown(name, width)
    return text[:width]


def check_spec(spec_ppm: float | None) -> None:
    if spec_ppm is not None and not (math.isfinite(spec_ppm) and spec_ppm > 0):
        raise UserError(f"--spec-ppm must be a positive number of ppm, got {spec_ppm:g}")


def spec_counts(units: list[UnitRecord], spec_ppm: float) -> str:
    """`spec 12 ppm (test RMS): 480 within, 12 out of spec, 8 unsure`."""
    n = Counter(spec_verdict(u, spec_ppm) for u in units)
    return (f"spec {spec_ppm:g} ppm (test RMS): {n['within spec']} within, "
            f"{n['out of spec']} out of spec, {n['unsure']} unsure")


def run_list(args: argparse.Namespace) -> int:

    spec = args.spec_ppm
    check_spec(spec)
    with open_store(args.fleet, "read") as store:
        units = store.units()
        where = store.location
    if args.json:
        rows = [u.as_dict() | ({} if spec is None else {"spec": spec_verdict(u, spec)})
                for u in units]
        print(json.dumps(json_safe(rows), indent=2))
        return 0
    print(f"{where}: {len(units)} unit(s)")
    plateau = [u for u in units if is_plateau_unit(u)]
    units = [u for u in units if not is_plateau_unit(u)]
    if units:
        _list_units(units, spec)
    if plateau:
        _list_plateau_units(plateau, spec)
    return 0


def _list_units(units: list[UnitRecord], spec: float | None) -> None:
    """The units trained on sample logs: their residual over the noise floor, interval."""
    row = "{:<16} {:>8} {:>5} {:<24} {:>10} {:>10} {:>13}  {}"
    print(row.format("unit", "chamber", "logs", "structure", "train x", "test x",
                     "interval x", "recorded (UTC)")
          + ("" if spec is None else f"  spec {spec:g} ppm"))
    for u in units:
        f = u.figures
        floor = f.get("noise_floor_ppm")
        iv = u.interval
        interval = (f"{iv['rms_lo_ppm'] / floor:.1f}-{iv['rms_hi_ppm'] / floor:.1f}"
                    if iv and floor else "-")
        print(row.format(_cell(u.unit, 16), f"{u.chamber_hours:.1f} h", len(u.logs),
                         structure_of(u)[:24],
                         _fmt(f.get("train_rms_over_floor")), _fmt(f.get("test_rms_over_floor")),
                         interval, u.created_utc)
              + ("" if spec is None else f"  {spec_verdict(u, spec)}"))
    print("x: RMS SF error left / the noise floor"
          + ("" if spec is None else f"; {spec_counts(units, spec)}"))


def _list_plateau_units(units: list[UnitRecord], spec: float | None) -> None:
    """The units calibrated on plateau tables: their tables' static figures (the largest
    temperature group's nonlinearity and asymmetry) and the RMS left on their plateaus."""
    row = "{:<16} {:>8} {:>11} {:>9} {:>10} {:>8} {:>8} {:>8} {:>8}  {}"
    print("plateau units (rate table):")
    print(row.format("unit", "plateaus", "T, C", "SF ppm/C", "nonlin ppm", "asym ppm",
                     "bias", "train", "test", "recorded (UTC)"))
    for u in units:
        f, m = u.figures, u.summary
        lo, hi = (m.get("temp_range_c") or [math.nan, math.nan])[:2]
        print(row.format(_cell(u.unit, 16), f.get("plateaus", "-"), f"{lo:.1f}-{hi:.1f}",
                         _fmt(m.get("sf_drift_ppm_per_c")),
                         _fmt(m.get("sf_nonlinearity_ppm_fs"), ".1f"),
                         _fmt(m.get("sf_asymmetry_ppm")), _fmt(m.get("bias_dph")),
                         _fmt(f.get("train_after_rms_dph")), _fmt(f.get("test_after_rms_dph")),
                         u.created_utc))
    print("SF ppm/C: the SF's drift with temperature; nonlin: ppm of full scale; bias, train, "
          "test: deg/h (train, test: RMS left on the plateaus against the rate each sensed)"
          + ("" if spec is None else "; --spec-ppm reads a test RMS in ppm: plateau units "
                                     "are unsure"))


def run_check(args: argparse.Namespace) -> int:

    result, _, _ = checked(args.fleet, args.false_alarm)
    print(result.message())
    if args.json:
        _write_atomic(Path(args.json), json.dumps(json_safe(result.as_dict()), indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


def run_report(args: argparse.Namespace) -> int:

    check_spec(args.spec_ppm)
    check_out_dir(Path(args.out))  # refused before the check's minutes, not after
    result, units, where = checked(args.fleet, args.false_alarm, with_units=True)
    if not units:
        raise UserError(f"{where} has no units (fogsf fleet add first)")
    index = write_report(units, result, Path(args.out), title=where, spec_ppm=args.spec_ppm)
    print(f"wrote {index} ({len(units)} units, {len(result.outliers)} flagged"
          + ("" if args.spec_ppm is None else f"; {spec_counts(units, args.spec_ppm)}")
          + ")")
    return 0


def _write_atomic(path: Path, text: str) -> None:
    """Write a file whole or not at all (a temporary file beside it, then renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False,
                                     prefix=f".{path.name}.") as f:
        f.write(text)
    os.replace(f.name, path)
