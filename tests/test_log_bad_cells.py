"""`--bad-cells skip` (docs/logs.md, "What the reader refuses"): a cell that holds no number
makes its row measure nothing instead of refusing the log; by default the log is refused in
one line that names the option."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import read_log
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.stream_read import read_log_on_disk

N = 6000  # 10 min at 10 Hz


def _log(path: Path, bad: dict[tuple[int, int], str]) -> Path:
    """A 10 Hz log at 10 deg/s over a 20 -> 30 C ramp, the cells `bad` ((row, column) ->
    text) written in place of their numbers."""
    t = np.arange(N) / 10.0
    cols = [t, 20.0 + t / 60.0, np.full(N, 10.0), np.full(N, 10.001), np.full(N, 0.00234)]
    lines = ["time_s,temp_c,table_rate_dps,gyro_dps,earth_rate_dps"]
    for i in range(N):
        cells = [f"{c[i]:.6f}" for c in cols]
        for (r, c), text in bad.items():
            if r == i:
                cells[c] = text
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("cell,col", [("ERR", 3), ("NaN", 1), ("", 0), ("inf", 3)])
def test_a_bad_cell_refuses_naming_the_option(tmp_path: Path, capsys, cell: str,
                                              col: int) -> None:
    log = _log(tmp_path / "a.csv", {(1000, col): cell})
    capsys.readouterr()
    assert main(["inspect", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 1002" in err, err
    assert "--bad-cells skip" in err, err


@pytest.mark.parametrize("reader", [read_log, read_log_on_disk])
def test_skip_makes_the_rows_measure_nothing(tmp_path: Path, reader) -> None:  # noqa: ANN001
    bad = {(1000, 3): "ERR", (2500, 1): "NaN", (4000, 0): "-"}
    log = _log(tmp_path / "a.csv", bad)
    lg = reader(str(log), Dialect(bad_cells="skip"))
    assert len(lg) == N
    valid = np.asarray(lg.valid[:])
    assert list(np.flatnonzero(~valid)) == [1000, 2500, 4000]
    assert lg.time_s[4000] == pytest.approx(400.0)  # filled from its neighbours
    assert lg.gyro_dps[1000] == pytest.approx(10.001)
    note = " | ".join(lg.read_notes)
    assert "3 rows with a cell that holds no number (the first at line 1002)" in note, note


def test_skip_on_the_command_line(tmp_path: Path, capsys) -> None:
    log = _log(tmp_path / "a.csv", {(1000, 3): "ERR"})
    capsys.readouterr()
    assert main(["inspect", str(log), "--bad-cells", "skip", "--window-s", "60"]) == 0
    err = capsys.readouterr().err
    assert "1 row with a cell that holds no number (the first at line 1002) measures " \
        "nothing (--bad-cells skip)" in err, err
    # a row of another length is not a bad cell: still refused
    text = log.read_text().splitlines()
    text[500] += ",1"
    log.write_text("\n".join(text) + "\n")
    assert main(["inspect", str(log), "--bad-cells", "skip"]) == 2
    assert "wrong number of cells" in capsys.readouterr().err


@pytest.mark.parametrize("reader", [read_log, read_log_on_disk])
def test_a_bad_cell_in_the_first_row_is_a_bad_cell(tmp_path: Path, capsys,
                                                   reader) -> None:  # noqa: ANN001
    """`ERR` in the first row of a numeric column is a bad cell, not a text column: refused
    naming the option, skipped with it."""
    log = _log(tmp_path / "a.csv", {(0, 3): "ERR", (0, 1): "ERR", (5, 1): "ERR"})
    capsys.readouterr()
    assert main(["inspect", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 2" in err and "text column" not in err, err
    assert "--bad-cells skip" in err, err
    lg = reader(str(log), Dialect(bad_cells="skip"))
    assert len(lg) == N and list(np.flatnonzero(~np.asarray(lg.valid[:]))) == [0, 5]
    assert lg.gyro_dps[0] == pytest.approx(10.001)
    assert lg.temp_c[0] == pytest.approx(20.0, abs=1e-4)


@pytest.mark.parametrize("row", [0, N - 1])
def test_a_bad_time_at_an_edge_goes_on_at_the_nominal_step(tmp_path: Path, row: int) -> None:
    """A bad time stamp in the first or last row is filled on from its neighbour by the
    clock's step, not held at it (which would read as time not increasing)."""
    log = _log(tmp_path / "a.csv", {(row, 0): "ERR"})
    lg = read_log(str(log), Dialect(bad_cells="skip"))
    assert len(lg) == N and not lg.valid[row] and lg.valid.sum() == N - 1
    assert lg.time_s[row] == pytest.approx(row / 10.0)


@pytest.mark.parametrize("skip", [[], ["--bad-cells", "skip"]])
def test_a_bad_cell_in_a_plateau_table_names_its_row_not_the_option(tmp_path: Path, capsys,
                                                                      skip: list[str]) -> None:
    """A plateau table's row is one plateau's measurement, with nothing to fill it from: its
    bad cell is refused with or without --bad-cells skip, and the refusal asks for the row
    to be fixed or deleted rather than suggesting the option."""
    from test_plateau_tables import rig_rows, write_table

    path = write_table(tmp_path / "rig", rig_rows())
    lines = path.read_text().splitlines()
    cells = lines[5].split(",")
    cells[-1] = "ERR"
    lines[5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    assert main(["inspect", str(path), *skip]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and "line 6" in err[0] and "fix or delete that row" in err[0], err
    assert "makes such a row measure nothing" not in err[0]
