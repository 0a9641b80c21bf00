"""The fast reader (pyarrow's CSV reader) against the general path: the same log or the same
one-line refusal, naming the same line, for every dialect and every broken file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from fogsf.logs.chamber_log import LogError
from fogsf.logs.logio import _read_plain, parse_log, read_log
from fogsf.logs.read.arrow_csv import NotFast, read_numbers
from fogsf.logs.read.dialect import Dialect

HEADER = "time_s,temp_c,table_rate_dps,gyro_dps"


def rows(n: int = 60) -> list[str]:
    return [f"{0.1 * i:.1f},{20.0 + 0.01 * i:.4f},10,{10.0 + 1e-4 * (i % 7):.6f}"
            for i in range(n)]


def text(lines: list[str], header: str = HEADER) -> str:
    return "\n".join([header, *lines]) + "\n"


def _quoted(t: str) -> str:
    return "\n".join(",".join(f'"{c}"' for c in line.split(",")) if line else line
                     for line in t.split("\n"))


def _decimal_comma(t: str) -> str:
    return t.replace(",", ";").replace(".", ",")


# name -> (file text, dialect): each is read by the fast path
GOOD: dict[str, tuple[Callable[[str], str], Dialect]] = {
    "plain": (lambda t: t, Dialect()),
    "semicolon": (lambda t: t.replace(",", ";"), Dialect()),
    "tab": (lambda t: t.replace(",", "\t"), Dialect()),
    "crlf": (lambda t: t.replace("\n", "\r\n"), Dialect()),
    "bom": (lambda t: "\ufeff" + t, Dialect()),
    "quoted": (_quoted, Dialect()),
    "decimal-comma": (_decimal_comma, Dialect(decimal_comma=True)),
    "blanks-in-cells": (lambda t: t.replace(",", ", "), Dialect()),
    "blank-lines-at-end": (lambda t: t + "\n\n", Dialect()),
    "no-last-newline": (lambda t: t.rstrip("\n"), Dialect()),
    "renamed": (lambda t: t.replace("gyro_dps", "omega", 1),
                Dialect(columns=(("gyro_dps", "omega * 2"),))),
}


def _both(tmp_path: Path, body: str, dialect: Dialect) -> tuple[object, object]:
    """(read_log of the file, parse_log of its text): a ChamberLog or the LogError's text."""
    p = tmp_path / "log.csv"
    p.write_bytes(body.encode("utf-8"))

    def attempt(f: Callable[[], object]) -> object:
        try:
            return f()
        except LogError as e:
            return str(e)

    general_text = body.replace("\r\n", "\n")  # as open() gives it to parse_log
    return (attempt(lambda: read_log(p, dialect)),
            attempt(lambda: parse_log(general_text, str(p), dialect)))


@pytest.mark.parametrize("name", list(GOOD))
def test_fast_path_reads_every_dialect_as_the_general_path(name: str, tmp_path: Path) -> None:
    rewrite, dialect = GOOD[name]
    body = rewrite(text(rows()))
    fast, general = _both(tmp_path, body, dialect)
    assert not isinstance(fast, str), fast
    assert _read_plain(tmp_path / "log.csv", dialect) is not None  # pyarrow read it
    for col, v in general.columns().items():
        assert np.array_equal(fast.columns()[col], v), col
    assert fast.read_notes == general.read_notes
    assert fast.nominal_dt_s == general.nominal_dt_s


def _with(line_no: int, new: str) -> str:
    """The good log with its line `line_no` (1: the header) replaced."""
    lines = text(rows()).split("\n")
    lines[line_no - 1] = new
    return "\n".join(lines)


BAD = {  # name -> (file text, dialect, the refusal's start)
    "letter": (_with(7, "0.6,20.06,10,abc"), Dialect(), "line 7: non-numeric cell"),
    "empty-cell": (_with(9, "0.8,,10,10"), Dialect(), "line 9: non-numeric cell"),
    "short-row": (_with(5, "0.4,20.04,10"), Dialect(), "line 5: wrong number of cells"),
    "long-row": (_with(5, "0.4,20.04,10,10,1"), Dialect(), "line 5: wrong number of cells"),
    "blank-line-inside": (_with(20, ""), Dialect(), "line 20: wrong number of cells"),
    "nan": (_with(11, "1.0,20.1,10,nan"), Dialect(), "line 11: non-finite cell"),
    "inf": (_with(11, "1.0,inf,10,10"), Dialect(), "line 11: non-finite cell"),
    "overflow": (_with(11, "1.0,20.1,10,1e400"), Dialect(), "line 11: non-finite cell"),
    "quoted-data": (_with(13, '1.1,20.11,10,"10"'), Dialect(), None),  # read, not refused
    "time-back": (_with(31, "2.0,20.3,10,10"), Dialect(), "line 31: time not increasing"),
    "too-hot": (_with(40, "3.8,120,10,10"), Dialect(), "line 40: temperature out of range"),
    "delimiter-in-quotes": (_quoted(_with(15, "1.4,20.14,10,10,5")).replace('"10","5"',
                                                                             '"10,5"'),
                            Dialect(), "line 15: delimiter inside a quoted cell"),
    "bad-quoting": (_quoted(_with(15, '1.4,20.14,10,10')).replace('"10"\n', '"10"x\n', 1),
                    Dialect(), "line 15: bad quoting"),
    "dot-in-decimal-comma": (_decimal_comma(text(rows())).replace("0,2;", "0.2;", 1),
                             Dialect(decimal_comma=True), None),  # read, not refused
    "decimal-comma-cells": (_decimal_comma(_with(9, "0.8;20.08;10;10.5")),
                            Dialect(), "line 2: non-numeric cell"),
    "missing-column": (text(rows(), "time_s,temp_c,table_rate_dps,gyro"), Dialect(),
                       "line 1: missing required column"),
    "header-only": (text([]), Dialect(), "line 1: empty file"),
    "underscore-then-letter": (_with(40, "3.8,20.38,10,x").replace(",10,10.0000", ",10,1_0.0",
                                                                   1), Dialect(),
                               "line 40: non-numeric cell"),
    "underscore": (_with(9, "0.7,20.07,10,1_000"), Dialect(), "unreadable"),
    "nan-then-letter": (_with(40, "3.8,20.38,10,x").replace("0.6,20.0600,10,", "0.6,nan,10,"),
                        Dialect(), "line 40: non-numeric cell"),
    "blank-then-nan": (_with(11, "1.0,20.1,10,nan").replace("\n0.5,", "\n\n0.5,"),
                       Dialect(), "line 7: wrong number of cells"),
    "blank-lines-at-end-and-nan": (_with(11, "1.0,20.1,10,nan") + "\n \n\n", Dialect(),
                                   "line 11: non-finite cell"),
}

# the refusals the line scan gives (unquoted files whose header is good; a cell that float()
# reads and numpy does not, 1_000, leaves the file to the general path)
SCANNED = [k for k in BAD if BAD[k][2] and BAD[k][2].startswith("line ")
           and not BAD[k][2].startswith("line 1:") and '"' not in BAD[k][0]
           and "_0" not in BAD[k][0]]


@pytest.mark.parametrize("name", list(BAD))
def test_fast_path_refuses_as_the_general_path(name: str, tmp_path: Path) -> None:
    body, dialect, start = BAD[name]
    fast, general = _both(tmp_path, body, dialect)
    if start is None:
        assert not isinstance(fast, str) and not isinstance(general, str)
        assert np.array_equal(fast.time_s, general.time_s)
        return
    assert isinstance(fast, str) and fast == general, (fast, general)
    assert fast.startswith(f"{tmp_path / 'log.csv'}: {start}"), fast
    assert "\n" not in fast


def test_read_numbers_wants_the_line_count(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text(text(rows(10)))
    assert read_numbers(p, 10, ",", 4).shape == (10, 4)
    assert read_numbers(p, 10, ",", 4).flags.f_contiguous  # each column contiguous
    for wrong in (9, 11):
        with pytest.raises(NotFast):
            read_numbers(p, wrong, ",", 4)


def test_fast_path_reads_across_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                       ) -> None:
    """Many small blocks (as a long log is read): the same numbers, a bad cell still named."""
    import fogsf.logs.read.arrow_csv as arrow_csv

    monkeypatch.setattr(arrow_csv, "BLOCK_BYTES", 256)
    body = text(rows(3000))
    fast, general = _both(tmp_path, body, Dialect())
    assert np.array_equal(fast.gyro_dps, general.gyro_dps)
    lines = body.split("\n")
    lines[2500] = lines[2500].replace(",10,", ",x,")
    fast, general = _both(tmp_path, "\n".join(lines), Dialect())
    assert fast == general and "line 2501: non-numeric cell" in fast


@pytest.mark.parametrize("name", SCANNED)
def test_a_bad_row_is_named_without_the_general_path(name: str, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The line scan names the bad row reading line by line: the general path (which holds
    the whole text) is not needed, and the refusal is the general path's."""
    from fogsf.logs import logio

    body, dialect, start = BAD[name]
    _, general = _both(tmp_path, body, dialect)

    def no_general(*_: object, **__: object) -> None:
        raise AssertionError("the general path was used")

    monkeypatch.setattr(logio, "parse_log", no_general)
    with pytest.raises(LogError) as ei:
        read_log(tmp_path / "log.csv", dialect)
    assert str(ei.value) == general


def test_not_utf8_is_refused_as_such_whatever_comes_first(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    lines = text(rows()).split("\n")
    lines[5] = lines[5].replace(",10,", ",x,")  # a bad cell first, then a byte not UTF-8
    p.write_bytes("\n".join(lines).encode() + b"0.9,20,10,\xff\n")
    with pytest.raises(LogError, match=r"log.csv: cannot read: not UTF-8 text"):
        read_log(p)


def test_rows_read_before_a_bad_block_are_not_parsed_again(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The scan skips the rows pyarrow read (its blank lines still count): a late bad cell
    is named parsing only the rows from the failed block on; a blank line in an early block
    is named before it."""
    import fogsf.logs.read.arrow_csv as arrow_csv
    from fogsf.logs import logio
    from fogsf.logs.read import line_scan

    monkeypatch.setattr(arrow_csv, "BLOCK_BYTES", 512)
    lines = text(rows(3000)).split("\n")
    lines[2800] = lines[2800].replace(",10,", ",x,")
    _, general = _both(tmp_path, "\n".join(lines), Dialect())
    parsed: list[str] = []
    real = line_scan.bad_cell_in

    def counted(line: str, *a: object, **k: object) -> LogError | None:
        parsed.append(line)
        return real(line, *a, **k)

    monkeypatch.setattr(line_scan, "bad_cell_in", counted)
    monkeypatch.setattr(logio, "parse_log", None)  # the general path is not used
    with pytest.raises(LogError) as ei:
        read_log(tmp_path / "log.csv")
    assert str(ei.value) == general and "line 2801: non-numeric cell" in general
    assert 0 < len(parsed) < 100  # the rows of the blocks pyarrow read are skipped
    monkeypatch.undo()
    monkeypatch.setattr(arrow_csv, "BLOCK_BYTES", 512)
    lines.insert(99, "")
    fast, general = _both(tmp_path, "\n".join(lines), Dialect())
    assert fast == general and "line 100: wrong number of cells" in fast
