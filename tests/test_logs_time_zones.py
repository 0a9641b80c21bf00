"""A joined logger on local time (docs/logs.md, "Several loggers, one run"): its stamps put on
UTC by `tz` (a zone, summer time included, or an offset); one whole hours off the log's clock
refused as a time zone read as UTC, unless --allow-clock-offset."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.mapping.time_zone import local_to_utc, parse_tz, whole_hours_off

T0 = datetime(2026, 1, 15, 8, 0, 0, tzinfo=UTC)  # winter: Berlin is UTC+1


def gyro_log(folder: Path, t0: datetime = T0) -> Path:
    """The gyro's log on UTC epoch seconds from `t0`, 10 Hz, 300 s, +/-10 deg/s."""
    folder.mkdir(parents=True, exist_ok=True)
    n = 3000
    t = t0.timestamp() + np.arange(n) / 10.0
    table = np.where((np.arange(n) // 300) % 2 == 0, 10.0, -10.0)
    rows = ["time_s,table_rate_dps,gyro,earth_rate_dps"]
    rows += [f"{t[i]:.1f},{table[i]:g},{table[i] * 1.0001 + 0.00234:.8f},0.00234"
             for i in range(n)]
    (folder / "gyro.csv").write_text("\n".join(rows) + "\n")
    return folder / "gyro.csv"


def _rig(folder: Path, zone: str = "Europe/Berlin", t0: datetime = T0) -> Path:
    """`gyro_log` and a chamber logger's board thermometer at 1 Hz on local wall time (naive
    ISO text)."""
    gyro_log(folder, t0)
    tz = ZoneInfo(zone)
    lines = ["wall,board_T"]
    for k in range(-5, 306):
        wall = (t0 + timedelta(seconds=k)).astimezone(tz).replace(tzinfo=None)
        lines.append(f"{wall.isoformat()},{15.0 + 10.0 * k / 300:.3f}")
    (folder / "gyro.thermo.csv").write_text("\n".join(lines) + "\n")
    return folder / "gyro.csv"


def _map(folder: Path, extra: str = "") -> str:
    m = folder / "map.toml"
    m.write_text('gyro_dps = "gyro"\n\n[join.thermo]\nfile = "{stem}.thermo.csv"\ntime_s = "wall"\n'
                 f'temp_c = "board_T"\n{extra}')
    return str(m)


def _run(capsys, *argv: str) -> tuple[int, str]:
    capsys.readouterr()
    rc = main(list(argv))
    return rc, capsys.readouterr().err


def test_local_time_read_as_utc_refused_naming_the_zone(tmp_path: Path, capsys) -> None:
    log = _rig(tmp_path)
    rc, err = _run(capsys, "inspect", str(log), "--columns", _map(tmp_path), "--window-s", "20")
    assert rc == 2 and "Traceback" not in err, err
    line = next(ln for ln in err.splitlines() if ": error: " in ln)
    assert "time zone" in line and "+1 h" in line and 'tz = "Europe/Berlin"' in line, line
    assert "--allow-clock-offset" in line
    rc, err = _run(capsys, "inspect", str(log), "--columns", _map(tmp_path), "--window-s", "20",
                   "--allow-clock-offset")
    assert rc == 2 and "covers none" in err and "time zone" not in err, err


@pytest.mark.parametrize("tz", ["Europe/Berlin", "+01:00", "UTC+1"])
def test_tz_puts_the_logger_on_utc(tmp_path: Path, capsys, tz: str) -> None:
    log = _rig(tmp_path)
    rc, err = _run(capsys, "inspect", str(log), "--columns", _map(tmp_path, f'tz = "{tz}"\n'),
                   "--window-s", "20")
    assert rc == 0, err
    assert "300 of" not in err and "3000 of 3000 rows covered" in err, err


def test_summer_time_in_a_zone(tmp_path: Path, capsys) -> None:
    log = _rig(tmp_path, t0=datetime(2026, 7, 15, 8, 0, 0, tzinfo=UTC))  # UTC+2
    rc, err = _run(capsys, "inspect", str(log), "--columns", _map(tmp_path), "--window-s", "20")
    assert rc == 2 and "+2 h" in err, err
    rc, err = _run(capsys, "inspect", str(log), "--columns",
                   _map(tmp_path, 'tz = "Europe/Berlin"\n'), "--window-s", "20")
    assert rc == 0, err


def test_local_to_utc_across_the_spring_change() -> None:
    """Berlin: 2026-03-29 02:00 local becomes 03:00 (01:00 UTC)."""
    tz = parse_tz("Europe/Berlin", "test")
    wall = np.array([datetime(2026, 3, 29, h, m, tzinfo=UTC).timestamp()
                     for h, m in ((1, 30), (1, 59), (3, 0), (3, 30))])
    utc = local_to_utc(wall, tz)
    assert list(wall - utc) == [3600.0, 3600.0, 7200.0, 7200.0]


def test_bad_zones_refused() -> None:
    for bad in ("Mars/Olympus", "+25:00", "", 3):
        with pytest.raises(UserError, match="tz ="):
            parse_tz(bad, "[join.x]")


def test_whole_hours_only_at_both_ends() -> None:
    assert whole_hours_off(3600.0, 3600.0, 60.0) == 1
    assert whole_hours_off(-7190.0, -7210.0, 60.0) == -2
    assert whole_hours_off(3600.0, 10.0, 60.0) is None  # started late, not a zone
    assert whole_hours_off(12.0, 5.0, 60.0) is None
