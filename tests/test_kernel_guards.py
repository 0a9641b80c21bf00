"""The kernel's floating-point guards (fogsf_fp.h), its power-on self-test and the model's
integrity check: fast-math builds stop at compile time, fogsf_selftest passes on a good build
and fails on an FMA-contracted one, a flipped byte or a forged version is refused."""

from __future__ import annotations

import platform
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import FLAGS, init, kernel_for, seal, writable_copy

from fogsf.bindings.cores import UNANNOUNCED
from fogsf.bindings.cores import main as cores_main
from fogsf.bindings.firmware import arm_tools_missing, golden_inputs
from fogsf.bindings.kernel import C_DIR, SOURCES, STRICT, Kernel, build_kernel
from fogsf.export.header import model_crc32, write_model
from fogsf.export.selftest import render_selftest
from fogsf.models import samples

COMPILERS = [cc for cc in ("gcc", "clang") if shutil.which(cc)]
FMA_HOST = platform.machine() in ("x86_64", "AMD64") and " fma " in (
    Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").is_file() else "")


@pytest.fixture(scope="module")
def kroot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("guard-kernels")


def compile_kernel(cc: str, extra: list[str], out: Path) -> subprocess.CompletedProcess:
    """Each kernel source compiled with the strict flags plus `extra` (stops at the first
    that fails)."""
    proc = None
    for name in SOURCES:
        proc = subprocess.run([cc, *STRICT, "-O2", *extra, "-I", str(C_DIR), "-c",
                               str(C_DIR / name), "-o", str(out / f"{name}.o")],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            return proc
    assert proc is not None
    return proc


@pytest.mark.slow
@pytest.mark.parametrize("cc", COMPILERS)
@pytest.mark.parametrize("flag, message", [
    ("-ffast-math", "built with -ffast-math"),
    ("-ffinite-math-only", "built with -ffinite-math-only"),
    ("-fno-signed-zeros", "-fno-signed-zeros"),
], ids=["fast-math", "finite-math-only", "no-signed-zeros"])
def test_a_fast_math_build_does_not_compile(cc, flag, message, tmp_path) -> None:
    if flag == "-fno-signed-zeros" and cc == "clang":
        pytest.skip("clang announces -fno-signed-zeros by no macro")
    assert compile_kernel(cc, [], tmp_path).returncode == 0  # the same build without the flag
    proc = compile_kernel(cc, [flag], tmp_path)
    assert proc.returncode != 0 and message in proc.stderr, proc.stderr


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64") or shutil.which("gcc") is None,
                    reason="x87 evaluation (FLT_EVAL_METHOD 2) needs gcc on x86-64")
def test_x87_excess_precision_does_not_compile(tmp_path) -> None:
    proc = compile_kernel("gcc", ["-mfpmath=387"], tmp_path)
    assert proc.returncode != 0 and "FLT_EVAL_METHOD is not 0" in proc.stderr, proc.stderr


def test_each_compiler_gets_the_pragmas_it_honours() -> None:
    """clang: fp reassociate(off), STDC FP_CONTRACT OFF and, on x86 only (clang 14 refuses it
    elsewhere: an error under -Werror), float_control(precise, on) first; gcc, which warns
    that it ignores those: optimize("fp-contract=off"); any other compiler the standard
    pragma. What they hold is measured by the flag matrix below and by `make
    firmware-cores`; the strict flags and CMake still pass -ffp-contract=off."""
    text = re.sub(r"/\*.*?\*/\n", "", (C_DIR / "fogsf_fp.h").read_text(), flags=re.DOTALL)
    assert ("#if defined(__clang__)\n#if defined(__x86_64__) || defined(__i386__)\n"
            "#pragma float_control(precise, on)\n#endif\n#pragma clang fp reassociate(off)\n"
            "#pragma STDC FP_CONTRACT OFF\n#elif defined(__GNUC__)\n"
            '#pragma GCC optimize("fp-contract=off")\n#else\n#pragma STDC FP_CONTRACT OFF\n'
            "#endif\n") in text
    assert "-ffp-contract=off" in STRICT
    cmake = (C_DIR / "CMakeLists.txt").read_text()
    assert "target_compile_options(fogsf PUBLIC -ffp-contract=off)" in cmake
    for name in SOURCES:
        first = re.search(r'#include "([^"]+)"', (C_DIR / name).read_text())
        assert first is not None and first[1] == "fogsf_fp.h", name


def test_the_committed_selftest_is_what_the_reference_gives() -> None:
    """fogsf_selftest.c holds the numpy reference's bits for its model and inputs (regenerate
    with `python -m fogsf.export.selftest` after a change to either)."""
    assert (C_DIR / "fogsf_selftest.c").read_text() == render_selftest()


@pytest.mark.parametrize("cc", COMPILERS)
def test_selftest_passes_on_a_good_build(cc, kroot) -> None:
    kernel = kernel_for(samples.random_model(3, 4, 1, 16, 10, seed=2026), kroot, cc)
    size = kernel.ffi.sizeof("fogsf_state")
    assert kernel.lib.fogsf_selftest(kernel.ffi.new("fogsf_state *"), size) == 0
    assert kernel.lib.fogsf_selftest(kernel.ffi.NULL, size) == 2  # no scratch: the model part
    assert kernel.lib.fogsf_selftest(kernel.ffi.new("fogsf_state *"), size - 4) == 2


SELFTEST_MAIN = """#include <stdio.h>
#include "fogsf.h"
int main(void) { static fogsf_state s; unsigned r = fogsf_selftest(&s, sizeof s);
                 printf("%u\\n", r); return 0; }
"""


# What a caller's flags do to the kernel on an x86-64 host with FMA (gcc 12, clang 14), the
# kernel's sources given only these flags (no -std=c99, no -ffp-contract=off): "refused" (an
# #error of fogsf_fp.h), "pass" (fogsf_selftest 0: the pragmas hold the bits), or the
# self-test's code (compiles, and the self-test catches it: clang ignores every pragma under
# -ffp-contract=fast; float_control(precise, on) does not hold -fno-honor-nans or
# -fno-honor-infinities, whose folded compares the float-rule probes see (8); a program
# linked with -funsafe-math-optimizations starts with denormals flushed to zero,
# crtfastmath.o). firmware/c/MISRA.md, Dir 1.1, states the same.
FLAG_MATRIX = [
    ("gcc", "", "pass"),  # GNU default: -std=gnu17 and -ffp-contract=fast
    ("gcc", "-std=gnu99", "pass"), ("gcc", "-ffp-contract=fast", "pass"),
    ("gcc", "-ffast-math", "refused"), ("gcc", "-Ofast", "refused"),
    ("gcc", "-ffinite-math-only", "refused"), ("gcc", "-freciprocal-math", "refused"),
    ("gcc", "-fno-signed-zeros", "refused"),
    ("gcc", "-fassociative-math -fno-signed-zeros -fno-trapping-math", "refused"),
    ("gcc", "-funsafe-math-optimizations", "refused"),
    ("clang", "", "pass"), ("clang", "-std=gnu99", "pass"),
    ("clang", "-ffast-math", "refused"), ("clang", "-Ofast", "refused"),
    ("clang", "-ffinite-math-only", "refused"), ("clang", "-ffp-model=fast", "refused"),
    ("clang", "-fno-honor-nans", 8), ("clang", "-fno-honor-infinities", 8),
    ("clang", "-freciprocal-math", "pass"), ("clang", "-fno-signed-zeros", "pass"),
    ("clang", "-fassociative-math -fno-signed-zeros -fno-trapping-math", "pass"),
    ("clang", "-fdenormal-fp-math=preserve-sign", "pass"),
    ("clang", "-ffp-contract=fast", 3), ("clang", "-funsafe-math-optimizations", 1),
]


@pytest.mark.skipif(not FMA_HOST, reason="needs an x86-64 CPU with FMA")
@pytest.mark.parametrize("cc, flags, want", FLAG_MATRIX,
                         ids=[f"{c}[{f or 'default'}]" for c, f, _ in FLAG_MATRIX])
def test_every_value_changing_flag_is_refused_held_or_caught(cc, flags, want, tmp_path) -> None:
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} not installed")
    (tmp_path / "main.c").write_text(SELFTEST_MAIN)
    exe = tmp_path / "selftest"
    proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-mfma",
                           *flags.split(), "-I", str(C_DIR), str(tmp_path / "main.c"),
                           *(str(C_DIR / n) for n in SOURCES), "-o", str(exe)],
                          capture_output=True, text=True)
    if want == "refused":
        assert proc.returncode != 0 and "fogsf: built with" in proc.stderr, proc.stderr
        return
    assert proc.returncode == 0, proc.stderr
    got = int(subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout)
    assert got == (0 if want == "pass" else want)


@pytest.mark.slow
@pytest.mark.skipif(arm_tools_missing() is not None or shutil.which("clang") is None,
                    reason="needs the cross tools and clang")
def test_every_unannounced_flag_fails_the_selftest_on_the_cores(tmp_path, capsys) -> None:
    """clang for ARM announces -freciprocal-math, -fno-signed-zeros, -fno-honor-nans,
    -fno-honor-infinities and -fassociative-math by no macro and has no pragma against the
    first four there: each compiles, and fogsf_selftest's float-rule probes
    (FOGSF_SELFTEST_FLOAT_RULES, 8) fail on the hard-float M4F and the soft-float M0
    (-fassociative-math: its -fno-signed-zeros is what the probes see; reassociation itself
    is held by the pragma). The default build only: the probes' code is the same in both."""
    assert cores_main(["tests/fixtures/small_model", "--out", str(tmp_path), "--cores",
                       "cortex-m4f,cortex-m0", "--builds", "default",
                       "--toolchains", ",".join(UNANNOUNCED)]) == 0
    out = capsys.readouterr().out
    runs = re.findall(r"under qemu-system-arm -M \S+: (\w+): .*; selftest (\d+)", out)
    assert len(runs) == 2 * len(UNANNOUNCED), out  # cores x flags
    for verdict, code in runs:
        assert verdict == "CAUGHT" and int(code) & 8, out


# the flags the pragmas hold: the whole kernel's outputs on golden inputs (every bad input
# planted) bit for bit those of the strict build, not only the self-test's
HELD = [("gcc", ("-std=gnu17", "-mfma", "-ffp-contract=fast")),
        ("clang", ("-mfma", "-fno-signed-zeros")), ("clang", ("-fno-honor-nans",)),
        ("clang", ("-fno-honor-infinities",)), ("clang", ("-freciprocal-math",)),
        ("clang", ("-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math"))]


@pytest.mark.skipif(not FMA_HOST, reason="needs an x86-64 CPU with FMA")
@pytest.mark.parametrize("cc, extra", HELD, ids=[f"{c}{list(e)}" for c, e in HELD])
def test_held_flags_give_the_strict_builds_bits(cc, extra, kroot) -> None:
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} not installed")
    model = shape_model(*SHAPES[3])  # a play, both heads: every part of the step
    temp, gyro = golden_inputs(model, n=3000, seed=4)
    want = kernel_for(model, kroot, cc).run_bias(temp, gyro)
    got = Kernel(model, build_kernel(model, root=kroot, cc=cc, extra=extra)).run_bias(temp, gyro)
    for u, v in zip(want, got, strict=True):
        assert u.tobytes() == v.tobytes()


@pytest.mark.parametrize("cc", COMPILERS)
def test_selftest_at_init_refuses_a_build_that_fails_it(cc, tmp_path) -> None:
    """FOGSF_SELFTEST_AT_INIT 1: init runs the self-test on the caller's state; a build whose
    arithmetic gives other bits (here: fogsf_expf perturbed through a macro in a copy of the
    kernel, as a broken soft-float library would) gets SELFTEST_FAILED | MODEL_INVALID from
    init and corrected 0 from every step; the unperturbed build initialises and steps."""
    src = tmp_path / "c"
    shutil.copytree(C_DIR, src, ignore=shutil.ignore_patterns("test", "arm", "fuzz", "*.md",
                                                              "*.txt"))
    cell = src / "fogsf_cell.c"
    cell.write_text(cell.read_text().replace("    e = (p * z + r) + 1.0f;",
                                             "    e = ((p * z + r) + 1.0f) * PERTURB;"))
    model = samples.random_model(1, 1, 1, 1, decimation=2, seed=5)
    write_model(model, tmp_path / "gen", "m1")
    (tmp_path / "main.c").write_text(
        '#include <stdio.h>\n#include "m1.h"\nint main(void)\n{\n    static fogsf_state s;\n'
        "    fogsf_output o;\n    unsigned r = fogsf_init(&m1, &s, sizeof s);\n"
        "    fogsf_step(&m1, &s, 20.0f, 10.0f, &o);\n"
        '    printf("%u %u %g\\n", r, (unsigned)o.flags, (double)o.corrected_dps);\n'
        "    return 0;\n}\n")
    results = {}
    for perturb in ("1.0f", "1.0000001f"):
        exe = tmp_path / f"init{perturb}"
        subprocess.run([cc, *STRICT, "-O2", "-DFOGSF_SELFTEST_AT_INIT=1", f"-DPERTURB={perturb}",
                        "-I", str(src), "-I", str(tmp_path / "gen"), str(tmp_path / "main.c"),
                        *(str(src / n) for n in SOURCES), str(tmp_path / "gen" / "m1.c"),
                        "-o", str(exe)], check=True, capture_output=True, text=True)
        results[perturb] = subprocess.run([str(exe)], capture_output=True, text=True,
                                          check=True).stdout.split()
    invalid, failed = FLAGS["MODEL_INVALID"], FLAGS["SELFTEST_FAILED"]
    assert results["1.0f"][:2] == ["0", "0"] and float(results["1.0f"][2]) != 0.0
    assert results["1.0000001f"] == [str(failed | invalid), str(invalid), "0"]


# (K, F, L, H, D, seed, poly, quad_diag, bias head, plays)
SHAPES = [(3, 4, 1, 16, 10, 2026, False, False, False, ()),
          (2, 4, 1, 8, 10, 5, True, True, True, ()),
          (2, 4, 2, 6, 3, 6, True, False, False, (((0.2, 0.5, 0.3), 2.0),)),
          (1, 3, 1, 4, 5, 7, True, True, True, (((1.0, 0.0), 0.5),))]


def shape_model(k, f, layers, hidden, d, seed, poly, diag, bias, plays):  # noqa: ANN001, ANN201
    return samples.random_model(k, f, layers, hidden, d, seed=seed, poly_head=poly,
                                quad_diag=diag, bias_head=bias, plays=plays)


@pytest.mark.parametrize("shape", SHAPES, ids=["plain", "bias-head", "play", "play-bias"])
def test_every_flipped_byte_of_every_table_is_refused(shape, kroot) -> None:
    """The export's CRCs are zlib's; a copy of the model whose tables are copies passes;
    one flipped bit in any byte of any table, or in a scalar, is refused by
    fogsf_model_check and fogsf_init, and the state it started gives MODEL_INVALID."""
    model = shape_model(*shape)
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    assert (lib.fogsf_model_crc32(kernel.m, 1), lib.fogsf_model_crc32(kernel.m, 0)) == \
        model_crc32(model) == (kernel.m.crc32_sizes, kernel.m.crc32)
    keep: list = []
    m, fields = writable_copy(kernel, keep)
    assert lib.fogsf_model_check(m) == 0
    out = ffi.new("fogsf_output *")
    rng = np.random.default_rng(shape[5])
    for path, arr in fields.items():
        raw = ffi.buffer(arr)
        for byte in sorted({0, len(raw) - 1, *rng.integers(0, len(raw), 3).tolist()}):
            bit = 1 << int(rng.integers(0, 8))
            raw[byte] = bytes([raw[byte][0] ^ bit])
            assert lib.fogsf_model_check(m) == 32, (path, byte)
            state = ffi.new("fogsf_state *")
            assert init(kernel, m, state) == 32, (path, byte)
            lib.fogsf_step(m, state, 20.0, 10.0, out)
            assert (out.corrected_dps, out.flags) == (0.0, 32), (path, byte)
            raw[byte] = bytes([raw[byte][0] ^ bit])
            assert lib.fogsf_model_check(m) == 0, (path, byte)
    for field in ("t_ref_c", "out_scale", "head_b", "stuck_samples"):
        bad = ffi.new("fogsf_model *", m[0])
        raw = ffi.buffer(ffi.addressof(bad[0], field), 4)
        raw[1] = bytes([raw[1][0] ^ 0x10])
        assert lib.fogsf_model_check(bad) == 32, field


@pytest.mark.parametrize("shape", SHAPES[:3], ids=["plain", "bias-head", "play"])
def test_a_forged_version_is_refused(shape, kroot) -> None:
    """Only this kernel's FOGSF_FORMAT_VERSION is accepted, even with CRCs recomputed for
    the forged value: a plain model that claims the bias or play format of before (4, 5)
    is never read as a larger struct (the kernel has no such cast left)."""
    model = shape_model(*shape)
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    assert kernel.m.format_version == 6
    for version in (0, 2, 3, 4, 5, 7, 0xFFFFFFFF):
        forged = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), format_version=version)
        assert lib.fogsf_model_check(forged) == 32, version
        state = ffi.new("fogsf_state *")
        assert init(kernel, forged, state) == 32
        out = ffi.new("fogsf_output *")
        lib.fogsf_step(forged, state, 20.0, 10.0, out)
        assert (out.corrected_dps, out.flags) == (0.0, 32)
    assert lib.fogsf_model_check(seal(lib, ffi.new("fogsf_model *", kernel.m[0]))) == 0
    source = (C_DIR / "fogsf.c").read_text()
    assert not re.search(r"\(const fogsf_\w+ \*\)", source)  # no cast between model structs


def test_a_state_steps_only_the_model_it_was_started_with(kroot) -> None:
    a = kernel_for(samples.random_model(3, 4, 1, 16, 10, seed=2026), kroot)
    ffi, lib = a.ffi, a.lib
    other = seal(lib, ffi.new("fogsf_model *", a.m[0]), t_ref_c=21.0)
    assert lib.fogsf_model_check(other) == 0
    state = a.new_state()
    out = ffi.new("fogsf_output *")
    lib.fogsf_step(other, state, 20.0, 10.0, out)
    assert (out.corrected_dps, out.flags) == (0.0, 32)
    lib.fogsf_step(a.m, state, 20.0, 10.0, out)
    assert out.flags == 0 and out.corrected_dps != 0.0
