"""Joined streams whose clock steps back or disagrees with the log's (docs/logs.md, "Several
loggers, one run" and "Clocks"): a re-synchronised clock told from a reboot by the
temperature across the step; a clock warning on a short line of its own naming its cause."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from test_logs_time_zones import gyro_log

from fogsf.cli.main import main
from fogsf.logs.chamber_log import LogError
from fogsf.logs.logio import read_log
from fogsf.logs.mapping.joins import JoinReport
from fogsf.logs.read.dialect import Dialect

T0 = datetime(2026, 1, 15, 8, 0, 0, tzinfo=UTC)
SLOPE_C_PER_S = 10.0 / 300.0  # the chamber's board temperature: 15 C + 2 C/min


def _thermo(folder: Path, stamp_s: list[float], true_s: list[float]) -> None:
    """A chamber logger at 1 Hz: the board temperature at each true time, stamped
    `stamp_s` (seconds from T0, ISO text)."""
    lines = ["wall,board_T"]
    for s, k in zip(stamp_s, true_s, strict=True):
        wall = (T0 + timedelta(seconds=s)).replace(tzinfo=None)
        lines.append(f"{wall.isoformat()},{15.0 + SLOPE_C_PER_S * k:.4f}")
    (folder / "gyro.thermo.csv").write_text("\n".join(lines) + "\n")


def _map(folder: Path, time_s: str = "wall") -> Dialect:
    m = folder / "map.toml"
    m.write_text('gyro_dps = "gyro"\n\n[join.thermo]\nfile = "{stem}.thermo.csv"\n'
                 f'time_s = "{time_s}"\ntemp_c = "board_T"\n')
    return Dialect(joins=Dialect.mapping_joins(str(m)), columns=Dialect.parse_columns(str(m)))


def test_a_resynchronised_stream_clock_is_joined(tmp_path: Path) -> None:
    """The logger's clock ran 30 s ahead and was set right at 150 s: the temperature runs on
    across the step, so the rows before it are moved onto the clock after it and the joined
    temperature is the true one."""
    log = gyro_log(tmp_path)
    true = [float(k) for k in range(-5, 306)]
    _thermo(tmp_path, [k + (30.0 if k < 150 else 0.0) for k in true], true)
    lg = read_log(str(log), _map(tmp_path))
    truth = 15.0 + SLOPE_C_PER_S * (np.asarray(lg.time_s) - T0.timestamp())
    assert np.abs(lg.temp_c - truth).max() < 1e-3
    note = " | ".join(lg.read_notes)
    assert "[join.thermo] time steps -29.0 s" in note and "re-synchronised" in note, note
    assert "runs on" in note


def test_a_rebooted_stream_clock_is_refused_saying_so(tmp_path: Path, capsys) -> None:
    """A logger counting seconds since boot, down 40 s at 150 s: its clock restarts and the
    temperature jumps: refused in one line naming the reboot."""
    log = gyro_log(tmp_path)
    true = [float(k) for k in range(-5, 150)] + [float(k) for k in range(190, 306)]
    boot = [k + 5.0 if k < 150 else k - 190.0 for k in true]
    (tmp_path / "gyro.thermo.csv").write_text(
        "boot_s,board_T\n" + "".join(f"{b:g},{15.0 + SLOPE_C_PER_S * k:.4f}\n"
                                     for b, k in zip(boot, true, strict=True)))
    m = tmp_path / "map.toml"
    m.write_text('gyro_dps = "gyro"\n\n[join.thermo]\nfile = "{stem}.thermo.csv"\n'
                 f'time_s = "boot_s + {T0.timestamp() - 5.0}"\ntemp_c = "board_T"\n')
    capsys.readouterr()
    assert main(["inspect", str(log), "--columns", str(m), "--window-s", "20"]) == 2
    err = capsys.readouterr().err
    line = next(ln for ln in err.splitlines() if ": error: " in ln)
    assert "Traceback" not in err and "clock restarts" in line, err
    assert "temperature jumps" in line and "rebooted" in line, line


def test_the_clock_warning_is_a_short_line_of_its_own(tmp_path: Path, capsys) -> None:
    """A chamber logger 90 s off the gyro's clock at both ends: the notes say what the join
    did, and a line of its own says the clocks disagree and the likely cause."""
    log = gyro_log(tmp_path)
    true = [float(k) for k in range(-5, 306)]
    _thermo(tmp_path, [k + 90.0 for k in true], true)
    m = tmp_path / "map.toml"
    _map(tmp_path)
    capsys.readouterr()
    assert main(["inspect", str(log), "--columns", str(m), "--window-s", "20"]) == 0
    err = capsys.readouterr().err.splitlines()
    read = next(ln for ln in err if ln.startswith("fogsf: read "))
    warn = [ln for ln in err if ln.startswith("fogsf: warning: ")]
    assert "CHECK THE CLOCKS" not in read and len(warn) == 1, err
    assert "CHECK THE CLOCKS" in warn[0] and "same at both ends" in warn[0], warn
    assert "wrong offset in time_s" in warn[0], warn
    assert len(warn[0].split(f"{log}: ", 1)[1]) < 200, warn


def test_a_warning_whole_hours_off_names_the_time_zone() -> None:
    r = JoinReport("thermo", "x.thermo.csv", 40000, 3000, [], 3600.0, 3600.4, 5.0)
    w = r.warning()
    assert "+1 h at both ends, a time zone" in w and 'tz = "+01:00"' in w, w
    assert JoinReport("t", "x", 100, 100, [], 0.5, -0.2, 5.0).warning() == ""


def test_a_reboot_before_another_step_is_judged_on_its_own_rows(tmp_path: Path) -> None:
    """A chamber logger down 15 s (the temperature jumps 0.5 C) whose clock steps back, and
    down 60 s again 50 rows later: the first step is judged on the rows up to the second,
    so it is refused as a reboot at its own line."""
    log = gyro_log(tmp_path)
    true = ([float(k) for k in range(-5, 150)] + [float(k) for k in range(165, 215)]
            + [float(k) for k in range(275, 400)])
    stamp = [k if k < 150 else k - 60.0 if k < 215 else k - 130.0 for k in true]
    _thermo(tmp_path, stamp, true)
    with pytest.raises(LogError) as e:
        read_log(str(log), _map(tmp_path))
    text = str(e.value)
    assert "line 157" in text and "clock restarts" in text, text
    assert "temperature jumps +0.500 C" in text, text
