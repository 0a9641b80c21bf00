"""Logs as rigs and spreadsheets write them: BOM, ; and tab, the rig's column names, several
gyro axes; every refusal names the option that fixes it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from trainer.cli import main
from trainer.errors import UserError
from trainer.logio import Dialect, LogError, read_log

SHORT = ["--scenario", "paper", "--start-c", "15", "--stop-c", "25", "--ramp-rate", "1",
         "--seed", "3"]
RIG = {"time_s": "t", "temp_c": "temperature", "table_rate_dps": "table", "gyro_dps": "omega"}


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dialects") / "plain.csv"
    assert main(["simulate", *SHORT, "--out", str(out)]) == 0
    return out


def _same(a, b) -> None:  # noqa: ANN001 - ChamberLogs
    for k, v in a.columns().items():
        assert np.array_equal(v, b.columns()[k]), k


def _rewrite(src: Path, dst: Path, header: list[str] | None = None, delim: str = ",",
             bom: bool = False) -> Path:
    lines = src.read_text().splitlines()
    if header is not None:
        lines[0] = ",".join(header)
    text = "\n".join(line.replace(",", delim) for line in lines) + "\n"
    dst.write_text(("\ufeff" if bom else "") + text, encoding="utf-8")
    return dst


def test_bom_semicolon_and_tab_read_as_the_plain_log(plain: Path, tmp_path: Path) -> None:
    ref = read_log(plain)
    _same(read_log(_rewrite(plain, tmp_path / "bom.csv", bom=True)), ref)
    semi = _rewrite(plain, tmp_path / "semi.csv", delim=";", bom=True)
    _same(read_log(semi), ref)
    _same(read_log(semi, Dialect(delimiter=";")), ref)
    _same(read_log(_rewrite(plain, tmp_path / "tab.csv", delim="\t")), ref)
    assert main(["inspect", str(semi), "--delimiter", ";"]) == 0


def test_a_decimal_comma_is_refused_with_a_hint(plain: Path, tmp_path: Path) -> None:
    semi = _rewrite(plain, tmp_path / "semi.csv", delim=";")
    lines = semi.read_text().splitlines()
    lines[5] = lines[5].replace(".", ",", 1)
    semi.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match=r"line 6: non-numeric cell.*decimal comma"):
        read_log(semi)


def test_the_rigs_column_names_are_mapped(plain: Path, tmp_path: Path, capsys) -> None:
    header = plain.read_text().splitlines()[0].split(",")
    rig = _rewrite(plain, tmp_path / "rig.csv", [RIG.get(h, h) for h in header])
    with pytest.raises(LogError, match="missing required column.*--columns time_s=NAME"):
        read_log(rig)
    arg = ",".join(f"{k}={v}" for k, v in RIG.items())
    _same(read_log(rig, Dialect(columns=Dialect.parse_columns(arg))), read_log(plain))
    mapping = tmp_path / "columns.json"
    mapping.write_text(json.dumps(RIG))
    assert main(["inspect", str(rig), "--columns", str(mapping), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == len(read_log(plain))
    assert main(["inspect", str(rig), "--columns", "time_s=tt"]) == 2
    assert "--columns names 'tt' for time_s" in capsys.readouterr().err
    with pytest.raises(UserError, match="not a column of the format"):
        Dialect.parse_columns("speed=omega")


def test_one_axis_of_a_three_axis_log(plain: Path, tmp_path: Path, capsys) -> None:
    log = read_log(plain)
    cols = {k: v for k, v in log.columns().items() if k != "gyro_dps"}
    axes = {"gyro_x_dps": log.gyro_dps, "gyro_y_dps": log.gyro_dps * (1 + 300e-6),
            "gyro_z_dps": log.gyro_dps * (1 - 200e-6)}
    names = [*cols, *axes]
    data = np.column_stack([*cols.values(), *axes.values()])
    imu = tmp_path / "imu.csv"
    with open(imu, "w") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.10g")
    with pytest.raises(LogError, match=r"--gyro-column gyro_x_dps \(fogsf train: --axis x\)"):
        read_log(imu)
    y = read_log(imu, Dialect(gyro_column="gyro_y_dps"))
    assert np.allclose(y.gyro_dps, axes["gyro_y_dps"], rtol=1e-9)
    assert "gyro_x_dps" in y.extra  # the other axes are kept, not dropped
    out = tmp_path / "m"
    assert main(["train", "--train", str(imu), "--axis", "z", "--model", "poly",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["train", "--train", str(imu), "--axis", "z", "--gyro-column", "gyro_x_dps",
                 "--model", "poly", "--out", str(out)]) == 2
    assert "--axis or --gyro-column" in capsys.readouterr().err


def test_a_log_that_never_reaches_20_c_names_ref_sf(tmp_path: Path, capsys) -> None:
    warm = tmp_path / "warm.csv"
    assert main(["simulate", "--scenario", "paper", "--start-c", "30", "--stop-c", "40",
                 "--ramp-rate", "1", "--out", str(warm)]) == 0
    assert main(["inspect", str(warm)]) == 2
    assert "--ref-sf" in capsys.readouterr().err
    assert main(["inspect", str(warm), "--ref-sf", "1.0"]) == 0
