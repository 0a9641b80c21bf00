"""The golden vectors on Cortex-M4F, M3 and M0 under QEMU (make firmware-cores), and the
call-graph stack walk of a linked image."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from fogsf.bindings.cores import main
from fogsf.bindings.firmware import arm_tools_missing
from fogsf.bindings.stack import parse_image, walk

LISTING = """
00000100 <leaf>:
 100:	push	{r4, r5, lr}
 102:	vpush	{d8-d9}
 106:	sub	sp, #16
 108:	pop	{r4, r5, pc}

00000110 <mid>:
 110:	stmdb	sp!, {r4, r5, r6, r7, r8, lr}
 114:	sub.w	sp, sp, #264	@ 0x108
 118:	bl	100 <leaf>
 11c:	b.n	118 <mid+0x8>
 11e:	b.w	140 <__aeabi_fmul>

00000140 <__aeabi_fmul>:
 140:	push	{r4, lr}
 142:	bx	lr

00000150 <top>:
 150:	push	{lr}
 152:	bl	110 <mid>
 156:	bl	160 <loop>

00000160 <loop>:
 160:	push	{r3, lr}
 162:	bl	160 <loop>
"""


def test_the_walk_sums_frames_along_the_deepest_path() -> None:
    funcs = parse_image(LISTING)
    assert funcs["leaf"].frame == 12 + 16 + 16  # three registers, two d registers, 16
    assert funcs["mid"].frame == 24 + 264 and funcs["mid"].calls == {"leaf", "__aeabi_fmul"}
    bound = walk(funcs, ("mid",))
    assert bound.bytes == 24 + 264 + 44 and bound.path == ["mid", "leaf"]
    assert not bound.unbounded
    rec = walk(funcs, ("top",))
    assert "loop" in rec.unbounded  # recursion has no bound


@pytest.mark.slow
@pytest.mark.skipif(arm_tools_missing() is not None, reason=f"{arm_tools_missing()}")
def test_make_firmware_cores_passes_on_every_core(tmp_path, capsys) -> None:
    """Every core and each toolchain of the default set: arm-none-eabi-gcc with the strict
    flags and in its GNU default (-ffp-contract=fast), clang with its defaults and with
    -ffp-contract=fast: the golden vectors bit for bit and the self-test 0 (the kernel's
    pragmas hold the bits whatever those flags say). The even-time build on the M4F and the
    M0 with the strict flags and the two contracting ones (`make firmware-cores` runs it on
    every core and toolchain)."""
    clang = shutil.which("clang") is not None
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path), "--builds",
                 "default"]) == 0
    even = ["gcc-c99", "gcc-gnu", *(["clang-contract-fast"] if clang else [])]
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path), "--builds",
                 "even-time", "--cores", "cortex-m4f,cortex-m0", "--toolchains",
                 ",".join(even)]) == 0
    out = capsys.readouterr().out
    for label in ("Cortex-M4F (FPv4-SP hard float) under qemu-system-arm -M mps2-an386: PASS",
                  "Cortex-M3 (soft float) under qemu-system-arm -M mps2-an385: PASS",
                  "Cortex-M0 (soft float) under qemu-system-arm -M microbit: PASS"):
        assert label in out, out
    runs = (4 if clang else 2) * 3 + len(even) * 2  # toolchains x cores, for each build
    assert out.count("PASS: 12000 outputs bit-exact") == runs, out
    assert out.count("selftest 0 (the reference's bits)") == runs, out
    assert "toolchain gcc-gnu: arm-none-eabi-gcc's GNU default" in out, out
    assert "build: even-time (-DFOGSF_EVEN_TIME=1)" in out, out
    assert "__aeabi_" in out  # the M0's deepest chain runs into libgcc's soft float
    # the strict build's instructions per sample, a line a core and build
    counts = re.findall(r"instructions per sample: worst (\d+), mean (\d+) .*: worst (\d+)\)",
                        out)
    assert len(counts) == 3 + 2, out
    assert all(int(w) > int(m) > 0 and int(w) >= int(p) > 0 for w, m, p in counts), counts


def test_sample_counts_take_the_worst_the_steady_mean_and_the_plain_worst(monkeypatch) -> None:
    """Samples 0, D and 2D start a model step: the worst is over all, the mean over samples
    D+1 .. 2D, the plain worst over those that start no step."""
    import fogsf.bindings.icount as icount
    d = 4
    counts = [900, 50, 60, 70, 1000, 10, 20, 30, 800]  # 2D + 1 samples
    monkeypatch.setattr(icount, "counts_of", lambda elf, dec, core: counts)
    c = icount.sample_counts(Path("bench.elf"), d)
    assert (c.worst, c.non_step_worst) == (1000, 70)
    assert c.mean == (10 + 20 + 30 + 800) / 4
    assert c.worst_over_mean == 1000 / c.mean


@pytest.mark.skipif(arm_tools_missing() is not None, reason=f"{arm_tools_missing()}")
def test_a_build_with_other_bits_fails_its_golden_vectors(tmp_path, monkeypatch,
                                                          capsys) -> None:
    """The check can fail: an M4F image whose kernel computes otherwise (here the power-on
    rule's plausible range moved to 0..125 C, so the golden log's cold start waits) FAILs on
    its mismatches while its self-test (which starts at 15 C) still passes."""
    import fogsf.bindings.cores as cores
    strict = cores.TOOLCHAINS["gcc-c99"]
    monkeypatch.setitem(cores.TOOLCHAINS, "gcc-c99", cores.Toolchain(
        strict.name, strict.cc, (*strict.flags, "-DFOGSF_TEMP_PLAUSIBLE_MIN_C=0.0f"),
        strict.label))
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path), "--cores",
                 "cortex-m4f", "--builds", "default", "--toolchains", "gcc-c99"]) == 1
    out = capsys.readouterr().out
    assert ": FAIL: " in out and "mismatch" in out and "selftest 0" in out, out


@pytest.mark.skipif(arm_tools_missing() is not None or shutil.which("clang") is None,
                    reason="needs the cross tools and clang")
def test_value_changing_flags_are_refused_or_caught(tmp_path, capsys) -> None:
    """gcc -ffast-math stops at fogsf_fp.h's #error; clang -freciprocal-math, which no macro
    announces and clang 14 has no pragma against on ARM, compiles, and the M4F image's
    self-test fails: its model part and its float-rule probes, 2 | 8 (FOGSF_SELFTEST_AT_INIT
    would refuse the model at init)."""
    assert main(["tests/fixtures/small_model", "--out", str(tmp_path), "--cores",
                 "cortex-m4f", "--builds", "default", "--toolchains",
                 "gcc-fast-math,clang-reciprocal-math"]) == 0
    out = capsys.readouterr().out
    assert "REFUSED to compile: fogsf: built with -ffast-math" in out, out
    assert "mps2-an386: CAUGHT:" in out and "selftest 10 (FAIL" in out, out
