"""Plateau tables (docs/logs.md, "Plateau tables"): a rig's DAQ writes a row per rate plateau
(the mean output in counts, the commanded rate, the mean temperature) with a
fogsf-columns.toml beside it saying layout = "plateaus". The table reads back exactly, inspect
recovers the IEEE Std 952 figures planted in it per temperature group, and every refusal is
one line with exit status 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.chamber_log import LogError
from fogsf.logs.logio import read_log
from fogsf.logs.measure.table_figures import table_figures, temperature_groups
from fogsf.logs.plateau_table import read_plateau_table
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.parquet_log import write_columns

NOMINAL = 25000.0  # counts per deg/s: the map divides by it
EARTH = 0.00234
SETPOINTS = (36.0, 40.0, 45.0, 50.0, 57.0)
RATES = (0.0, 50.0, 100.0, 150.0, 0.0, -50.0, -100.0, -150.0)  # a rig's staircase, each set point
T0 = 45.0
SF_PPM, SF_PPM_PER_C = 150.0, 2.0  # the SF vs nominal and its drift
ASYM_PPM = 20.0  # SF+ - SF-
BIAS_DPH, BIAS_DPH_PER_C = 1.0, 0.05
# an odd deviation from the line per |rate| (deg/s): orthogonal to r and 1 over the staircase
# (50 * 0.0045 - 150 * 0.0015 = 0), so it is the nonlinearity and moves no other figure
DEV = {50.0: 0.0045, 100.0: 0.0, 150.0: -0.0015}
PLATEAU_S = 20.0


def sf_ppm(t: np.ndarray | float) -> np.ndarray | float:
    return SF_PPM + SF_PPM_PER_C * (np.asarray(t) - T0)


def bias_dph(t: np.ndarray | float) -> np.ndarray | float:
    return BIAS_DPH + BIAS_DPH_PER_C * (np.asarray(t) - T0)


def planted_nonlinearity_ppm_fs(t: float) -> float:
    """IEEE Std 952's nonlinearity of one group: the largest deviation of a level's mean from
    the least-squares line through the group's plateaus, over full scale. The line through
    0, 0, +/-50, +/-100, +/-150 absorbs the asymmetry's mean (|r| averages 75 deg/s), so a
    level deviates by its DEV plus the asymmetry's A/2 (|r| - 75)."""
    half = ASYM_PPM / 2 * 1e-6
    dev = [abs(s * d + half * (r - 75.0)) for r, d in DEV.items() for s in (-1, 1)]
    return max(dev) / (150.0 * (1 + float(sf_ppm(t)) * 1e-6)) * 1e6


def rig_rows(jitter_c: float = 0.2) -> dict[str, np.ndarray]:
    """The plateau means a rig writes: per set point the staircase RATES, its temperature
    scattered within +/- jitter_c; output = r (1 + SF(T) +/- A/2) + DEV + bias(T) + earth."""
    rng = np.random.default_rng(7)
    rate = np.tile(RATES, len(SETPOINTS))
    temp = np.repeat(SETPOINTS, len(RATES)) + rng.uniform(-jitter_c, jitter_c, rate.size)
    sf = 1 + (sf_ppm(temp) + np.sign(rate) * ASYM_PPM / 2) * 1e-6
    dev = np.array([DEV.get(abs(r), 0.0) for r in rate]) * np.sign(rate)
    out = rate * sf + dev + bias_dph(temp) / 3600 + EARTH
    return {"t_start": np.arange(rate.size) * PLATEAU_S, "out_counts": out * NOMINAL,
            "cmd_rate": rate, "temp": temp, "dur": np.full(rate.size, PLATEAU_S)}


MAP = """layout = "plateaus"
gyro_dps = "out_counts / 25000"
table_rate_dps = "cmd_rate"
temp_c = "temp"
earth_rate_dps = 0.00234
"""
# how the table says what time a row stands for: extra map lines, the columns written
TIMES = {"start": ('time_is = "start"\ntime_s = "t_start"\n', ["t_start"]),
         "middle": ('time_is = "middle"\ntime_s = "t_mid"\n', ["t_mid"]),
         "duration": ('duration_s = "dur"\n', ["dur"]),
         "plateau_s": ("plateau_s = 20\n", [])}


def write_table(folder: Path, rows: dict[str, np.ndarray], times: str = "start",
                map_text: str = MAP) -> Path:
    """The CSV a rig's DAQ writes (numbers in full) and its fogsf-columns.toml."""
    folder.mkdir(parents=True, exist_ok=True)
    extra, cols = TIMES[times]
    rows = {**rows, "t_mid": rows["t_start"] + PLATEAU_S / 2}
    names = [*cols, "out_counts", "cmd_rate", "temp"]
    lines = [",".join(names)] + [",".join(repr(float(rows[c][i])) for c in names)
                                 for i in range(rows["cmd_rate"].size)]
    (folder / "table.csv").write_text("\n".join(lines) + "\n")
    (folder / "fogsf-columns.toml").write_text(map_text + extra)
    return folder / "table.csv"


@pytest.mark.parametrize("times", list(TIMES))
def test_a_rigs_table_reads_back_exactly(times: str, tmp_path: Path) -> None:
    rows = rig_rows()
    t = read_plateau_table(write_table(tmp_path, rows, times))
    assert np.array_equal(t.gyro_dps, rows["out_counts"] / NOMINAL)
    assert np.array_equal(t.table_rate_dps, rows["cmd_rate"])
    assert np.array_equal(t.temp_c, rows["temp"])
    assert np.array_equal(t.earth_rate_dps, np.full(len(t), EARTH))
    assert np.array_equal(t.time_s, rows["t_start"])  # every way of giving times: the starts
    assert np.array_equal(t.duration_s, np.full(len(t), PLATEAU_S))
    assert t.path == str(tmp_path / "table.csv") and t.valid is None


def test_a_parquet_table_and_columns_given_read_as_the_csv(tmp_path: Path) -> None:
    rows = rig_rows()
    csv = write_table(tmp_path / "csv", rows)
    write_columns(tmp_path / "pq" / "table.parquet",
                  {k: rows[k] for k in ("t_start", "out_counts", "cmd_rate", "temp")})
    (tmp_path / "map.toml").write_text((tmp_path / "csv" / "fogsf-columns.toml").read_text())
    a = read_plateau_table(csv)
    b = read_plateau_table(tmp_path / "pq" / "table.parquet",
                           Dialect(columns=Dialect.mapping_file(tmp_path / "map.toml"),
                                   layout=Dialect.mapping_layout(tmp_path / "map.toml")))
    for k in ("time_s", "duration_s", "table_rate_dps", "gyro_dps", "temp_c"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    # the CLI takes the map as --columns FILE too
    assert main(["inspect", str(tmp_path / "pq" / "table.parquet"), "--columns",
                 str(tmp_path / "map.toml")]) == 0


def test_a_table_in_the_formats_names_needs_only_its_layout(tmp_path: Path) -> None:
    rows = rig_rows()
    names = {"t_start": "time_s", "cmd_rate": "table_rate_dps", "temp": "temp_c"}
    head = ["time_s", "gyro_dps", "table_rate_dps", "temp_c", "earth_rate_dps"]
    vals = [rows["t_start"], rows["out_counts"] / NOMINAL, rows["cmd_rate"], rows["temp"],
            np.full(rows["temp"].size, EARTH)]
    assert set(names.values()) < set(head)
    (tmp_path / "table.csv").write_text(
        ",".join(head) + "\n" + "".join(",".join(repr(float(v[i])) for v in vals) + "\n"
                                        for i in range(rows["temp"].size)))
    (tmp_path / "fogsf-columns.toml").write_text('layout = "plateaus"\ntime_is = "start"\n')
    t = read_plateau_table(tmp_path / "table.csv")
    assert np.array_equal(t.gyro_dps, vals[1]) and np.array_equal(t.time_s, vals[0])


def _inspect(capsys, path: Path, *argv: str) -> dict:
    assert main(["inspect", str(path), "--json", *argv]) == 0
    return json.loads(capsys.readouterr().out)


def test_inspect_recovers_the_planted_figures_per_temperature(tmp_path: Path, capsys) -> None:
    s = _inspect(capsys, write_table(tmp_path, rig_rows()))
    f = s["figures"]
    assert s["plateaus"] == len(RATES) * len(SETPOINTS) and s["bias_plateaus"] == 10
    assert [round(g["temp_c"]) for g in f["groups"]] == [round(t) for t in SETPOINTS]
    for g in f["groups"]:
        assert g["plateaus"] == len(RATES)
        # the SF moves +/- 0.4 ppm with the temperature scatter inside a group
        assert g["sf_ppm"] == pytest.approx(sf_ppm(g["temp_c"]), abs=0.5)
        assert g["bias_dph"] == pytest.approx(bias_dph(g["temp_c"]), abs=0.02)
        assert g["sf_asymmetry_ppm"] == pytest.approx(ASYM_PPM, abs=1.0)
        assert g["sf_nonlinearity_ppm_fs"] == pytest.approx(
            planted_nonlinearity_ppm_fs(g["temp_c"]), abs=0.5)
    assert f["sf_drift_ppm_per_c"] == pytest.approx(SF_PPM_PER_C, abs=0.05)
    assert f["bias_drift_dph_per_c"] == pytest.approx(BIAS_DPH_PER_C, abs=0.002)
    o = f["overall"]  # the whole table's fit: SF and bias as polynomials of temperature
    assert o["sf_asymmetry_ppm"] == pytest.approx(ASYM_PPM, abs=0.2)
    assert o["sf_ppm"] == pytest.approx(sf_ppm(o["temp_c"]), abs=0.2)
    # the nonlinearity leaks a little into the cubic thermal terms through the temperature
    # scatter (0.03 deg/h here, 1e-5 deg/s against a 4.5e-3 deg/s deviation)
    assert o["bias_dph"] == pytest.approx(bias_dph(o["temp_c"]), abs=0.05)
    assert o["sf_nonlinearity_ppm_fs"] == pytest.approx(planted_nonlinearity_ppm_fs(T0), abs=1)


def test_inspect_prints_a_row_per_temperature_group(tmp_path: Path, capsys) -> None:
    path = write_table(tmp_path, rig_rows(), "duration")
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "plateau table, 40 plateaus (10 at 0 deg/s)" in out
    assert "times from duration_s" in out and "in 5 groups" in out
    table = out.split("bias (deg/h)\n", 1)[1].splitlines()
    assert len([line for line in table if line.startswith("    ")]) == len(SETPOINTS)
    assert "SF +2.0" in out.split("drift with temperature")[1]


def _refused(capsys, *argv: str) -> str:
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    err = [line for line in err if not line.startswith("fogsf: read ")]
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def _with(rows: dict[str, np.ndarray], **cols: np.ndarray) -> dict[str, np.ndarray]:
    return {**rows, **cols}


@pytest.mark.parametrize(("change", "times", "says"), [
    # samples mixed in: rows 0.1 s apart at the table's start
    (lambda r: _with(r, t_start=np.concatenate([[0.0, 0.1], r["t_start"][2:]])), "start",
     "line 3: samples in a plateau table: time_s 0.1 is 0.1 s after the row above"),
    (lambda r: _with(r, t_start=r["t_start"][::-1].copy()), "start",
     "line 3: time not increasing"),
    (lambda r: _with(r, dur=np.where(np.arange(r["dur"].size) == 4, 0.1, r["dur"])), "duration",
     "line 6: not a plateau: a plateau of 0.1 s"),
    (lambda r: _with(r, cmd_rate=np.full(r["cmd_rate"].size, 100.0)), "start",
     "rates never change: table_rate_dps is 100 deg/s on every row"),
    (lambda r: _with(r, temp=40.0 + 0.1 * np.sin(np.arange(r["temp"].size))), "start",
     "one temperature only"),
])
def test_each_refusal_is_one_line(change, times: str, says: str, tmp_path: Path,  # noqa: ANN001
                                  capsys) -> None:
    path = write_table(tmp_path, change(rig_rows()), times)
    err = _refused(capsys, "inspect", str(path))
    assert says in err and str(path) in err, err


@pytest.mark.parametrize(("map_text", "says"), [
    (MAP.replace('temp_c = "temp"\n', ""), "missing required column: temp_c"),
    (MAP, "no time for the rows"),
])
def test_a_map_without_a_column_or_a_time_is_refused(map_text: str, says: str, tmp_path: Path,
                                                    capsys) -> None:
    path = write_table(tmp_path, rig_rows(), "plateau_s")  # no time column
    (tmp_path / "fogsf-columns.toml").write_text(map_text)  # nor plateau_s
    assert says in _refused(capsys, "inspect", str(path))


def test_time_s_without_time_is_is_refused(tmp_path: Path, capsys) -> None:
    path = write_table(tmp_path, rig_rows(), "start")
    toml = tmp_path / "fogsf-columns.toml"
    toml.write_text(toml.read_text().replace('time_is = "start"\n', ""))
    assert 'time_is = "start" or "middle"' in _refused(capsys, "inspect", str(path))


@pytest.mark.parametrize("argv", [
    ["plan", "--from-logs", "{t}", "--hours", "4", "--out", "{d}/plan"],
])
def test_other_commands_refuse_a_plateau_table_naming_inspect(argv: list[str], tmp_path: Path,
                                                              capsys) -> None:
    path = write_table(tmp_path / "rig", rig_rows())
    err = _refused(capsys, *(a.format(t=path, d=tmp_path) for a in argv))
    assert "a plateau table" in err and "`train`, `replay`, `diagnose` and `fleet add`" in err
    with pytest.raises(LogError, match="`train`, `replay`, `diagnose` and `fleet add`"):
        read_log(path)


def test_a_plateau_key_on_a_sample_log_is_refused(tmp_path: Path, capsys) -> None:
    path = write_table(tmp_path, rig_rows(), "start", MAP.replace('layout = "plateaus"\n', ""))
    assert "time_is is a plateau table's key" in _refused(capsys, "inspect", str(path))


def test_groups_with_one_direction_or_no_rate_give_what_they_measure() -> None:
    """A group at +rates only gives its SF and bias; one of bias plateaus only, its bias; the
    whole table's thermal terms stop at what its turning groups tell apart (two: a line)."""
    r = np.array([0, 50, 100, 0, 50, -50, 100, -100, 0, 0.0])
    temp = np.array([30, 30.4, 30.9, 40, 40, 40, 40, 40, 50, 50.5])
    assert temperature_groups(temp).tolist() == [0, 0, 0, 1, 1, 1, 1, 1, 2, 2]
    f = table_figures(r, r * 1.0001 + 1e-4, temp)
    one_way, full, still = f.groups
    assert one_way.sf_ppm == pytest.approx(100.0) and one_way.bias_dps == pytest.approx(1e-4)
    assert np.isnan(one_way.nonlinearity_ppm) and np.isnan(one_way.asymmetry_ppm)
    assert full.asymmetry_ppm == pytest.approx(0.0, abs=1e-6)
    assert np.isnan(still.sf_ppm) and still.bias_dps == pytest.approx(1e-4)
    assert f.overall is not None and f.overall.sf_ppm == pytest.approx(100.0)
    d = f.as_dict()["groups"][2]
    assert d["sf_ppm"] is None and d["sf_asymmetry_ppm"] is None
