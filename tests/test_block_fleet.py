"""`fogsf fleet export`: one calibration block per unit, read back to each unit's model, and
a manifest (serial, model id, block, bytes, SHA-256); a unit without its model is refused."""

from __future__ import annotations

import csv
import hashlib
from dataclasses import replace
from pathlib import Path

import pytest
from fleet_units import fake_record

from fogsf.cli.main import main
from fogsf.export.block import block_bytes, read_block
from fogsf.fleet.store import open_store
from fogsf.models import samples

SERIALS = ("SN001", "SN002", "line 3/SN 7")


def _fleet(tmp_path: Path, keep: bool = True) -> tuple[Path, dict[str, str]]:
    fleet = tmp_path / "line.fleet"
    ids = {}
    with open_store(str(fleet), "create") as store:
        for i, sn in enumerate(SERIALS):
            model = samples.random_model(2, 4, 1, 8, 10, seed=40 + i, poly_head=bool(i % 2))
            folder = model.save(tmp_path / "models" / f"u{i}")
            ids[sn] = model.model_id
            store.add(replace(fake_record(sn, seed=i), model_id=model.model_id,
                              model_dir=str(folder) if keep or i else ""))
    return fleet, ids


def test_fleet_export_writes_a_block_per_unit_and_the_manifest(tmp_path: Path, capsys) -> None:
    fleet, ids = _fleet(tmp_path)
    out = tmp_path / "blocks"
    assert main(["fleet", "export", str(fleet), "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "manifest.csv").open()))
    assert [r["serial"] for r in rows] == sorted(SERIALS)
    for r in rows:
        data = (out / r["block"]).read_bytes()
        assert r["model_id"] == ids[r["serial"]] == read_block(data).model_id
        assert r["sha256"] == hashlib.sha256(data).hexdigest()
        assert int(r["bytes"]) == len(data)
    names = {r["serial"]: r["block"] for r in rows}
    assert names["SN001"] == "SN001.bin"
    assert names["line 3/SN 7"].startswith("line_3_SN_7-") and "/" not in names["line 3/SN 7"]
    said = capsys.readouterr().out.splitlines()
    assert said[-1] == f"wrote 3 blocks and {out / 'manifest.csv'}"
    # the same fleet, the same bytes
    again = tmp_path / "again"
    assert main(["fleet", "export", str(fleet), "--out", str(again)]) == 0
    assert (again / "manifest.csv").read_bytes() == (out / "manifest.csv").read_bytes()


def test_a_unit_without_its_model_folder_stops_the_export(tmp_path: Path, capsys) -> None:
    fleet, _ = _fleet(tmp_path, keep=False)
    out = tmp_path / "blocks"
    assert main(["fleet", "export", str(fleet), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'SN001': the fleet kept no model folder" in err[0]
    assert not out.exists()  # nothing written before every unit was checked


def test_a_changed_model_folder_is_refused(tmp_path: Path, capsys) -> None:
    fleet, _ = _fleet(tmp_path)
    samples.random_model(2, 4, 1, 8, 10, seed=99).save(tmp_path / "models" / "u1")
    assert main(["fleet", "export", str(fleet), "--out", str(tmp_path / "b")]) == 2
    assert "the folder changed since the unit was added" in capsys.readouterr().err


@pytest.mark.parametrize("serial", ["SN001", "a.b-c_d", "x/y", "..", "ü", " a", "a" * 64])
def test_block_names_are_plain_files(serial: str) -> None:
    from fogsf.cli.fleet_export import block_name
    name = block_name(serial)
    assert "/" not in name and not name.startswith(".") and name.endswith(".bin")
    assert block_name(serial) == name


def test_block_bytes_of_a_unit_match_the_single_export(tmp_path: Path) -> None:
    fleet, _ = _fleet(tmp_path)
    out = tmp_path / "blocks"
    assert main(["fleet", "export", str(fleet), "--out", str(out)]) == 0
    model = samples.random_model(2, 4, 1, 8, 10, seed=40)
    assert (out / "SN001.bin").read_bytes() == block_bytes(model)
