"""The calibration block on the cores under QEMU: the generated C's golden vectors bit for
bit from a model read out of a block at a flash address (M4F, M3, M0), and the example
firmware/examples/block2 (one image, two gyros, each unit's blocks loaded into its sectors)
built by CMake and run with the blocks of two units."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsf.bindings.firmware import arm_tools_missing, qemu_cmd, run_cmd
from fogsf.export.block import write_block
from fogsf.models import reference, samples
from fogsf.models.stream_flags import FLAG_TEMP_INVALID

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "fixtures" / "small_model"
RATE_FIXTURE = ROOT / "tests" / "fixtures" / "rate_model"  # with the rate part (R 8, Q 3)
EXAMPLE = ROOT / "firmware" / "examples" / "block2"
TOOLCHAIN = ROOT / "firmware" / "cmake" / "cortex-m4f.cmake"
SAMPLES = 1200  # BLOCK2_SAMPLES of main.c
SECTORS = (0x00300000, 0x00310000)

need_tools = pytest.mark.skipif(
    arm_tools_missing() is not None or shutil.which("cmake") is None,
    reason=f"needs cmake and the Cortex-M tools: {arm_tools_missing() or 'cmake missing'}")


@pytest.mark.slow
@need_tools
# the rate part's block on the hard-float M4F and the soft-float M0 only, to save a run: the
# M3 reads the small fixture's block, and `make firmware-cores` steps the rate C on all three
@pytest.mark.parametrize("fixture,cores", [(FIXTURE, "cortex-m4f,cortex-m3,cortex-m0"),
                                           (RATE_FIXTURE, "cortex-m4f,cortex-m0")],
                         ids=["small", "rate"])
def test_block_golden_vectors_on_every_core(fixture: Path, cores: str, tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "fogsf.bindings.cores", str(fixture),
                           "--target", "block", "--cores", cores, "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    for core, addr in (("Cortex-M4F", "0x00300000"), ("Cortex-M3", "0x00300000"),
                       ("Cortex-M0", "0x00030000")):
        if core.lower() not in cores:
            continue
        line = next(ln for ln in lines if ln.strip().startswith(core))
        assert f"block at {addr}: PASS: 12000 outputs bit-exact" in line
    assert lines[-1].startswith(f"PASS on {cores.replace(',', ', ')}")


def unit_models(unit: int) -> list:
    """Two gyros' models of one unit (other shapes: the image holds no model)."""
    return [samples.random_model(3, 4, 1, 16, 10, seed=200 + 2 * unit),
            samples.random_model(2, 4, 1, 16, 10, seed=201 + 2 * unit, poly_head=True,
                                 bias_head=True, plays=(((0.2, 0.5, 0.3), 2.0),))]


def gyro_inputs(g: int) -> tuple[np.ndarray, np.ndarray]:
    """The inputs main.c computes, op for op in float32."""
    i = np.arange(SAMPLES)
    temp = ((np.float32(-30.0) + i.astype(np.float32) * np.float32(0.0625))
            + np.float32(g) * np.float32(0.25)).astype(np.float32)
    temp[i % 257 == 11 + g] = np.float32(np.nan)
    gyro = (np.float32(20.0) + i.astype(np.float32) * np.float32(0.002)).astype(np.float32)
    return temp, gyro


def parse(text: str) -> dict[str, np.ndarray]:
    rows: dict[str, list[list[int]]] = {"a": [], "b": []}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 6 and parts[0] in rows:
            assert int(parts[1], 16) == len(rows[parts[0]]), line
            rows[parts[0]].append([int(p, 16) for p in parts[2:]])
    return {g: np.array(r, dtype=np.uint64) for g, r in rows.items()}


def run_image(elf: Path, blocks: list[Path]) -> subprocess.CompletedProcess:
    loaders = [arg for b, addr in zip(blocks, SECTORS, strict=True)
               for arg in ("-device", f"loader,file={b},addr=0x{addr:08x},force-raw=on")]
    return subprocess.run(qemu_cmd(elf, *loaders), capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@need_tools
def test_one_image_two_blocks_for_each_unit(tmp_path: Path) -> None:
    build = tmp_path / "build"
    run_cmd(["cmake", "-S", str(EXAMPLE), "-B", str(build),
             f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}", "-DCMAKE_BUILD_TYPE=Release"],
            "cmake configure (block2)")
    run_cmd(["cmake", "--build", str(build)], "cmake build (block2)")
    elf = build / "block2.elf"
    for unit in (0, 1):
        models = unit_models(unit)
        blocks = [write_block(m, tmp_path / f"unit{unit}_{g}.bin")
                  for g, m in zip("ab", models, strict=True)]
        proc = run_image(elf, blocks)
        text = proc.stdout + proc.stderr
        assert proc.returncode == 0 and "block2 done" in text, text[-2000:]
        got = parse(text)
        for g, (name, model) in enumerate(zip("ab", models, strict=True)):
            assert f"gyro {name}: model {model.model_id}" in text
            temp, gyro = gyro_inputs(g)
            ref = reference.replay(model, temp, gyro)
            assert got[name].shape == (SAMPLES, 4)
            np.testing.assert_array_equal(got[name][:, 0], ref.sf_ppm.view(np.uint32))
            np.testing.assert_array_equal(got[name][:, 1],
                                          ref.corrected_dps.astype(np.float32).view(np.uint32))
            bias = ref.bias_dph if ref.bias_dph is not None else np.zeros(SAMPLES, np.float32)
            np.testing.assert_array_equal(got[name][:, 2],
                                          np.asarray(bias, np.float32).view(np.uint32))
            np.testing.assert_array_equal(got[name][:, 3], ref.flags)
            assert (ref.flags & FLAG_TEMP_INVALID).any()
    # gyro b's sector left empty: refused with its reason (3, bad magic), the image stops
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"\0" * 256)
    proc = run_image(elf, [tmp_path / "unit0_a.bin", empty])
    assert proc.returncode != 0 and "block2 FAIL b 03" in proc.stdout + proc.stderr
