"""The column map's expressions (docs/logs.md, "Column map"): a ROS-logged rig (split epoch
time, rad/s, a stepper in steps/s, flags for rows that measure nothing) read to the plain
log's numbers on both reading paths; per-axis names; every refusal in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import log_axes_of, parse_log, read_log
from fogsf.logs.mapping.expressions import (
    EvaluationError,
    ExpressionError,
    parse_expression,
    split_top_level,
)
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.writer import write_log

SHORT = ["--scenario", "paper", "--start-c", "15", "--stop-c", "25", "--ramp-rate", "1",
         "--seed", "3"]
STEPS_PER_REV = 577803.965671
T0 = 1_700_000_000
ROS_HEADER = "sec,nanosec,gyro_raw,gyro_temp,rig_rate,rig_heating,rig_enabled,rig_stalled"


def ros_map(earth: float) -> dict[str, str | float]:
    return {"time_s": "sec + nanosec * 1e-9",
            "table_rate_dps": f"rig_rate * 360 / {STEPS_PER_REV}",
            "gyro_dps": "gyro_raw * 57.29577951308232",
            "temp_c": "gyro_temp",
            "earth_rate_dps": earth,
            "valid": "rig_enabled == 1 and rig_stalled == 0"}


def toml_of(mapping: dict[str, str | float]) -> str:
    return "".join(f"{k} = {json.dumps(v)}\n" for k, v in mapping.items())


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("expr") / "plain.csv"
    assert main(["simulate", *SHORT, "--out", str(out)]) == 0
    return out


def write_ros(log: ChamberLog, path: Path, enabled: np.ndarray | None = None,
              stalled: np.ndarray | None = None, delim: str = ",") -> Path:
    """The log as the ROS rig writes it: epoch time in sec + nanosec, the gyro in rad/s,
    the table as stepper steps/s, flags."""
    n = len(log)
    ns = np.round(log.time_s * 1e9).astype(np.int64) + 123_456_789
    sec, nsec = T0 + ns // 1_000_000_000, ns % 1_000_000_000
    enabled = np.ones(n) if enabled is None else enabled
    stalled = np.zeros(n) if stalled is None else stalled
    rows = [f"{sec[i]},{nsec[i]},{float(np.radians(log.gyro_dps[i]))!r},"
            f"{float(log.temp_c[i])!r},{float(log.table_rate_dps[i]) * STEPS_PER_REV / 360!r},"
            f"1,{enabled[i]:.0f},{stalled[i]:.0f}" for i in range(n)]
    path.write_text("\n".join([ROS_HEADER, *rows]).replace(",", delim) + "\n")
    return path


def _refused(capsys, *argv: str) -> str:
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


# --- the evaluator ----------------------------------------------------------------------

COLS = {"a": np.array([1.0, 2.0, 4.0]), "b": np.array([0.5, 0.0, 2.0]),
        "gx[dps]": np.array([3.0, 4.0, 5.0])}


@pytest.mark.parametrize(("text", "want"), [
    ("a + b * 2", [2.0, 2.0, 8.0]),
    ("-a ** 2", [-1.0, -4.0, -16.0]),
    ("(a - 1) / 2", [0.0, 0.5, 1.5]),
    ("abs(b - 1) + sqrt(a)", [1.5, 1 + 2 ** 0.5, 3.0]),
    ("sin(0 * a) + cos(0)", [1.0, 1.0, 1.0]),
    ("`gx[dps]` * 2", [6.0, 8.0, 10.0]),
    ("0.00234", [0.00234] * 3),
    ("1e-9 * 2", [2e-9] * 3),
])
def test_arithmetic(text: str, want: list[float]) -> None:
    np.testing.assert_allclose(parse_expression(text).evaluate(COLS, 3), want, rtol=1e-15)


@pytest.mark.parametrize(("text", "want"), [
    ("a == 2", [0, 1, 0]),
    ("a != 2 and b > 0", [1, 0, 1]),
    ("a < 2 or b >= 2", [1, 0, 1]),
    ("not b", [0, 1, 0]),
    ("1 <= a < 4", [1, 1, 0]),
    ("a * (b > 0) > 1", [0, 0, 1]),
])
def test_conditions(text: str, want: list[float]) -> None:
    e = parse_expression(text, condition=True)
    assert e.evaluate(COLS, 3).tolist() == want


@pytest.mark.parametrize(("text", "needle"), [
    ("a.real", "an attribute"),
    ("a[0]", "a subscript"),
    ("exp(a)", "the function exp()"),
    ("__import__('os')", "the function __import__()"),
    ("a // 2", "the operator //"),
    ("a % 2", "the operator %"),
    ("'text'", "is not a number"),
    ("True", "is not a number"),
    ("1j", "is not a number"),
    ("lambda: 1", "is not allowed"),
    ("a if b else 1", "is not allowed"),
    ("a == 1", "a comparison is not allowed (only in valid)"),
    ("a and b", "and/or is not allowed (only in valid)"),
    ("a +", "syntax error"),
    ("gx[dps] * 2", "a subscript"),
    ("temp C", "backquotes"),
    ("`a * 2", "without its pair"),
    ("sqrt(a, b)", "takes one argument"),
    ("a + " * 150 + "a", "nested more than 100 deep"),
    ("a + " * 20000 + "a", "nested too deeply"),
    ("1" * 400, "beyond float64's range"),
    ("1" * 400 + ".0", "beyond float64's range"),
])
def test_forbidden_says_what_is_allowed(text: str, needle: str) -> None:
    with pytest.raises(ExpressionError) as e:
        parse_expression(text)
    assert needle in str(e.value)


@pytest.mark.parametrize(("text", "row", "needle"), [
    ("a / b", 1, "division by zero: b is 0"),
    ("sqrt(b - 1)", 0, "sqrt(b - 1) is NaN"),
    ("a ** 2000", 1, "a ** 2000 is Inf"),
    ("1 / (a - 1)", 0, "division by zero: a - 1 is 0"),
])
def test_bad_values_name_the_first_row(text: str, row: int, needle: str) -> None:
    with pytest.raises(EvaluationError) as e:
        parse_expression(text).evaluate(COLS, 3)
    assert e.value.row == row and needle in str(e.value)


def test_columns_split_at_commas_outside_parentheses_and_backquotes() -> None:
    assert split_top_level("a=b,c=sqrt(abs(x)),d=`p,q` * 2") == [
        "a=b", "c=sqrt(abs(x))", "d=`p,q` * 2"]
    cols = Dialect.parse_columns("valid=a == 1 and b <= 2,time_s=sec + nanosec * 1e-9,"
                                 "earth_rate_dps=0.00234")
    assert dict(cols) == {"valid": "a == 1 and b <= 2", "time_s": "sec + nanosec * 1e-9",
                          "earth_rate_dps": "0.00234"}


# --- the ROS rig, read to the plain log's numbers ---------------------------------------

def _check_ros(got: ChamberLog, ref: ChamberLog) -> None:
    np.testing.assert_allclose(got.time_s - T0, ref.time_s + 0.123456789, rtol=0, atol=5e-7)
    np.testing.assert_allclose(got.gyro_dps, ref.gyro_dps, rtol=1e-14)
    np.testing.assert_allclose(got.table_rate_dps, ref.table_rate_dps, rtol=1e-14)
    assert np.array_equal(got.temp_c, ref.temp_c)
    assert got.sample_dt_s == ref.sample_dt_s


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_ros_rig_reads_to_the_plain_logs_numbers(suffix: str, plain: Path, tmp_path: Path,
                                                   capsys) -> None:
    ref = read_log(plain)
    ros = write_ros(ref, tmp_path / "ros.csv")
    mapping = ros_map(float(ref.earth_rate_dps[0]))  # type: ignore[index]
    f = tmp_path / f"fogsf-columns{suffix}"
    f.write_text(toml_of(mapping) if suffix == ".toml" else json.dumps(mapping))
    got = read_log(ros)
    _check_ros(got, ref)
    assert got.valid is not None and got.valid.all()
    assert np.array_equal(got.earth_rate_dps, ref.earth_rate_dps)  # type: ignore[arg-type]
    assert list(got.extra) == ["sec", "nanosec", "gyro_raw", "rig_rate", "rig_heating",
                               "rig_enabled", "rig_stalled"]
    assert main(["inspect", "--json", str(plain)]) == 0
    want = json.loads(capsys.readouterr().out)
    assert main(["inspect", "--json", str(ros)]) == 0
    out = capsys.readouterr()
    have = json.loads(out.out)
    assert have["samples"] == want["samples"] and have["sample_rate_hz"] == 10.0
    for k, v in want["metrics"].items():
        assert have["metrics"][k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
    assert "time_s = sec + nanosec * 1e-9" in out.err and "gyro_temp -> temp_c" in out.err


def test_the_same_map_on_every_path(plain: Path, tmp_path: Path) -> None:
    """--columns and a file give the same; quoted cells and decimal commas (the general
    path) the fast path's numbers."""
    ref = read_log(plain)
    mapping = ros_map(0.00234)
    arg = ",".join(f"{k}={v}" for k, v in mapping.items())
    fast = read_log(write_ros(ref, tmp_path / "ros.csv"), Dialect(
        columns=Dialect.parse_columns(arg)))
    f = tmp_path / "map.toml"
    f.write_text(toml_of(mapping))
    dialect = Dialect(columns=Dialect.parse_columns(str(f)), columns_from=str(f))
    text = (tmp_path / "ros.csv").read_text()
    quoted = tmp_path / "quoted.csv"
    quoted.write_text("\n".join(",".join(f'"{c}"' for c in line.split(","))
                                for line in text.splitlines()) + "\n")
    comma = tmp_path / "comma.csv"
    comma.write_text(text.replace(",", ";").replace(".", ","))
    for other in (read_log(tmp_path / "ros.csv", dialect), read_log(quoted, dialect),
                  read_log(comma, Dialect(columns=dialect.columns, decimal_comma=True))):
        for k, v in fast.columns().items():
            assert np.array_equal(v, other.columns()[k]), k


def test_rows_the_flags_mark_measure_nothing(plain: Path, tmp_path: Path) -> None:
    ref = read_log(plain)
    n = len(ref)
    enabled, stalled = np.ones(n), np.zeros(n)
    enabled[100:150] = 0
    stalled[300:305] = 1
    ros = write_ros(ref, tmp_path / "ros.csv", enabled, stalled)
    (tmp_path / "fogsf-columns.toml").write_text(toml_of(ros_map(0.00234)))
    got = read_log(ros)
    want = np.ones(n, dtype=bool)
    want[100:150] = want[300:305] = False
    assert got.valid is not None and np.array_equal(got.valid, want)
    assert np.array_equal(got.measures, want) and len(got) == n
    # written back in the format (an epoch time base keeps every digit) and read the same
    write_log(tmp_path / "out" / "plain.csv", got)
    back = read_log(tmp_path / "out" / "plain.csv")
    assert np.array_equal(back.time_s, got.time_s)
    assert np.array_equal(back.measures, got.measures)


def test_an_epoch_time_base_at_high_rates(tmp_path: Path) -> None:
    """ns time stamps of 1.7e9 s: the rate is the stated one, a dropped sample counted."""
    for hz in (100.0, 1000.0, 4000.0):
        ns = T0 * 10**9 + 987_654_321 + np.round(np.arange(4000) * 1e9 / hz).astype(np.int64)
        rows = [f"{v // 10**9},{v % 10**9},20.5,10,10" for v in ns]
        text = "\n".join(["sec,nanosec,temp_c,table_rate_dps,gyro_dps", *rows]) + "\n"
        dialect = Dialect(columns=(("time_s", "sec + nanosec * 1e-9"),))
        assert parse_log(text, "x.csv", dialect).sample_rate_hz == hz
        lines = text.splitlines()
        del lines[1001]
        log = parse_log("\n".join(lines), "x.csv", dialect)
        assert log.sample_rate_hz == hz and log.sampling.dropped == 1
        assert log.sampling.jittered == 0  # float64's rounding of the stamps is no jitter


# --- non-identifier names ----------------------------------------------------------------

def test_names_that_are_not_identifiers(tmp_path: Path) -> None:
    p = tmp_path / "rig.csv"
    rows = [f"{0.1 * i:.1f};20.5;10;{10.0 + 1e-4 * i!r};{i % 3}" for i in range(20)]
    p.write_text("\n".join(["t [s];temp C;table;gx[dps];flag", *rows]) + "\n")
    log = read_log(p, Dialect(columns=Dialect.parse_columns(
        "time_s=t [s],temp_c=temp C,table_rate_dps=table,gyro_dps=`gx[dps]` * 2,"
        "valid=`flag` != 1")))
    assert log.time_s[3] == pytest.approx(0.3) and log.temp_c[0] == 20.5
    assert log.gyro_dps[1] == pytest.approx(2 * (10.0 + 1e-4))
    assert log.measures.tolist() == [i % 3 != 1 for i in range(20)]
    assert list(log.extra) == ["gx[dps]", "flag"]
    # Python reads the micro sign (U+00B5) in an identifier as mu (U+03BC): still the column
    p.write_text(p.read_text().replace("gx[dps]", "g_\u00b5rad", 1))
    log = read_log(p, Dialect(columns=Dialect.parse_columns(
        "time_s=t [s],temp_c=temp C,table_rate_dps=table,gyro_dps=g_\u00b5rad * 1e-6")))
    assert log.gyro_dps[1] == pytest.approx(1e-6 * (10.0 + 1e-4))


# --- per-axis names ----------------------------------------------------------------------

def _imu(tmp_path: Path, header: str, mapping: dict[str, str | float] | None = None) -> Path:
    """A 3-axis log on a one-axis table: each axis sees the table through its cosine."""
    p = tmp_path / "imu.csv"
    rows = [f"{0.1 * i:.1f},21.5,100,{80.0 + 1e-3 * i!r},{-60.0 + 1e-3 * i!r},{1e-3 * i!r}"
            for i in range(50)]
    p.write_text("\n".join([header, *rows]) + "\n")
    if mapping is not None:
        (tmp_path / "fogsf-columns.toml").write_text(toml_of(mapping))
    return p


SKEW = {"table_rate_x_dps": "table * 0.8", "table_rate_y_dps": "table * -0.6",
        "earth_rate_x_dps": 0.001, "earth_rate_dps": 0.002}


def test_per_axis_names_from_the_header(tmp_path: Path) -> None:
    p = _imu(tmp_path, "time_s,temp_c,table_rate_dps,gyro_x_dps,gyro_y_dps,gyro_z_dps",
             {"earth_rate_x_dps": 0.001, "earth_rate_dps": 0.002})
    assert log_axes_of(p, Dialect()) == ["x", "y", "z"]
    x = read_log(p, Dialect(axis="x"))
    assert x.gyro_dps[0] == 80.0 and x.earth_rate_dps[0] == 0.001  # type: ignore[index]
    y = read_log(p, Dialect(axis="y"))
    assert y.gyro_dps[0] == -60.0 and y.earth_rate_dps[0] == 0.002  # type: ignore[index]
    assert "gyro_x_dps" in y.extra and "earth_rate_x_dps" in y.extra


def test_per_axis_names_from_the_map(tmp_path: Path, capsys) -> None:
    mapping = {"gyro_x_dps": "gx", "gyro_y_dps": "gy", "gyro_z_dps": "gz", **SKEW}
    p = _imu(tmp_path, "time_s,temp_c,table,gx,gy,gz", mapping)
    assert log_axes_of(p, Dialect()) == ["x", "y", "z"]
    assert log_axes_of(p, Dialect(axis="y")) == ["x", "y", "z"]  # --axis is not a filter
    x = read_log(p, Dialect(axis="x"))
    assert x.table_rate_dps[0] == pytest.approx(80.0) and x.gyro_dps[0] == 80.0
    assert x.earth_rate_dps[0] == 0.001  # type: ignore[index]
    y = read_log(p, Dialect(axis="y"))
    assert y.table_rate_dps[0] == pytest.approx(-60.0)
    assert y.earth_rate_dps[0] == 0.002  # type: ignore[index]
    with pytest.raises(LogError, match="missing required column: table_rate_dps"):
        read_log(p, Dialect(axis="z"))  # no table_rate_z_dps and no table_rate_dps
    # the common table rate is what an axis without its own reads
    cols = Dialect.parse_columns(",".join(f"{k}={v}" for k, v in mapping.items())
                                 + ",table_rate_dps=table")
    z = read_log(p, Dialect(columns=cols, axis="z"))
    assert z.table_rate_dps[0] == 100.0 and z.gyro_dps[1] == pytest.approx(1e-3)
    assert read_log(p, Dialect(columns=cols, axis="x")).table_rate_dps[0] == pytest.approx(80)
    assert log_axes_of(p, Dialect(columns=cols)) == ["x", "y", "z"]
    notes = read_log(p, Dialect(axis="y")).read_notes
    assert notes[0].startswith("columns gx -> gyro_x_dps, gy -> gyro_y_dps, gz -> gyro_z_dps,"
                               " table_rate_x_dps = table * 0.8,")
    assert notes[-1] == "columns gyro_y_dps -> gyro_dps, table_rate_y_dps -> table_rate_dps " \
                        "(--axis y)", notes
    err = _refused(capsys, "inspect", str(p), "--axis", "w")
    assert "--axis names 'gyro_w_dps' for gyro_dps; header has: time_s, temp_c, table, gx" in err
    assert "the column map gives table_rate_x_dps" in err


def test_log_axes_of_reads_the_header_only(tmp_path: Path) -> None:
    p = tmp_path / "imu.csv"
    p.write_text('\ufeff"time_s";"temp_c";"table_rate_dps";"gyro_b_dps";"gyro_a_dps"\n'
                 "not read\n")
    assert log_axes_of(p, Dialect()) == ["b", "a"]
    cols = Dialect.parse_columns("gyro_c_dps=gyro_a_dps * -1")
    assert log_axes_of(p, Dialect(columns=cols)) == ["b", "a", "c"]
    assert log_axes_of(p, Dialect(columns=(("gyro_c_dps", "gyro_a_dps"),))) == ["b", "c"]
    with pytest.raises(LogError, match="no such file"):
        log_axes_of(tmp_path / "nope.csv", Dialect())
    with pytest.raises(LogError, match="no such column"):
        log_axes_of(p, Dialect(columns=(("gyro_c_dps", "ga * 2"),)))


# --- refusals, one line each -------------------------------------------------------------

BASE = "sec,temp,table,omega,flag,n\n" + "".join(
    f"{i},{20 + 0.01 * i},{0 if i == 7 else 10},10.001,{i % 2},{i}\n" for i in range(20))
MAP = "time_s=sec,temp_c=temp,table_rate_dps=table,gyro_dps=omega"


@pytest.mark.parametrize(("extra", "needle"), [
    ("earth_rate_dps=omega - omgea",
     "line 1: no such column: --columns names 'omgea' for earth_rate_dps (in omega - omgea)"
     "; header has: sec, temp, table, omega, flag, n"),
    ("earth_rate_dps=omega +* 2", "syntax error"),
    ("earth_rate_dps=omega.real", "an attribute (.) is not allowed; allowed: numbers"),
    ("earth_rate_dps=exp(omega)", "the function exp() is not allowed"),
    ("earth_rate_dps=omega > 1", "a comparison is not allowed (only in valid)"),
    ("earth_rate_dps=1 / (sec - 4)",
     "line 6: column map: earth_rate_dps = 1 / (sec - 4) (--columns): division by zero: "
     "sec - 4 is 0"),
    ("earth_rate_dps=sqrt(4 - sec)",
     "line 7: column map: earth_rate_dps = sqrt(4 - sec) (--columns): sqrt(4 - sec) is NaN"),
    ("valid=flag > 5", "no row measures: valid = flag > 5 (--columns) is 0 on every row"),
    ("valid=flag * 2", "line 3: column map: valid = flag * 2 (--columns) is 2: valid takes a "
     "condition"),
    ("valid=n", "line 4: column map: valid (the log's 'n') (--columns) is 2"),
    ("speed=omega", "'speed' is not a column of the format (time_s, temp_c, table_rate_dps, "
     "gyro_dps, earth_rate_dps, chamber_c, valid, temp_<name>_c, gyro_<a>_dps, "
     "table_rate_<a>_dps, earth_rate_<a>_dps)"),
    ("gyro_x_y_dps=omega", "is not a column of the format"),
    ("earth_rate_dps=", "expected OURS=THEIRS pairs"),
    ("time_s=sec * 2", "time_s is mapped twice"),
])
def test_refusals(extra: str, needle: str, tmp_path: Path, capsys) -> None:
    p = tmp_path / "rig.csv"
    p.write_text(BASE)
    assert len(read_log(p, Dialect(columns=Dialect.parse_columns(MAP)))) == 20
    err = _refused(capsys, "inspect", str(p), "--columns", f"{MAP},{extra}", "--latitude-deg",
                   "45")
    assert needle in err, err


def test_a_valid_that_keeps_only_zero_rate_rows(tmp_path: Path) -> None:
    p = tmp_path / "rig.csv"
    p.write_text(BASE)
    cols = Dialect.parse_columns(f"{MAP},valid=sec == 7")
    with pytest.raises(LogError, match="every row has a zero table rate or valid = 0"):
        read_log(p, Dialect(columns=cols))


@pytest.mark.parametrize("value", ["true", "nan", "inf", "[1]", '""'])
def test_a_mapping_file_takes_text_and_finite_numbers(value: str, tmp_path: Path) -> None:
    f = tmp_path / "map.toml"
    f.write_text(f"earth_rate_dps = {value}\n")
    with pytest.raises(UserError, match="map.toml: (expected a mapping|earth_rate_dps is "
                                        "mapped to nothing)"):
        Dialect.mapping_file(f)


def test_a_map_beside_a_log_in_the_formats_names(plain: Path, tmp_path: Path) -> None:
    """The ROS map does not apply to a plain log beside it (it reads none of its columns);
    a map of numbers alone applies to every log."""
    p = tmp_path / "plain.csv"
    p.write_text(_without_earth(plain.read_text()))
    f = tmp_path / "fogsf-columns.toml"
    f.write_text(toml_of(ros_map(0.00234)))
    log = read_log(p)
    assert log.earth_rate_dps is None and log.valid is None
    assert log.read_notes == (f"{f} not applied: the header has the format's names",)
    f.write_text('earth_rate_dps = "0.00234"\n')
    log = read_log(p)
    assert log.earth_rate_dps is not None and (log.earth_rate_dps == 0.00234).all()
    assert log.read_notes == (f"columns earth_rate_dps = 0.00234 ({f})",)


def _without_earth(text: str) -> str:
    rows = [line.split(",") for line in text.splitlines()]
    k = rows[0].index("earth_rate_dps")
    return "\n".join(",".join(r[:k] + r[k + 1:]) for r in rows) + "\n"


def test_axis_reads_its_own_thermometer(tmp_path: Path) -> None:
    """--axis A reads temp_A_c (one thermometer per gyro) as temp_c; without one, the
    common temp_c."""
    from fogsf.logs.logio import read_log
    from fogsf.logs.read.dialect import Dialect

    rows = [f"{0.1 * i:.1f},{20 + 0.01 * i:.2f},{30 + 0.01 * i:.2f},10,10,10" for i in range(6)]
    p = tmp_path / "imu.csv"
    p.write_text("time_s,temp_c,temp_x_c,table_rate_dps,gyro_x_dps,gyro_y_dps\n"
                 + "\n".join(rows) + "\n")
    x = read_log(p, Dialect(axis="x"))
    y = read_log(p, Dialect(axis="y"))
    assert x.temp_c[0] == 30.0 and y.temp_c[0] == 20.0
    assert "temp_x_c" in y.extra
