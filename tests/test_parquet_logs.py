"""Parquet logs: the same ChamberLog as their CSV (names, column map, --axis, rules), the
refusals naming the data row; `replay --out x.parquet` and its round trip; blocks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from fogsf.cli.main import main
from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import log_axes_of, read_log
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.writer import write_log
from fogsf.models import samples


def a_log(n: int = 3000, seed: int = 1) -> ChamberLog:
    rng = np.random.default_rng(seed)
    return ChamberLog(
        time_s=np.arange(n) * 0.01,
        temp_c=np.linspace(10.0, 30.0, n),
        table_rate_dps=np.where(np.arange(n) % 1000 < 500, 10.0, -10.0),
        gyro_dps=rng.normal(10.0, 0.01, n),
        earth_rate_dps=np.full(n, 0.0023),
        extra={"chamber_c": rng.uniform(10, 30, n)},
    )


def same(a: ChamberLog, b: ChamberLog) -> None:
    assert a.columns().keys() == b.columns().keys()
    for name, col in a.columns().items():
        assert np.array_equal(b.columns()[name], col), name
    assert a.read_notes == b.read_notes and a.nominal_dt_s == b.nominal_dt_s


def test_a_parquet_log_reads_as_its_csv(tmp_path: Path) -> None:
    write_log(tmp_path / "a.csv", a_log())
    log = read_log(tmp_path / "a.csv")  # the numbers a CSV holds (10 digits)
    write_log(tmp_path / "a.parquet", log)
    same(log, read_log(tmp_path / "a.parquet"))
    # the same bytes for the same log
    write_log(tmp_path / "b.parquet", log)
    assert (tmp_path / "a.parquet").read_bytes() == (tmp_path / "b.parquet").read_bytes()


def _rig_table(log: ChamberLog) -> pa.Table:
    """A rig's own names and types: integer nanoseconds, a float32 temperature, a bool."""
    n = len(log)
    return pa.table({
        "sec": pa.array((np.arange(n) // 100).astype(np.int64)),
        "nanosec": pa.array((np.arange(n) % 100 * 10_000_000).astype(np.int64)),
        "temperature": pa.array(log.temp_c.astype(np.float32)),
        "table": log.table_rate_dps, "gyro_x_dps": log.gyro_dps,
        "gyro_y_dps": -log.gyro_dps, "ok": pa.array(np.arange(n) % 7 != 0),
    })


def test_column_map_and_axis_apply_to_a_parquet_log(tmp_path: Path) -> None:
    log = a_log()
    table = _rig_table(log)
    pq.write_table(table, tmp_path / "rig.parquet")
    # the same cells as CSV text, every digit (float32 and bool as float64)
    cols = np.column_stack([table.column(k).to_numpy().astype(np.float64)
                            for k in table.column_names])
    np.savetxt(tmp_path / "rig.csv", cols, fmt="%.17g", delimiter=",",
               header=",".join(table.column_names), comments="")
    columns = Dialect.parse_columns("time_s=sec + nanosec * 1e-9,temp_c=temperature,"
                                    "table_rate_dps=table,valid=ok == 1")
    dialect = Dialect(columns=columns, axis="y")
    from_csv = read_log(tmp_path / "rig.csv", dialect)
    from_parquet = read_log(tmp_path / "rig.parquet", dialect)
    same(from_csv, from_parquet)
    assert np.array_equal(from_parquet.gyro_dps, -log.gyro_dps)
    assert from_parquet.valid is not None and not from_parquet.valid[7]
    assert log_axes_of(tmp_path / "rig.parquet", Dialect()) == ["x", "y"]


def test_parquet_refusals_name_the_row(tmp_path: Path) -> None:
    log = a_log()
    p = tmp_path / "bad.parquet"

    def refused(table: pa.Table, dialect: Dialect | None = None) -> str:
        pq.write_table(table, p)
        with pytest.raises(LogError) as ei:
            read_log(p, dialect)
        return str(ei.value)

    good = {k: pa.array(v) for k, v in log.columns().items()}
    t = log.time_s.copy()
    t[100] = t[99]
    assert refused(pa.table({**good, "time_s": t})).startswith(
        f"{p}: time not increasing: row 101: time_s 0.99 after 0.99")
    g = log.gyro_dps.copy()
    g[41] = np.nan
    assert refused(pa.table({**good, "gyro_dps": g})) == (
        f"{p}: non-finite cell: row 42: column 'gyro_dps' is nan")
    assert refused(pa.table({**good, "gyro_dps": pa.array([1.0, None] * (len(log) // 2))})
                   ) == f"{p}: empty cell: row 2: column 'gyro_dps' has no value (null)"
    assert refused(pa.table({**good, "note": pa.array(["x"] * len(log))})) == (
        f"{p}: non-numeric column: column 'note' holds string: a log's columns are numbers")
    missing = {k: v for k, v in good.items() if k != "temp_c"}
    assert refused(pa.table(missing)).startswith(
        f"{p}: missing required column: column names: temp_c (header has: ")
    temp = log.temp_c.copy()
    temp[2999] = 150.0
    assert refused(pa.table({**good, "temp_c": temp})) == (
        f"{p}: temperature out of range: row 3000: temp_c = 150 C, allowed -60..100 C")
    (tmp_path / "text.parquet").write_text("time_s,temp_c\n")
    with pytest.raises(LogError, match="cannot read: not a Parquet file"):
        read_log(tmp_path / "text.parquet")
    with pytest.raises(LogError, match="cannot read: no such file"):
        read_log(tmp_path / "none.parquet")


def test_parquet_ignores_csv_options_and_says_so(tmp_path: Path) -> None:
    write_log(tmp_path / "a.parquet", a_log())
    back = read_log(tmp_path / "a.parquet", Dialect(delimiter=";", decimal_comma=True))
    assert back.read_notes[0] == "--delimiter and --decimal-comma not used: a Parquet log"


def test_replay_writes_parquet_as_its_csv(tmp_path: Path, capsys, monkeypatch) -> None:
    """`replay --out x.parquet`: the numbers of the CSV output, every bit (float32 sf), the
    same metrics; a Parquet log replays as its CSV; blocks of the kernel carry its state."""
    import fogsf.cli.replay as replay

    monkeypatch.setenv("FOGSF_BUILD_DIR", str(tmp_path / "kernels"))
    monkeypatch.setattr(replay, "REPLAY_BLOCK", 777)  # many blocks
    model = samples.random_model(3, 4, 1, 8, decimation=10, seed=6)
    model.save(tmp_path / "m")
    temp, _ = samples.chamber_ramp(hours=0.5, seed=3)
    n = temp.shape[0]
    rng = np.random.default_rng(3)
    log = ChamberLog(np.arange(n) * 0.1, temp, np.full(n, 10.0),
                     10.0 + rng.normal(0, 0.002, n), np.zeros(n))
    write_log(tmp_path / "run.csv", log)
    log = read_log(tmp_path / "run.csv")  # the numbers the CSV holds
    write_log(tmp_path / "run.parquet", log)
    outs = {}
    for src, out in (("run.csv", "c.csv"), ("run.csv", "c.parquet"),
                     ("run.parquet", "p.parquet")):
        assert main(["replay", str(tmp_path / "m"), str(tmp_path / src), "--out",
                     str(tmp_path / out), "--json", str(tmp_path / f"{out}.json"),
                     "--ref-sf", "1.0"]) == 0
        outs[out] = json.loads((tmp_path / f"{out}.json").read_text())
    assert outs["c.csv"]["after"] is not None
    assert outs["c.csv"] == outs["c.parquet"] == outs["p.parquet"]
    assert (tmp_path / "c.parquet").read_bytes() == (tmp_path / "p.parquet").read_bytes()
    table = pq.read_table(tmp_path / "c.parquet")
    assert table.column_names == ["time_s", "gyro_dps", "gyro_corrected_dps", "sf_error_ppm"]
    assert table.schema.field("sf_error_ppm").type == pa.float32()
    from fogsf.bindings.kernel import Kernel

    corrected, sf, _ = Kernel(model).run(log.temp_c, log.gyro_dps)  # one run, from reset
    assert np.array_equal(table.column("gyro_corrected_dps").to_numpy(), corrected)
    assert np.array_equal(table.column("sf_error_ppm").to_numpy(), sf)
    assert np.array_equal(table.column("time_s").to_numpy(), log.time_s)
    text = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)
    assert np.array_equal(text[:, 2], corrected)
    assert np.array_equal(text[:, 3].astype(np.float32), sf)


def test_simulate_writes_a_parquet_log(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.parquet"
    assert main(["simulate", "--scenario", "paper", "--ramp-rate", "1.0", "--profile", "soak",
                 "--start-c", "20", "--duration-min", "10", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"PAR1"
    capsys.readouterr()
    assert main(["inspect", str(out), "--json", "--ref-sf", "1.0"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == 6001


def test_replay_of_a_bias_head_model_in_blocks(tmp_path: Path, monkeypatch) -> None:
    """A model with a bias head: bias_dph written block by block (the kernel's state carried)
    to CSV and Parquet, every sample that of one run from reset."""
    import fogsf.cli.replay as replay
    from fogsf.bindings.kernel import Kernel

    monkeypatch.setenv("FOGSF_BUILD_DIR", str(tmp_path / "kernels"))
    monkeypatch.setattr(replay, "REPLAY_BLOCK", 1000)
    model = samples.random_model(3, 4, 1, 8, decimation=10, seed=6, bias_head=True)
    model.save(tmp_path / "m")
    temp, _ = samples.chamber_ramp(hours=0.3, seed=3)
    n = temp.shape[0]
    log = ChamberLog(np.arange(n) * 0.1, temp, np.full(n, 10.0),
                     10.0 + np.random.default_rng(3).normal(0, 0.002, n), np.zeros(n))
    write_log(tmp_path / "run.csv", log)
    log = read_log(tmp_path / "run.csv")
    for out in ("c.csv", "c.parquet"):
        assert main(["replay", str(tmp_path / "m"), str(tmp_path / "run.csv"), "--out",
                     str(tmp_path / out), "--ref-sf", "1.0"]) == 0
    corrected, sf, bias, _ = Kernel(model).run_bias(log.temp_c, log.gyro_dps)
    table = pq.read_table(tmp_path / "c.parquet")
    assert table.column_names[-1] == "bias_dph"
    assert np.array_equal(table.column("bias_dph").to_numpy(), bias)
    assert np.array_equal(table.column("gyro_corrected_dps").to_numpy(), corrected)
    text = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)
    assert text.shape[1] == 5 and np.array_equal(text[:, 4].astype(np.float32), bias)
    assert np.array_equal(text[:, 3].astype(np.float32), sf)
