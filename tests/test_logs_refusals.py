"""Logs that cannot be right are refused in one line, exit 2 (docs/logs.md, "Units" and "What
the reader refuses"): a gyro or table in another unit at any latitude and table rate, an SF
ratio outside the plausible band with its likely cause named, an inverted axis, time stamps
rounded coarser than the rows; and logs that are right are not."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.chamber_log import earth_rate_vertical_dps
from fogsf.logs.measure.sf_reference import same_units
from fogsf.logs.measure.units import SF_BAND

RAD = math.pi / 180.0


def write(path: Path, rate_dps: float = 10.0, gyro_factor: float = 1.0,
          table_factor: float = 1.0, latitude_deg: float = 34.26, earth_column: bool = True,
          stamp: str = "%.10g", seconds: float = 300.0, reversals: bool = False,
          seed: int = 0) -> Path:
    """A 10 Hz log over 15 .. 25 C: the gyro (SF 1 + 50 ppm/C, its earth rate, noise) read
    as `gyro_factor` x deg/s, the table as `table_factor` x deg/s; `stamp` formats time_s."""
    rng = np.random.default_rng(seed)
    n = int(seconds * 10) + 1
    t = np.arange(n) / 10.0
    temp = 15.0 + 10.0 * t / t[-1]
    table = np.full(n, rate_dps)
    if reversals:
        table = np.where((np.arange(n) // 300) % 2 == 0, rate_dps, -rate_dps)
    earth = earth_rate_vertical_dps(latitude_deg)
    gyro = (table * (1.0 + 50e-6 * (temp - 20.0)) + earth + rng.normal(0, 1e-3, n)) * gyro_factor
    names = ["time_s", "temp_c", "table_rate_dps", "gyro_dps"] + (["earth_rate_dps"]
                                                                  if earth_column else [])
    rows = [",".join(names)]
    for i in range(n):
        cells = [stamp % t[i], f"{temp[i]:.4f}", f"{table[i] * table_factor:.10g}",
                 f"{gyro[i]:.10g}"] + ([f"{earth:.10g}"] if earth_column else [])
        rows.append(",".join(cells))
    path.write_text("\n".join(rows) + "\n")
    return path


def refused(capsys, *argv: str) -> str:
    """The one error line of a command that must exit 2."""
    capsys.readouterr()
    assert main(list(argv)) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ": error: " in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def accepted(capsys, *argv: str) -> str:
    capsys.readouterr()
    rc = main(list(argv))
    out = capsys.readouterr()
    assert rc == 0, out.err
    return out.out


@pytest.mark.parametrize("latitude", [0.0, 34.26, 60.0, -45.0, 89.0])
@pytest.mark.parametrize("rate", [1.0, 10.0, 100.0])
def test_rad_s_gyro_refused_at_any_latitude_and_rate(tmp_path: Path, capsys, latitude: float,
                                                    rate: float) -> None:
    """The earth rate in deg/s taken out of a rad/s gyro moved its ratio off pi/180 by up to
    1.35 % at 10 deg/s and 34 deg; the check takes it out in the gyro's unit too."""
    p = write(tmp_path / "rad.csv", rate, gyro_factor=RAD, latitude_deg=latitude,
              earth_column=False)
    err = refused(capsys, "inspect", str(p), "--latitude-deg", str(latitude), "--window-s", "20")
    assert "units" in err and "gyro_dps is in rad/s" in err, err
    assert "57.29577951308232" in err, err


def test_rad_s_gyro_refused_by_train(tmp_path: Path, capsys) -> None:
    p = write(tmp_path / "rad.csv", 10.0, gyro_factor=RAD, earth_column=False)
    err = refused(capsys, "train", "--train", str(p), "--latitude-deg", "34.26", "--out",
                  str(tmp_path / "m.json"))
    assert "gyro_dps is in rad/s" in err, err


@pytest.mark.parametrize(("gyro", "table", "says"), [
    (1.0, 1.0 / 6.0, "rpm"),
    (RAD * 1000.0, 1.0, "mrad/s"),
    (1000.0, 1.0, "mdeg/s"),
    (1.0, RAD, "table_rate_dps is in rad/s"),
    (3600.0, 1.0, "deg/h"),
])
def test_units_named(tmp_path: Path, capsys, gyro: float, table: float, says: str) -> None:
    p = write(tmp_path / "u.csv", gyro_factor=gyro, table_factor=table)
    err = refused(capsys, "inspect", str(p), "--window-s", "20")
    assert "units" in err and says in err, err


def test_table_in_rpm_refused_and_its_fix_reads(tmp_path: Path, capsys) -> None:
    p = write(tmp_path / "rpm.csv", table_factor=1.0 / 6.0)
    err = refused(capsys, "inspect", str(p), "--window-s", "20")
    assert "rpm" in err and "* 6" in err, err
    accepted(capsys, "inspect", str(p), "--window-s", "20", "--columns",
             "table_rate_dps=table_rate_dps * 6")


def test_inverted_axis_named_with_its_fix(tmp_path: Path, capsys) -> None:
    p = write(tmp_path / "inv.csv", gyro_factor=-1.0, reversals=True)
    err = refused(capsys, "inspect", str(p), "--window-s", "20")
    assert "inverted" in err and 'table_rate_dps = "-table_rate_dps"' in err, err
    (tmp_path / "fogsf-columns.toml").write_text('table_rate_dps = "-table_rate_dps"\n')
    out = accepted(capsys, "inspect", str(p), "--window-s", "20")
    assert "reference SF ratio 1.0000" in out or "reference SF ratio 0.9999" in out, out


def test_a_ratio_of_no_known_unit_refused(tmp_path: Path, capsys) -> None:
    p = write(tmp_path / "x.csv", gyro_factor=2.5)
    err = refused(capsys, "inspect", str(p), "--window-s", "20")
    assert "another unit or scaling" in err and "2.5" in err, err


@pytest.mark.parametrize("factor", [SF_BAND[0] + 0.01, 0.97, 1.0, 1.05, SF_BAND[1] - 0.01])
def test_ratios_in_the_band_read(tmp_path: Path, capsys, factor: float) -> None:
    """A nominal SF a few percent off is a gyro, not a unit."""
    p = write(tmp_path / "ok.csv", gyro_factor=factor)
    accepted(capsys, "inspect", str(p), "--window-s", "20")


def test_same_units_takes_negative_ratios_by_size() -> None:
    def w(r: float) -> SimpleNamespace:
        return SimpleNamespace(sf_ratio=np.array([r]))

    logs = [SimpleNamespace(path="a.csv"), SimpleNamespace(path="b.csv")]
    same_units(logs, [w(-1.00029), w(-0.999886)])  # 0.04 %: one gyro
    same_units(logs, [w(1.00029), w(0.999886)])
    with pytest.raises(UserError, match="differ by more than 1 %"):
        same_units(logs, [w(-1.02), w(-1.0)])
    with pytest.raises(UserError, match="differ in sign.*inverted"):
        same_units(logs, [w(-1.0), w(1.0)])


def test_whole_second_stamps_refused_naming_the_rate(tmp_path: Path, capsys) -> None:
    """A 10 Hz logger printing whole seconds: 9 of 10 steps are 0."""
    p = write(tmp_path / "round.csv", stamp="%.0f")
    err = refused(capsys, "inspect", str(p), "--window-s", "20")
    assert "repeated time stamps" in err and "--sample-rate-hz 10" in err, err
    out = accepted(capsys, "inspect", str(p), "--window-s", "20", "--sample-rate-hz", "10")
    assert "at 10 Hz" in out
    # a rate the rows do not fit drifts off the stamps: refused, naming the row count's
    err = refused(capsys, "inspect", str(p), "--window-s", "20", "--sample-rate-hz", "9")
    assert "repeated time stamps" in err and "10 Hz" in err, err


def test_time_that_never_advances_refused(tmp_path: Path, capsys) -> None:
    p = write(tmp_path / "flat.csv", seconds=30.0)
    lines = p.read_text().splitlines()
    p.write_text("\n".join([lines[0], *("5," + ln.split(",", 1)[1] for ln in lines[1:])]))
    err = refused(capsys, "inspect", str(p))
    assert "does not advance" in err, err
