"""Chamber-log reader: round trip, speed-independent checks, and every refusal of docs/logs.md."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import parse_log, read_log
from fogsf.logs.writer import write_log

HEADER = "time_s,temp_c,table_rate_dps,gyro_dps"


def good_rows(n: int = 5) -> list[str]:
    return [f"{0.1 * i:.1f},{20.0 + 0.01 * i:.4f},10,10.00{i}" for i in range(n)]


def csv(rows: list[str], header: str = HEADER) -> str:
    return "\n".join([header, *rows]) + "\n"


def refused(text: str) -> LogError:
    with pytest.raises(LogError) as ei:
        parse_log(text, "x.csv")
    return ei.value


def test_round_trip_keeps_every_column(tmp_path: Path) -> None:
    n = 1000
    rng = np.random.default_rng(1)
    log = ChamberLog(
        time_s=np.arange(n) * 0.1,
        temp_c=rng.uniform(-40, 50, n),
        table_rate_dps=np.where(np.arange(n) % 200 < 100, 10.0, -10.0),
        gyro_dps=rng.normal(10, 1, n),
        earth_rate_dps=np.full(n, 0.0023),
        extra={"chamber_c": rng.uniform(-40, 50, n), "my_note": rng.normal(size=n)},
    )
    p = tmp_path / "a.csv"
    write_log(p, log)
    back = read_log(p)
    for name, col in log.columns().items():
        np.testing.assert_allclose(back.columns()[name], col, rtol=1e-9, atol=1e-12)
    assert list(back.extra) == ["chamber_c", "my_note"]
    p2 = tmp_path / "b.csv"
    write_log(p2, back)
    assert p.read_bytes() == p2.read_bytes()


def test_good_file_reads() -> None:
    log = parse_log(csv(good_rows()), "x.csv")
    assert len(log) == 5 and log.earth_rate_dps is None
    assert log.duration_s == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("text", "rule", "line"),
    [
        ("", "empty file", None),
        ("\n\n", "empty file", None),
        (HEADER + "\n", "empty file", 1),
        ("time_s,temp_c,gyro_dps\n0,20,10\n", "missing required column", 1),
        (HEADER + ",temp_c\n0,20,10,10,20\n", "bad header", 1),
        (csv(good_rows()[:2] + ["0.2,20,10"]), "wrong number of cells", 4),
        (csv(good_rows()[:3] + ["0.3,abc,10,10"]), "non-numeric cell", 5),
        (csv(good_rows()[:3] + ["0.3,,10,10"]), "non-numeric cell", 5),
        (csv(good_rows()[:1] + ["0.1,nan,10,10"]), "non-finite cell", 3),
        (csv(good_rows()[:1] + ["0.1,20,inf,10"]), "non-finite cell", 3),
        (csv(good_rows()[:3] + ["0.2,20,10,10"]), "time not increasing", 5),
        (csv(good_rows()[:3] + ["0.1,20,10,10"]), "time not increasing", 5),
        (csv([r + ",0" for r in good_rows()], HEADER + ",valid"), "no row measures", None),
        (csv(good_rows()[:3] + ["0.3,101,10,10"]), "temperature out of range", 5),
        (csv(good_rows()[:3] + ["0.3,-60.5,10,10"]), "temperature out of range", 5),
        (csv([r + ",120" for r in good_rows()], HEADER + ",chamber_c"),
         "temperature out of range", 2),
        (csv([r + ",-70" for r in good_rows()], HEADER + ",temp_coil_c"),
         "temperature out of range", 2),
    ],
)
def test_refusals_name_file_line_and_rule(text: str, rule: str, line: int | None) -> None:
    err = refused(text)
    assert err.rule == rule
    assert err.line == line
    assert str(err).startswith("x.csv")
    assert rule in str(err)


def test_missing_file_and_binary(tmp_path: Path) -> None:
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "nope.csv")
    p = tmp_path / "bin.csv"
    p.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(LogError, match="not UTF-8"):
        read_log(p)


def test_unknown_columns_kept_and_temperature_like_names_checked() -> None:
    text = csv([r + ",500" for r in good_rows()], HEADER + ",pressure_hpa")
    log = parse_log(text, "x.csv")
    assert log.extra["pressure_hpa"][0] == 500


def test_rows_that_measure_nothing_stay_in_the_log(tmp_path: Path) -> None:
    """Zero table rate or valid = 0: kept, not measuring; written back and read the same."""
    rows = [f"{0.1 * i:.1f},20,{0 if i in (1, 2) else 10},10,{0 if i == 4 else 1}"
            for i in range(6)]
    log = parse_log(csv(rows, HEADER + ",valid"), "x.csv")
    assert len(log) == 6
    assert log.measures.tolist() == [True, False, False, True, False, True]
    write_log(tmp_path / "v.csv", log)
    back = read_log(tmp_path / "v.csv")
    assert back.valid is not None and back.measures.tolist() == log.measures.tolist()
    assert "valid" not in back.extra


def test_no_earth_rate_needs_latitude() -> None:
    log = parse_log(csv(good_rows()), "x.csv")
    with pytest.raises(LogError, match="latitude"):
        log.earth()
    assert log.earth(90.0)[0] == pytest.approx(360 / 86164.0905)


def test_cli_refusal_is_one_line_no_traceback(tmp_path: Path) -> None:
    import subprocess
    import sys

    p = tmp_path / "bad.csv"
    p.write_text(csv(good_rows()[:3] + ["0.2,20,10,10"]))
    r = subprocess.run([sys.executable, "-m", "fogsf", "inspect", str(p)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert f"{p}: line 5: time not increasing" in r.stderr


def test_header_only_file_is_one_clean_line(tmp_path: Path) -> None:
    import subprocess
    import sys

    p = tmp_path / "empty.csv"
    p.write_text("time_s,temp_c,table_rate_dps,gyro_dps\n")
    r = subprocess.run([sys.executable, "-W", "default", "-m", "fogsf", "inspect", str(p)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        f"fogsf inspect: error: {p}: line 1: empty file: a header but no data rows"], r.stderr


@pytest.mark.parametrize("name", ["gx[dps]", "gyro_x", "wz", "omega_y"])
def test_a_gyro_like_column_suggests_gyro_column(name: str) -> None:
    text = csv(good_rows()).replace("gyro_dps", name, 1)
    with pytest.raises(LogError, match=re.escape(f"--gyro-column {shlex.quote(name)}")):
        parse_log(text, "x.csv")


@pytest.mark.parametrize("name", ["temp_x", "gyro_temp", "gyro_temp_c", "gx_degc"])
def test_no_gyro_like_column_gets_the_column_map_hint(name: str) -> None:
    text = csv(good_rows()).replace("gyro_dps", name, 1)
    with pytest.raises(LogError, match="--columns") as e:
        parse_log(text, "x.csv")
    assert "--gyro-column" not in str(e.value)


@pytest.mark.parametrize("step_c", [1.0, 0.25, 0.0625])
def test_a_quantised_thermometer_reads_as_written(step_c: float, tmp_path: Path) -> None:
    """A board thermometer in 1 C, 0.25 C or 0.0625 C (a 12-bit sensor's) steps: long runs
    of one reading are a quantised ramp, not a stuck sensor; read as written on both paths."""
    n = 36_000  # 1 h at 10 Hz, a ramp of 1 C/min from -10 C
    t = np.arange(n) * 0.1
    true_c = -10.0 + t / 60.0
    log = ChamberLog(time_s=t, temp_c=np.round(true_c / step_c) * step_c,
                     table_rate_dps=np.full(n, 10.0), gyro_dps=np.full(n, 10.001),
                     earth_rate_dps=np.full(n, 0.0023),
                     extra={"temp_coil_c": np.floor(true_c / step_c) * step_c})
    p = tmp_path / "q.csv"
    write_log(p, log)
    for back in (read_log(p), parse_log(p.read_text(), str(p))):
        assert np.array_equal(back.temp_c, log.temp_c)
        assert np.array_equal(back.extra["temp_coil_c"], log.extra["temp_coil_c"])
        assert back.read_notes == () and back.measures.all()
        held = np.diff(back.temp_c) == 0
        assert held.mean() > 0.97  # nearly every step repeats the reading
        assert set(np.unique(np.diff(back.temp_c))) <= {0.0, step_c}


def test_replay_csv_keeps_an_epoch_time_base(tmp_path: Path) -> None:
    """At 1 kHz on a 1.7e9 s epoch the replay CSV keeps every step (12 digits would not)."""
    from fogsf.cli.replay import write_corrected

    t = 1.7e9 + np.arange(5) * 1e-3
    z = np.zeros(5)
    write_corrected(tmp_path / "c.csv", t, z, z, z.astype(np.float32))
    back = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)[:, 0]
    np.testing.assert_array_equal(back, t)
