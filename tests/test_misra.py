"""`make misra` (cppcheck's MISRA C:2012 addon) passes on the kernel and the generated models
of every shape, and fails on a Required finding, a plain int, an unrecorded Advisory rule."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fogsf.bindings import misra

pytestmark = pytest.mark.skipif(shutil.which(misra.CPPCHECK) is None,
                                reason="cppcheck not installed: `make misra` not run "
                                       "(apt-get install cppcheck, or make toolchain)")


def test_the_kernel_and_every_model_shape_pass(tmp_path: Path, capsys) -> None:
    assert misra.main(["--out", str(tmp_path), "--json", str(tmp_path / "misra.json")]) == 0
    out = capsys.readouterr().out
    assert "findings: Mandatory 0, Required 0" in out and out.rstrip().endswith(
        "every Advisory rule recorded in MISRA.md"), out
    for name in misra.shapes():
        assert (tmp_path / "models" / f"{name}.c").is_file()


def test_a_required_finding_fails(tmp_path: Path, capsys) -> None:
    """An `int` used as a boolean condition (Rule 14.4, Required) in an extra file."""
    bad = tmp_path / "bad.c"
    bad.write_text("#include <stdint.h>\nint32_t bad_fn(int32_t x);\n"
                   "int32_t bad_fn(int32_t x)\n{\n    int32_t y = 0;\n"
                   "    if (x) {\n        y = 1;\n    }\n    return y;\n}\n")
    assert misra.main(["--out", str(tmp_path / "run"), str(bad)]) == 1
    out = capsys.readouterr().out
    assert "bad.c:6: Required rule 14.4" in out and out.rstrip().endswith("FAIL"), out


def test_the_rule_table_and_the_record() -> None:
    assert misra.category("9.1") == "Mandatory" and misra.category("10.4") == "Required"
    assert misra.category("12.1") == "Advisory" and misra.category("99.9") == "Required"
    assert misra.category("Dir 4.6") == "Advisory" and misra.category("Dir 1.1") == "Required"
    recorded = misra.recorded_rules()
    assert {"Dir 1.1", "Dir 4.6", "19.2", "12.1"} <= recorded
    assert recorded - {"Dir 1.1"} - {"5.6", "10.4", "10.8", "15.7", "10.1", "14.4"} <= \
        misra.ADVISORY  # the record keeps only Advisory rules (it names the fixed ones too)


def test_a_plain_int_in_the_kernel_is_found(tmp_path: Path) -> None:
    src = tmp_path / "k.c"
    src.write_text('/* int in a comment */\nstatic const char *s = "int";\nstatic int f;\n')
    found = misra.plain_integer_lines([src])
    assert [(f.line, f.rule) for f in found] == [(3, "Dir 4.6")]
