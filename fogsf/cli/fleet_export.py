"""fogsf fleet export: one calibration block per unit of a fleet, and their manifest.

Each unit's model is read from the model folder `fleet add --out` kept (checked against the
model id the fleet recorded), written as its block (`fogsf export --blob`: docs/firmware.md,
"Calibration block") to OUT/FILE.bin, and listed in OUT/manifest.csv: serial, model id, the
block's file, its bytes and SHA-256, one row a unit in serial order. FILE is the serial where
it is a plain file name (letters, digits, '.', '_', '-'), else the serial with the other
characters as '_' and 8 hex digits of its SHA-256 (so two serials never share a file).
The same fleet gives the same files.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import re
from pathlib import Path

from fogsf.errors import UserError
from fogsf.export.block import block_bytes
from fogsf.fleet.names import shown
from fogsf.fleet.records import UnitRecord
from fogsf.fleet.store import open_store
from fogsf.models.stream import StreamModel

MANIFEST = "manifest.csv"
COLUMNS = ("serial", "model_id", "block", "bytes", "sha256")
PLAIN = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")
EXAMPLE = "fogsf fleet export line.fleet --out blocks/"


def configure(p: argparse.ArgumentParser, fleet_help: str) -> None:
    p.add_argument("fleet", metavar="FLEET", help=fleet_help)
    p.add_argument("--out", required=True, metavar="DIR",
                   help=f"folder to write (created): one SERIAL.bin a unit and {MANIFEST}")
    p.set_defaults(_fleet_run=run)


def block_name(serial: str) -> str:
    """The block's file name for a serial (see the module's docstring)."""
    if PLAIN.fullmatch(serial):
        return f"{serial}.bin"
    safe = re.sub(r"[^A-Za-z0-9_-]", "_", serial)[:40]
    return f"{safe}-{hashlib.sha256(serial.encode()).hexdigest()[:8]}.bin"


def unit_model(unit: UnitRecord) -> StreamModel:
    """The unit's model from its kept folder, refused unless it is the one recorded."""
    if not unit.model_dir:
        raise UserError(f"unit {shown(unit.unit)}: the fleet kept no model folder for it "
                        "(added without --out): add it again with --out DIR --replace")
    if not Path(unit.model_dir).is_dir():
        raise UserError(f"unit {shown(unit.unit)}: its model folder {unit.model_dir} is gone")
    model = StreamModel.load(unit.model_dir)
    if model.model_id != unit.model_id:
        raise UserError(f"unit {shown(unit.unit)}: {unit.model_dir} holds model "
                        f"{model.model_id}, the fleet recorded {unit.model_id}: the folder "
                        "changed since the unit was added")
    return model


def run(args: argparse.Namespace) -> int:
    with open_store(args.fleet, "read") as store:
        units = store.units()
    if not units:
        raise UserError(f"{args.fleet}: the fleet has no units to export")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    blocks = [(u, unit_model(u)) for u in units]  # every unit checked before a file is written
    out.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(COLUMNS)
    for unit, model in blocks:
        data = block_bytes(model)
        name = block_name(unit.unit)
        (out / name).write_bytes(data)
        digest = hashlib.sha256(data).hexdigest()
        writer.writerow((unit.unit, model.model_id, name, len(data), digest))
        print(f"{shown(unit.unit)}: model {model.model_id}, {out / name} ({len(data)} bytes, "
              f"sha256 {digest[:16]})")
    (out / MANIFEST).write_text(text.getvalue())
    print(f"wrote {len(blocks)} blocks and {out / MANIFEST}")
    return 0
