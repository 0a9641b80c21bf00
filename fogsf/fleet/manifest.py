"""`fogsf fleet add-many`'s manifest: a CSV of units, one a row.

Columns: `unit` (serial number), `train` (training logs separated by ';'), `test` and `out`
(optional: a test log, a model folder to keep). Relative paths are read from the manifest's
folder."""

from __future__ import annotations

import codecs
import csv
import io
from dataclasses import dataclass
from pathlib import Path

from fogsf.errors import UserError
from fogsf.fleet.names import check_unit_name, shown

COLUMNS = ("unit", "train", "test", "out")


@dataclass
class ManifestRow:
    unit: str
    train: list[str]
    test: str | None = None
    out: str | None = None


def _resolve(folder: Path, text: str) -> str:
    p = Path(text)
    return str(p if p.is_absolute() else folder / p)


def _text(p: Path) -> str:
    """The manifest's text: UTF-8 (a BOM allowed) or UTF-16 with its BOM, as spreadsheets
    save CSV; anything else refused in one line (a guessed encoding would misname units)."""
    data = p.read_bytes()
    try:
        if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
            return data.decode("utf-16")
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data[:e.start].count(b"\n") + 1
        raise UserError(f"{p}: line {line}: not UTF-8 text (byte 0x{data[e.start]:02x}): "
                        "save the manifest as UTF-8 CSV") from None


def read_manifest(path: str | Path) -> list[ManifestRow]:
    """The manifest's rows; a missing column, an empty unit or train cell, a unit named
    twice or a log that does not exist is refused with its line."""
    p = Path(path)
    if not p.is_file():
        raise UserError(f"manifest {p} does not exist")
    folder = p.parent
    try:  # a malformed CSV (a field past csv's limit, a stray quote): its line
        with io.StringIO(_text(p), newline="") as f:
            reader = csv.DictReader(f)
            head = [h.strip() for h in (reader.fieldnames or [])]
            missing = [c for c in ("unit", "train") if c not in head]
            if missing:
                raise UserError(f"{p}: line 1: the manifest needs the columns unit and train "
                                f"(missing {', '.join(missing)}; optional: test, out)")
            unknown = [h for h in head if h not in COLUMNS]
            if unknown:
                raise UserError(f"{p}: line 1: unknown column(s) {', '.join(unknown)} "
                                f"(columns: {', '.join(COLUMNS)})")
            rows: list[ManifestRow] = []
            seen: dict[str, int] = {}
            for line, raw in enumerate(reader, start=2):
                cells = {(k or "").strip(): (v or "").strip() for k, v in raw.items()
                         if k is not None}
                if not any(cells.values()):
                    continue  # a blank line
                unit = cells.get("unit", "")
                if not unit:
                    raise UserError(f"{p}: line {line}: empty unit")
                try:
                    check_unit_name(unit)  # every unit refused before any is trained
                except UserError as e:
                    raise UserError(f"{p}: line {line}: {e}") from None
                if unit in seen:
                    raise UserError(f"{p}: line {line}: unit {shown(unit)} again (first on line "
                                    f"{seen[unit]})")
                seen[unit] = line
                train = [_resolve(folder, t.strip()) for t in cells.get("train", "").split(";")
                         if t.strip()]
                if not train:
                    raise UserError(f"{p}: line {line}: unit {shown(unit)} has no training log")
                test = _resolve(folder, cells["test"]) if cells.get("test") else None
                for log in [*train, *([test] if test else [])]:
                    if not Path(log).is_file():
                        raise UserError(f"{p}: line {line}: log {log} does not exist")
                out = _resolve(folder, cells["out"]) if cells.get("out") else None
                rows.append(ManifestRow(unit, train, test, out))
    except csv.Error as e:
        raise UserError(f"{p}: line {reader.line_num}: not a CSV manifest ({e})") from None
    if not rows:
        raise UserError(f"{p}: the manifest names no unit")
    return rows
