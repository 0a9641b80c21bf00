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


@pytest.mark.slow
def test_the_kernel_and_every_model_shape_pass(tmp_path: Path, capsys) -> None:
    assert misra.main(["--out", str(tmp_path), "--json", str(tmp_path / "misra.json")]) == 0
    out = capsys.readouterr().out
    assert "findings: Mandatory 0, Required 0" in out and out.rstrip().endswith(
        "every Advisory rule recorded in MISRA.md"), out
    for name in misra.shapes():
        assert (tmp_path / "models" / f"{name}.c").is_file()


@pytest.mark.slow
def test_a_required_finding_fails(tmp_path: Path, capsys, monkeypatch) -> None:
    """An `int` used as a boolean condition (Rule 14.4, Required) in an extra file (one model
    shape beside it: the run over every shape is the test above)."""
    plain = next(iter(misra.shapes().items()))
    monkeypatch.setattr(misra, "shapes", lambda: dict([plain]))
    bad = tmp_path / "bad.c"
    bad.write_text("#include <stdint.h>\nint32_t bad_fn(int32_t x);\n"
                   "int32_t bad_fn(int32_t x)\n{\n    int32_t y = 0;\n"
                   "    if (x) {\n        y = 1;\n    }\n    return y;\n}\n")
    assert misra.main(["--out", str(tmp_path / "run"), str(bad)]) == 1
    out = capsys.readouterr().out
    assert "bad.c:6: Required rule 14.4" in out and out.rstrip().endswith("FAIL"), out


def test_the_gsa_shape_is_the_largest_the_search_can_give() -> None:
    from fogsf.training.net.gsa_search import gsa_space

    for kind in ("paper", "extended"):
        bounds = {p.name: p.high for p in gsa_space(kind)}
        assert (bounds["layers"], bounds["hidden"]) == (misra.GSA_LAYERS, misra.GSA_HIDDEN)
    model = misra.gsa_model()
    assert (model.layers, model.hidden) == (misra.GSA_LAYERS, misra.GSA_HIDDEN)


def test_the_rule_table_and_the_record() -> None:
    assert misra.category("9.1") == "Mandatory" and misra.category("10.4") == "Required"
    assert misra.category("12.1") == "Advisory" and misra.category("99.9") == "Required"
    assert misra.category("Dir 4.6") == "Advisory" and misra.category("Dir 1.1") == "Required"
    recorded = misra.recorded_rules()
    assert {"Dir 1.1", "Dir 4.6", "19.2", "12.1"} <= recorded
    assert recorded - {"Dir 1.1"} <= misra.ADVISORY  # its bullets keep only Advisory rules
    assert len(misra.all_rules()) == 158 + 17  # 158 rules with Amendments 1 and 2, 17 dirs


def test_the_coverage_matrix_lists_every_required_and_mandatory_rule(tmp_path: Path) -> None:
    """MISRA.md's matrix names each Required and Mandatory rule with its category and what
    checks it; a matrix without a row, or with a wrong category, is a `make misra` problem."""
    assert misra.matrix_problems() == []
    text = misra.MISRA_MD.read_text()
    rows = dict((m[1], m[2]) for m in misra.MATRIX_ROW.finditer(text))
    assert rows["8.3"] == "Mandatory" or rows["8.3"] == "Required"
    assert rows["9.1"] == "Mandatory" and "Dir 4.14" in rows and "12.1" not in rows
    bad = tmp_path / "MISRA.md"
    bad.write_text(text.replace("| 17.4 | Mandatory |", "| 17.4 | Required |").replace(
        "| 8.3 | Required |", "| 8.33 | Required |"))
    problems = misra.matrix_problems(bad)
    assert len(problems) == 2 and any("8.3 missing" in p for p in problems), problems


def test_the_own_checks_find_what_the_addon_missed(tmp_path: Path) -> None:
    """Rule 8.3 (a parameter named otherwise than in the header) and Rule 10.8 (a float
    expression cast to int32_t), as the kernel had them before issue 49; the kernel now has
    neither."""
    (tmp_path / "k.h").write_text("float k_expf(float x);\nuint32_t k_other(const float *a,\n"
                                  "                   uint32_t n);\n")
    (tmp_path / "k.c").write_text("/* k_expf(float y) in a comment */\n"
                                  "float k_expf(float x_in)\n{\n"
                                  "    int32_t n = (int32_t)(x_in + 0.5f);\n"
                                  "    return (float)n;\n}\n"
                                  "uint32_t k_other(const float *a, uint32_t n)\n{\n"
                                  "    return (uint32_t)a[0] + n;\n}\n")
    found = misra.parameter_names(tmp_path / "k.h", [tmp_path / "k.c"])
    assert [(f.line, f.rule) for f in found] == [(2, "8.3")] and "x_in" in found[0].message
    casts = misra.composite_casts([tmp_path / "k.c"])
    assert [(f.line, f.rule) for f in casts] == [(4, "10.8")]
    kernel = [misra.C_DIR / n for n in (*misra.SOURCES, *misra.KERNEL_HEADERS)]
    assert misra.parameter_names(misra.C_DIR / "fogsf.h", kernel) == []
    assert misra.composite_casts(kernel) == []


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_the_rule_mapped_compiler_warnings(tmp_path: Path, monkeypatch) -> None:
    """The kernel compiles clean under gcc's warnings that map to rules (both builds); a
    shadowed variable (Rule 5.3) and a switch without default (Rule 16.4) planted in a copy
    are found with their rules."""
    assert misra.compiler_warnings() == []
    src = tmp_path / "c"
    shutil.copytree(misra.C_DIR, src, ignore=shutil.ignore_patterns("test", "arm", "fuzz"))
    cell = src / "fogsf_cell.c"
    cell.write_text(cell.read_text().replace(
        "float fogsf_sigmoidf(float x)\n{\n",
        "float fogsf_sigmoidf(float x)\n{\n    {\n        float x = 1.0f;\n"
        "        switch ((uint32_t)x) {\n        case 0u:\n            break;\n"
        "        }\n    }\n"))
    monkeypatch.setattr(misra, "C_DIR", src)
    rules = {f.rule for f in misra.compiler_warnings()}
    assert {"5.3", "16.4"} <= rules, rules


def test_a_plain_int_in_the_kernel_is_found(tmp_path: Path) -> None:
    src = tmp_path / "k.c"
    src.write_text('/* int in a comment */\nstatic const char *s = "int";\nstatic int f;\n')
    found = misra.plain_integer_lines([src])
    assert [(f.line, f.rule) for f in found] == [(3, "Dir 4.6")]
