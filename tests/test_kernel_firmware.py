"""Golden vectors: host driver (plain, ASan+UBSan) and the Cortex-M4F image under QEMU give
the host kernel's bits; the strict build flags hold for gcc and clang."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

from fogsf.bindings.firmware import (
    arm_size,
    arm_tools_missing,
    build_arm,
    build_host_driver,
    golden_inputs,
    run_host_driver,
    run_qemu,
    write_golden,
)
from fogsf.bindings.kernel import C_DIR, STRICT, Kernel, build_kernel, max_defines
from fogsf.export.header import write_model
from fogsf.models import reference, samples
from fogsf.models import stream as st

FIXTURE = "tests/fixtures/small_model"


@pytest.fixture(scope="module")
def golden(tmp_path_factory):
    """(model, host build, golden folder) for the committed fixture model."""
    root = tmp_path_factory.mktemp("fw")
    model = st.StreamModel.load(FIXTURE)
    build = build_kernel(model, root=root / "host")
    golden_dir = root / "golden"
    write_golden(model, Kernel(model, build), golden_dir)
    return model, build, golden_dir, root


def test_fixture_is_the_documented_random_model() -> None:
    want = samples.random_model(filters=3, n_features=4, layers=1, hidden=16, decimation=10,
                           seed=2026)
    assert st.StreamModel.load(FIXTURE).model_id == want.model_id


@pytest.mark.slow
@pytest.mark.parametrize("sanitize", [False, True], ids=["plain", "asan+ubsan"])
def test_host_driver_passes_golden_vectors(golden, sanitize) -> None:
    model, build, golden_dir, root = golden
    exe = build_host_driver(build, golden_dir, root / f"drv{int(sanitize)}", sanitize=sanitize)
    ok, out = run_host_driver(exe)
    assert ok and "PASS" in out, out
    assert "runtime error" not in out and "AddressSanitizer" not in out, out


def test_golden_check_detects_a_wrong_bit(golden, tmp_path) -> None:
    """The check can fail: flip one expected bit and it must say FAIL with the index."""
    model, build, golden_dir, _ = golden
    text = (golden_dir / "golden_vectors.h").read_text()
    start = text.index("golden_sf_bits")
    pos = text.index("0x", text.index("{", start)) + 9  # last hex digit of sample 0's sf
    digit = text[pos]
    flipped = text[:pos] + ("1" if digit != "1" else "0") + text[pos + 1:]
    bad_dir = tmp_path / "bad"
    bad_dir.mkdir()
    (bad_dir / "golden_vectors.h").write_text(flipped)
    ok, out = run_host_driver(build_host_driver(build, bad_dir, tmp_path / "drv"))
    assert not ok and "mismatch step sample 0:" in out and "FAIL: 2 mismatching" in out, out


@pytest.mark.slow
@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("size", [(0, 1, 1, 1, 1, 0, False), (3, 4, 2, 9, 50, 600, False),
                                  (0, 1, 1, 1, 1, 0, True), (2, 5, 1, 3, 10, 600, True)])
def test_strict_flags_compile_every_shape(cc, size, tmp_path) -> None:
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} not installed")
    k, f, layers, hidden, d, stuck, poly = size
    model = samples.random_model(k, f, layers, hidden, d, seed=1, stuck_samples=stuck,
                            poly_head=poly)
    write_model(model, tmp_path, "shape")
    for src in (C_DIR / "fogsf.c", C_DIR / "fogsf_cell.c", tmp_path / "shape.c"):
        proc = subprocess.run([cc, *STRICT, "-Wvla", "-O2", *max_defines(model), "-I",
                               str(tmp_path), "-I", str(C_DIR), "-c", str(src), "-o",
                               str(tmp_path / f"{src.name}.o")],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_a_model_larger_than_the_state_does_not_compile(tmp_path) -> None:
    """NAME.c refuses FOGSF_MAX_* smaller than its model (the state could not hold it)."""
    model = samples.random_model(2, 4, 1, 32, 10, seed=1)
    write_model(model, tmp_path, "big")
    cmd = [*STRICT, "-I", str(tmp_path), "-I", str(C_DIR), "-c", str(tmp_path / "big.c"),
           "-o", str(tmp_path / "big.o")]
    proc = subprocess.run(["gcc", *cmd], capture_output=True, text=True)
    assert proc.returncode != 0 and "big_fits_state" in proc.stderr, proc.stderr
    ok = subprocess.run(["gcc", "-DFOGSF_MAX_HIDDEN=32", *cmd], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr


def test_kernel_objects_need_no_library(golden) -> None:
    """No malloc, no libm, no stdio: the host objects reference only each other (and at most
    memset/memcpy, which a compiler may emit for loops)."""
    _, build, _, _ = golden
    objs = [str(build.directory / "fogsf.o"), str(build.directory / "fogsf_cell.o"),
            str(build.directory / "bound_model.o")]
    out = subprocess.run(["nm", "-u", *objs], capture_output=True, text=True, check=True).stdout
    undefined = {line.split()[-1] for line in out.splitlines() if line.strip().startswith("U")}
    # each other: fogsf.o calls the cell's unit, fogsf_cell.o's fogsf_run calls fogsf_step
    assert undefined <= {"fogsf_lstm_unit", "fogsf_step", "memset", "memcpy"}, undefined


@pytest.mark.skipif(arm_tools_missing() is not None,
                    reason=f"Cortex-M4F check needs the cross tools: {arm_tools_missing()}")
def test_cortex_m4f_under_qemu_gives_the_host_bits(golden) -> None:
    model, build, golden_dir, root = golden
    arm = build_arm(build.directory, golden_dir, root / "m4f", defines=build.defines)
    ok, out = run_qemu(arm.golden_elf)
    assert ok, out
    assert f"model {model.model_id}" in out and "PASS: 12000 outputs bit-exact" in out, out
    golden_text = out
    out = subprocess.run(["arm-none-eabi-nm", "-u", *map(str, arm.kernel_objs)],
                         capture_output=True, text=True, check=True).stdout
    undefined = {line.split()[-1] for line in out.splitlines() if line.strip().startswith("U")}
    defined = subprocess.run(["arm-none-eabi-nm", "--defined-only", *map(str, arm.kernel_objs)],
                             capture_output=True, text=True, check=True).stdout
    undefined -= {line.split()[-1] for line in defined.splitlines() if len(line.split()) == 3}
    assert all(u.startswith("__aeabi_") or u in {"memset", "memcpy"}
               for u in undefined), undefined  # libgcc helpers, nothing else
    # no double anywhere in the kernel (contract fogsf-stream-2): no soft-double helper
    assert not [u for u in undefined
                if re.match(r"__aeabi_(d[a-z]|f2d|i2d|ui2d|l2d|ul2d)", u)], undefined
    size = arm_size(arm, model)
    assert 0 < size.kernel_flash_bytes <= size.flash_bytes
    # the model pointer, then h, c, y, p (one play's slot), 12 scalars (the held outputs,
    # the correction's k and b, counters), 13 of the run-time check (the model's crc32 and
    # sizes, the pass, the fault, the verified outputs), all 4 bytes (z, h_prev and the
    # step's next outputs only in the even-time build): the kernel's own sizeof on the core
    words = 1 + 2 * 16 + 3 + 1 + 12 + 13
    assert size.ram_bytes >= size.state_bytes == 4 * words
    assert f"state {4 * words} bytes" in golden_text, golden_text


@pytest.mark.slow
@pytest.mark.skipif(arm_tools_missing() is not None,
                    reason=f"Cortex-M4F check needs the cross tools: {arm_tools_missing()}")
@pytest.mark.parametrize("poly", [False, True], ids=["plain", "poly-head"])
def test_cortex_m4f_two_layers_no_filters_no_stuck_check(poly, tmp_path) -> None:
    """The other shapes on target: 2 layers, K=0, stuck detection off, a step per sample;
    and the same with the polynomial head (quadratic and cubic terms in z)."""
    model = samples.random_model(0, 3, 2, 12, decimation=1, seed=77, stuck_samples=0,
                            poly_head=poly)
    build = build_kernel(model, root=tmp_path / "host")
    assert ("quad_w, cube_w" in (build.directory / "bound_model.c").read_text()) == poly
    write_golden(model, Kernel(model, build), tmp_path / "golden")
    arm = build_arm(build.directory, tmp_path / "golden", tmp_path / "m4f", defines=build.defines)
    ok, out = run_qemu(arm.golden_elf)
    assert ok and "PASS: 12000 outputs bit-exact" in out, out


@pytest.mark.slow
@pytest.mark.skipif(arm_tools_missing() is not None,
                    reason=f"Cortex-M4F check needs the cross tools: {arm_tools_missing()}")
@pytest.mark.parametrize("k, f, layers, hidden, d, n_in, diag, fdiag", [
    (11, 12, 1, 16, 5, 1, True, True),   # the default model's shape (the lag bank)
    (2, 4, 2, 6, 1, 3, False, False),    # a narrowed input into two layers, the full quadratic
], ids=["lag-bank-form", "narrowed-2-layers"])
def test_cortex_m4f_narrowed_forms(k, f, layers, hidden, d, n_in, diag, fdiag,
                                   tmp_path) -> None:
    """lstm_inputs, quad_diag and feat_diag on target: the golden vectors bit for bit under
    QEMU."""
    model = samples.random_model(k, f, layers, hidden, decimation=d, seed=78, poly_head=True,
                                 lstm_inputs=n_in, quad_diag=diag, feat_diag=fdiag)
    build = build_kernel(model, root=tmp_path / "host")
    text = (build.directory / "bound_model.c").read_text()
    assert f"static const float lstm0_w[{4 * hidden * n_in}]" in text
    assert (f"static const float quad_w[{f}]" in text) == diag
    assert (f"static const float feat_w[{f}]" in text) == fdiag
    kernel = Kernel(model, build)
    temp, gyro = golden_inputs(model)  # the golden vectors' inputs: numpy = host first
    corrected, sf, flags = kernel.run(temp, gyro)
    ref = reference.replay(model, temp, gyro)
    assert sf.tobytes() == ref.sf_ppm.tobytes() and np.ptp(ref.sf_ppm) > 1.0
    assert corrected.tobytes() == ref.corrected_dps.tobytes()
    assert np.array_equal(flags, ref.flags)
    write_golden(model, kernel, tmp_path / "golden")
    exe = build_host_driver(build, tmp_path / "golden", tmp_path / "asan", sanitize=True)
    ok, out = run_host_driver(exe)
    assert ok and "PASS: 12000 outputs bit-exact" in out, out
    arm = build_arm(build.directory, tmp_path / "golden", tmp_path / "m4f", defines=build.defines)
    ok, out = run_qemu(arm.golden_elf)
    assert ok and f"model {model.model_id}" in out and "PASS: 12000 outputs bit-exact" in out, out
