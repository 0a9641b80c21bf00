"""Raw logger output (docs/logs.md, "Raw logger output"): text columns, ISO-8601 time,
unwrap(), exact duplicate rows, units refused (rad/s vs deg/s, Kelvin, Fahrenheit), and
several loggers joined onto the gyro's clock, each written the way loggers write them
(sim/rigs/raw_loggers.py `write_loggers`, sim/rigs/rig_logs.py `write_plain`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.chamber_log import LogError
from fogsf.logs.logio import read_log
from fogsf.logs.mapping.expressions import parse_expression
from fogsf.logs.measure.sf_reference import reference_sf_of_logs
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.stream_read import in_memory, read_log_on_disk
from fogsf.sim.rigs import chambers, raw_loggers, rig_logs
from fogsf.sim.rigs import protocols as rigs

SEED = 20260304


def short_run(gyro_seed: int, seed: int, rate_hz: float = 10.0, lo: float = 5.0,
              hi: float = 35.0) -> rigs.RigRun:
    """+/-100 deg/s reversals, 60 s plateaus, over a loop lo -> hi -> lo at 3 C/min."""
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(lo, hi, 3.0, 3.0, soak_s=120.0),
                               rate_hz=rate_hz)
    return rigs.run_rig(p, gyro_seed, seed)


@pytest.fixture(scope="module")
def run() -> rigs.RigRun:
    return short_run(20001, 3)


def _refused(capsys, *argv: str) -> str:
    capsys.readouterr()
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    errors = [ln for ln in err.splitlines() if ": error: " in ln]
    assert len(errors) == 1 and "Traceback" not in err, err  # one line (after read notes)
    return errors[0]


# --- text columns, any column name ----------------------------------------------------------

def _with_columns(src: Path, dst: Path, extra: dict[str, list[str]], rename: dict[str, str]
                  ) -> Path:
    lines = src.read_text().splitlines()
    head = [rename.get(h, h) for h in lines[0].split(",")]
    out = [",".join(head + list(extra))]
    for i, line in enumerate(lines[1:]):
        out.append(",".join([line, *(v[i % len(v)] for v in extra.values())]))
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_text("\n".join(out) + "\n")
    return dst


def test_text_columns_the_map_does_not_read_are_left_out(run, tmp_path: Path, capsys) -> None:
    plain = rig_logs.write_plain(tmp_path / "a" / "plain.csv", run, gyro_unit="deg/s").path
    ros = _with_columns(plain, tmp_path / "b" / "ros.csv",
                        {"header.frame_id": ["base_link"], "note": ["ok", "a b", "x;y"]},
                        {"gyro_dps": "gyrox deg/s"})
    cols = (("gyro_dps", "gyrox deg/s"),)
    a, b = read_log(plain), read_log(ros, Dialect(columns=cols))
    assert np.array_equal(a.gyro_dps, b.gyro_dps) and np.array_equal(a.time_s, b.time_s)
    assert "header.frame_id" not in b.extra and "note" not in b.extra
    assert any("text columns left out: header.frame_id, note" in n for n in b.read_notes)
    on_disk = in_memory(read_log_on_disk(ros, Dialect(columns=cols)))
    assert np.array_equal(on_disk.gyro_dps, b.gyro_dps)
    # a name with '/' (the spill file's name does not come from it)
    slash = _with_columns(plain, tmp_path / "c" / "s.csv", {"frame": ["imu"]},
                          {"gyro_dps": "gyrox rad/s"})
    capsys.readouterr()
    assert main(["inspect", "--json", str(slash), "--columns", "gyro_dps=gyrox rad/s"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == len(a)
    # a text column the map reads is refused, naming it
    err = _refused(capsys, "inspect", str(ros), "--columns", "gyro_dps=gyrox deg/s,chamber_c=note")
    assert "text column" in err and "'note'" in err and "chamber_c" in err


def test_iso_time_reads_as_epoch_seconds(run, tmp_path: Path) -> None:
    plain = rig_logs.write_plain(tmp_path / "a" / "plain.csv", run, gyro_unit="deg/s").path
    a = read_log(plain)
    lines = plain.read_text().splitlines()
    stamps = raw_loggers.iso_stamps(a.time_s)
    iso = tmp_path / "b" / "iso.csv"
    iso.parent.mkdir()
    iso.write_text("\n".join(["wall," + lines[0].split(",", 1)[1]]
                             + [f"{s},{ln.split(',', 1)[1]}" for s, ln in
                                zip(stamps, lines[1:], strict=True)]) + "\n")
    d = Dialect(columns=(("time_s", "wall"),))
    for b in (read_log(iso, d), in_memory(read_log_on_disk(iso, d))):
        # the stamps hold milliseconds: the times read within 0.5 ms, and exactly as written
        assert np.abs(b.time_s - a.time_s).max() <= 0.5e-3
        want = np.round(a.time_s * 1e3) / 1e3
        assert np.abs(b.time_s - want).max() < 1e-6
        assert any("ISO-8601" in n for n in b.read_notes)


def test_unwrap_carries_across_blocks() -> None:
    rng = np.random.default_rng(SEED)
    period = 2.0**32
    start = period - rng.uniform(1e6, 2e7)  # 1 .. 20 s before the wrap (the run: 25 s)
    true_us = start + np.cumsum(rng.uniform(4000, 6000, 5000))
    counter = np.mod(true_us, period)
    assert (np.diff(counter) < 0).any(), f"seed {SEED}: no wrap drawn"
    e = parse_expression("unwrap(t_us, 2**32) * 1e-6")
    whole = e.evaluate({"t_us": counter}, counter.size)
    assert np.allclose(whole, true_us * 1e-6, rtol=0, atol=1e-9)
    e.carry.clear()
    cut = int(rng.integers(1, counter.size - 1))
    parts = [e.evaluate({"t_us": c}, c.size) for c in (counter[:cut], counter[cut:])]
    assert np.array_equal(np.concatenate(parts), whole)
    with pytest.raises(Exception, match="period is a number"):
        parse_expression("unwrap(t_us, t_us)")


def test_loggers_joined_on_the_gyros_clock(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(SEED + 1)
    gyro, seed = int(rng.integers(20000, 30000)), int(rng.integers(0, 1000))
    dropout = float(rng.uniform(20.0, 40.0))
    r = short_run(gyro, seed, rate_hz=20.0)
    rl = raw_loggers.write_loggers(tmp_path / "imu.csv", r, seed=seed, dropout_s=dropout)
    truth = rl.truth[""]
    lg = read_log(rl.path)
    msg = f"gyro {gyro} seed {seed} dropout {dropout:.1f}"
    assert len(lg) == r.stamp_s.size, msg  # the written duplicates dropped
    assert np.abs(lg.time_s - truth.time_s).max() < 2e-6, msg  # the counter's wrap unwrapped
    assert np.allclose(lg.gyro_dps, r.axes[""].gyro_dps, rtol=1e-11), msg
    assert np.array_equal(lg.table_rate_dps, r.command_dps), msg
    # the thermometer at 1 Hz, interpolated: within one second's change and its step
    ok = lg.valid
    assert np.abs(lg.temp_c[ok] - r.axes[""].temp_c[ok]).max() < 0.2, msg
    # the dropout is not bridged: rows over 5 s from a thermometer sample measure nothing
    th = read_log_times(rl.path.with_name("imu.thermo.csv"))
    k = np.searchsorted(th, lg.time_s)
    far = (np.minimum(np.abs(lg.time_s - th[np.clip(k - 1, 0, th.size - 1)]),
                      np.abs(th[np.clip(k, 0, th.size - 1)] - lg.time_s)) > 5.0)
    assert far.any() and not ok[far].any(), msg
    assert (~ok).sum() >= far.sum(), msg
    notes = " | ".join(lg.read_notes)
    assert "exact duplicate rows dropped" in notes and "join thermo" in notes, msg
    assert "1 gap > 5 s" in notes and "text columns left out: header.frame_id" in notes, msg
    disk = in_memory(read_log_on_disk(rl.path))
    for name in ("time_s", "gyro_dps", "temp_c", "table_rate_dps"):
        assert np.array_equal(getattr(disk, name), getattr(lg, name)), (msg, name)
    assert np.array_equal(disk.valid, lg.valid), msg
    capsys.readouterr()
    assert main(["inspect", str(rl.path)]) == 0
    err = capsys.readouterr().err
    assert "join thermo" in err and "join table" in err


def read_log_times(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()[1:]
    stamps = np.array([ln.split(",")[0] for ln in lines], dtype="datetime64[ms]")
    return stamps.astype(np.int64) * 1e-3


def test_a_missing_join_file_is_refused(tmp_path: Path, capsys) -> None:
    r = short_run(20003, 1)
    rl = raw_loggers.write_loggers(tmp_path / "imu.csv", r, seed=1)
    rl.path.with_name("imu.table.csv").unlink()
    err = _refused(capsys, "inspect", str(rl.path))
    assert "[join.table]" in err and "imu.table.csv" in err


def test_exact_duplicates_dropped_others_refused(run, tmp_path: Path) -> None:
    plain = rig_logs.write_plain(tmp_path / "plain.csv", run, gyro_unit="deg/s").path
    lines = plain.read_text().splitlines()
    rng = np.random.default_rng(SEED + 2)
    at = sorted(rng.choice(np.arange(2, len(lines)), size=4, replace=False).tolist())
    dup = list(lines)
    for i in reversed(at):
        dup.insert(i, lines[i])
    p = tmp_path / "dup" / "plain.csv"
    p.parent.mkdir()
    p.write_text("\n".join(dup) + "\n")
    a, b = read_log(plain), read_log(p)
    assert np.array_equal(a.gyro_dps, b.gyro_dps) and len(b) == len(a)
    assert any("4 exact duplicate rows dropped" in n for n in b.read_notes), at
    cells = lines[at[0]].split(",")
    cells[3] = "1.5"  # the same time, another gyro value: not a duplicate
    bad = list(lines)
    bad.insert(at[0] + 1, ",".join(cells))
    p.write_text("\n".join(bad) + "\n")
    with pytest.raises(LogError, match="time not increasing"):
        read_log(p)


# --- units -----------------------------------------------------------------------------------

def test_deg_s_under_a_rad_s_map_refused(run, tmp_path: Path, capsys) -> None:
    rl = rig_logs.write_plain(tmp_path / "d" / "plain.csv", run, gyro_unit="deg/s")
    rig_logs.write_mapping(rl.path.parent, {"gyro_dps": "gyro_dps * 57.29577951308232"})
    err = _refused(capsys, "inspect", str(rl.path))
    assert "rad/s" in err and "deg/s" in err and "180/pi" in err
    # a table command in rad/s read as deg/s
    rl2 = rig_logs.write_plain(tmp_path / "t" / "plain.csv", run, gyro_unit="deg/s")
    err = _refused(capsys, "inspect", str(rl2.path), "--columns",
                   "table_rate_dps=table_rate_dps * 0.017453292519943295")
    assert "rad/s" in err and "180/pi" in err


def test_units_switching_mid_log_refused_at_its_line(run, tmp_path: Path, capsys) -> None:
    rl = rig_logs.write_plain(tmp_path / "plain.csv", run, gyro_unit="deg/s")
    lines = rl.path.read_text().splitlines()
    rng = np.random.default_rng(SEED + 3)
    cut = int(rng.integers(len(lines) * 6 // 10, len(lines) * 8 // 10))
    out = [lines[0], *lines[1:cut]]
    for ln in lines[cut:]:
        c = ln.split(",")
        c[3] = repr(float(c[3]) / 57.29577951308232)
        out.append(",".join(c))
    rl.path.write_text("\n".join(out) + "\n")
    err = _refused(capsys, "inspect", str(rl.path))
    assert "units switch" in err, err
    line = int(err.split(": line ")[1].split(":")[0])
    assert line == cut + 1, (cut, err)  # the first line in the other unit


def test_training_logs_in_two_units_refused(run, tmp_path: Path) -> None:
    a = read_log(rig_logs.write_plain(tmp_path / "a" / "plain.csv", run, gyro_unit="deg/s").path)
    b = read_log(rig_logs.write_plain(tmp_path / "b" / "plain.csv", run, gyro_unit="deg/s").path)
    b.gyro_dps = b.gyro_dps * 1.02  # 2 %: not one gyro
    with pytest.raises(UserError, match="differ by more than 1 %"):
        reference_sf_of_logs([a, b])
    b.gyro_dps = a.gyro_dps * 1.0005
    reference_sf_of_logs([a, b])  # 500 ppm: one gyro's spread


def test_kelvin_named(run, tmp_path: Path, capsys) -> None:
    rl = rig_logs.write_plain(tmp_path / "k" / "plain.csv", run, gyro_unit="deg/s")
    err = _refused(capsys, "inspect", str(rl.path), "--columns", "temp_c=temp_c + 273.15")
    assert "Kelvin" in err and "273.15" in err


def test_a_heated_rig_takes_the_nearest_temperature(tmp_path: Path, capsys) -> None:
    r = short_run(20002, 5, lo=38.0, hi=62.0)
    rl = rig_logs.write_plain(tmp_path / "plain.csv", r, gyro_unit="deg/s")
    # in Fahrenheit (100 .. 144 F) it is out of range on most rows: named
    err = _refused(capsys, "inspect", str(rl.path), "--columns", "temp_c=temp_c * 1.8 + 32")
    assert "Fahrenheit" in err
    capsys.readouterr()
    assert main(["inspect", "--json", str(rl.path)]) == 0
    out = capsys.readouterr()
    s = json.loads(out.out)
    lo = s["temp_range_c"][0]
    assert lo > 25.0 and lo <= s["ref_temp_c"] <= lo + 1.0  # its windows' nearest to 20 C
    assert "nearest temperature" in out.err


def test_a_ros2_bag_exported_to_csv(tmp_path: Path) -> None:
    rng = np.random.default_rng(SEED + 4)
    gyro, seed = int(rng.integers(20000, 30000)), int(rng.integers(0, 1000))
    r = short_run(gyro, seed)
    rl = raw_loggers.write_ros2_export(tmp_path / "imu.csv", r)
    lg = read_log(rl.path)
    msg = f"gyro {gyro} seed {seed}"
    assert np.abs(lg.time_s - rl.truth[""].time_s).max() < 1e-6, msg
    assert np.allclose(lg.gyro_dps, r.axes[""].gyro_dps, rtol=1e-11), msg
    assert np.array_equal(lg.table_rate_dps, r.command_dps), msg
    assert np.abs(lg.temp_c - r.axes[""].temp_c).max() < 0.2, msg
    assert "header.frame_id" in " ".join(lg.read_notes), msg


def test_clocks_that_disagree_are_said_loudly(tmp_path: Path) -> None:
    r = short_run(20004, 2)
    rl = raw_loggers.write_loggers(tmp_path / "imu.csv", r, seed=2)
    text = rl.mapping_path.read_text()
    off = text.split("* 1e-6 + ")[1].split('"')[0]
    rl.mapping_path.write_text(text.replace(off, repr(float(off) + 600.0)))  # 10 min off
    lg = read_log(rl.path)
    assert "CHECK THE CLOCKS" not in " | ".join(lg.read_notes)
    warn = " | ".join(lg.read_warnings)  # a short line of its own, naming the likely cause
    assert "CHECK THE CLOCKS" in warn and "wrong offset in time_s" in warn, warn
    assert all(len(w) < 200 for w in lg.read_warnings), warn
    wrong = float(off) + 2.0**32 * 1e-6  # the offset of a counter that wrapped once more
    rl.mapping_path.write_text(text.replace(off, repr(wrong)))
    with pytest.raises(UserError, match="covers none of the log's rows.*check the clocks"):
        read_log(rl.path)
