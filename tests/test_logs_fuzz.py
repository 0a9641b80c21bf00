"""Corrupted logs of every format the reader takes (tests/logs_fuzz.py: cells, lines, bytes,
units, clocks, column maps) end in exit 0 or a one-line refusal (exit 2), never a
traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from logs_fuzz import fuzz, make_bases, one_line, run_cli


@pytest.mark.slow
def test_two_hundred_corrupted_logs_exit_0_or_2(tmp_path: Path) -> None:
    counts, bad = fuzz(tmp_path, 200, seed=5)
    assert not bad, "\n\n".join(f"{p}:\n{tb}" for p, tb in bad[:3])
    assert sum(c for (k, rc), c in counts.items() if k != "rule" and rc == 0) > 0  # some read


def test_the_base_logs_read(tmp_path: Path) -> None:
    """The logs the corruptions start from read (so a refusal is the corruption's)."""
    for kind, folder in make_bases(tmp_path).items():
        path = next(p for p in sorted(folder.iterdir()) if p.name != "fogsf-columns.toml")
        rc, err = run_cli(["inspect", str(path), "--window-s", "10"])
        assert rc == 0, (kind, err)


def test_a_traceback_is_caught(monkeypatch) -> None:
    """The harness can fail: an exception out of a reader is reported, not swallowed."""
    import fogsf.logs.read.stream_read as sr

    def broken(*a: object, **kw: object) -> None:
        raise ZeroDivisionError("planted")

    monkeypatch.setattr(sr, "read_log_on_disk", broken)
    rc, text = run_cli(["inspect", "x.csv"])
    assert rc is None and "ZeroDivisionError" in text
    assert not one_line("Traceback (most recent call last):\nfogsf inspect: error: x")
