"""The block loader's libFuzzer harness builds and runs its seeds and a short fuzz clean
(ASan + UBSan); the 1e7-input run is `make fuzz-block` (docs/firmware.md,
"Calibration block")."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("clang") is None, reason="needs clang with libFuzzer")
def test_block_fuzzer_short_run(tmp_path: Path, capsys) -> None:
    from fogsf.bindings.fuzz import fuzz
    assert fuzz(tmp_path, 3000, per_round=3000, target="block") == 0
    out = capsys.readouterr().out
    assert "seeds" in out and "8 accepted" in out.splitlines()[0]
    assert out.splitlines()[-1].startswith("PASS: ")
