"""A log read onto disk (logs/read/stream_read.py) is the log `read_log` gives, to the bit, and a
broken file is refused with the same line, whatever the block size the file is read in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_arrow_reader import BAD, GOOD, SCANNED, _both, _quoted, rows, text

from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import read_log
from fogsf.logs.read import arrow_csv, columns, parquet_log
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.stream_read import read_log_on_disk
from fogsf.logs.writer import write_log


def _read(f) -> ChamberLog | str:  # noqa: ANN001
    try:
        return f()
    except LogError as e:
        return str(e)


def same_log(a: ChamberLog, b: ChamberLog) -> None:
    ca, cb = a.columns(), b.columns()
    assert list(ca) == list(cb)
    for k, v in cb.items():
        assert np.array_equal(ca[k][:], v), k
    assert a.read_notes == b.read_notes
    assert a.nominal_dt_s == b.nominal_dt_s
    assert np.array_equal(a.measures[:], b.measures)


@pytest.fixture(params=[1 << 20, 64])
def small_blocks(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> int:
    """pyarrow's CSV blocks (bytes) and the column reads (samples) small: many borders."""
    monkeypatch.setattr(arrow_csv, "BLOCK_BYTES", request.param)
    monkeypatch.setattr(parquet_log, "BATCH_ROWS", max(7, request.param // 8))
    monkeypatch.setattr(columns, "READ_SAMPLES", max(16, request.param // 4))
    monkeypatch.setattr(columns, "STRICT", True)
    return request.param


@pytest.mark.parametrize("name", list(GOOD))
def test_every_dialect_reads_onto_disk_as_in_memory(name: str, tmp_path: Path,
                                                    small_blocks: int) -> None:
    rewrite, dialect = GOOD[name]
    p = tmp_path / "log.csv"
    p.write_bytes(rewrite(text(rows(300))).encode("utf-8"))
    same_log(read_log_on_disk(p, dialect), read_log(p, dialect))


@pytest.mark.parametrize("name", list(BAD))
def test_refusals_on_disk_are_the_same_line(name: str, tmp_path: Path, small_blocks: int
                                            ) -> None:
    body, dialect, _ = BAD[name]
    p = tmp_path / "log.csv"
    p.write_bytes(body.encode("utf-8"))
    whole, disk = _read(lambda: read_log(p, dialect)), _read(lambda: read_log_on_disk(p, dialect))
    if isinstance(whole, str):
        assert disk == whole
    else:
        same_log(disk, whole)


MAPS = {  # the refusal the column map gives first: the first column in the map's order
    "late-bad-valid": (("valid", "flag"), {250: "flag=2"}),
    "valid-never": (("valid", "flag"), {}),
    "earlier-column-later-row": (("gyro_dps", "g / d"), {280: "d=0"}),
}


@pytest.mark.parametrize("name", list(MAPS))
def test_column_map_refusals_on_disk(name: str, tmp_path: Path, small_blocks: int) -> None:
    mapped, edits = MAPS[name]
    lines = [f"{0.1 * i:.1f},{20.0 + 0.01 * i:.4f},10,{10.0 + 1e-4 * (i % 7):.6f},1,"
             f"{0 if name == 'valid-never' else 1},1" for i in range(300)]
    for row, what in edits.items():
        cells = lines[row].split(",")
        key, v = what.split("=")
        cells[{"flag": 5, "d": 6}[key]] = v
        lines[row] = ",".join(cells)
    body = text(lines, "time_s,temp_c,table_rate_dps,g,gyro_dps_x,flag,d")
    if name == "earlier-column-later-row":  # and a bad valid at an earlier row, mapped after
        body = body.replace("\n1.0,20.1000,10,10.000300,1,1,1", "\n1.0,20.1000,10,10.000300,1,3,1")
    p = tmp_path / "log.csv"
    p.write_text(body)
    dialect = Dialect(columns=((mapped[0], mapped[1]), ("valid", "flag"))
                      if mapped[0] != "valid" else (mapped,))
    whole, disk = _read(lambda: read_log(p, dialect)), _read(lambda: read_log_on_disk(p, dialect))
    assert isinstance(whole, str), whole
    assert disk == whole


def test_parquet_on_disk_as_in_memory(tmp_path: Path, small_blocks: int) -> None:
    p = tmp_path / "log.csv"
    p.write_text(text(rows(300)))
    pq = tmp_path / "log.parquet"
    write_log(pq, read_log(p))
    same_log(read_log_on_disk(pq), read_log(pq))
    bad = read_log(p)
    bad.temp_c[201] = 130.0
    write_log(pq, bad)
    assert _read(lambda: read_log_on_disk(pq)) == _read(lambda: read_log(pq))


def test_a_log_read_in_blocks_then_held_is_read_logs(tmp_path: Path) -> None:
    from fogsf.logs.read.stream_read import in_memory

    p = tmp_path / "log.csv"
    p.write_text(text(rows(300)).replace("time_s,", "time_s,").replace(",10,", ",10,", 1))
    held = in_memory(read_log_on_disk(p, Dialect(columns=(("valid", "temp_c > 20.5"),))))
    whole = read_log(p, Dialect(columns=(("valid", "temp_c > 20.5"),)))
    assert all(isinstance(v, np.ndarray) for v in held.columns().values())
    same_log(held, whole)


QUOTED = {f"quoted-{k}": _quoted(BAD[k][0]) for k in SCANNED if ";" not in BAD[k][0]}
QUOTED["delimiter-in-quotes"] = BAD["delimiter-in-quotes"][0]
QUOTED["bad-quoting"] = BAD["bad-quoting"][0]
QUOTED["bad-quoting-after-a-bad-cell"] = _quoted(BAD["letter"][0]).replace('"10"\n', '"10"x\n', 30)


@pytest.mark.parametrize("name", list(QUOTED))
def test_a_quoted_file_is_refused_without_the_general_path(name: str, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    """Quoted cells: the scan checks every row's quoting, then the cells, row by row (the
    general path, which holds the whole text, is not used), and names the general path's
    line."""
    from fogsf.logs import logio

    _, general = _both(tmp_path, QUOTED[name], Dialect())
    assert isinstance(general, str), general

    def no_general(*_: object, **__: object) -> None:
        raise AssertionError("the general path was used")

    monkeypatch.setattr(logio, "parse_log", no_general)
    assert _read(lambda: read_log_on_disk(tmp_path / "log.csv")) == general
    assert _read(lambda: read_log(tmp_path / "log.csv")) == general


def test_a_full_disk_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    from fogsf.errors import UserError

    p = tmp_path / "log.csv"
    p.write_text(text(rows(300)))
    spill = columns.Spill(str(tmp_path))
    f = spill.file("x", np.float64)

    class Full:
        def seek(self, *_: object) -> None:
            pass

        def write(self, *_: object) -> None:
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(f, "_file", Full())
    with pytest.raises(UserError, match=r"No space left on device; .*set TMPDIR"):
        f.append(np.zeros(3))
    monkeypatch.undo()
    spill.close()
    assert not spill.dir.exists()
