"""CMake integration: the `fogsf` library target, fogsf_add_model(), and the three-axis example
firmware/examples/imu3 built for Cortex-M4F (its models re-rated by SAMPLE_RATE_HZ) and run
under QEMU, every output of every axis compared bit for bit with the numpy reference
(fogsf/models/reference.py)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsf.bindings.firmware import arm_tools_missing, qemu_cmd, run_cmd
from fogsf.bindings.kernel import ROOT
from fogsf.models import reference, samples
from fogsf.models import stream as st
from fogsf.models.stream_flags import FLAG_TEMP_INVALID

EXAMPLE = ROOT / "firmware" / "examples" / "imu3"
TOOLCHAIN = ROOT / "firmware" / "cmake" / "cortex-m4f.cmake"
FOGSF = Path(sys.executable).parent / "fogsf"
SAMPLES = 1500  # IMU3_SAMPLES of main.c
AXES = "xyz"
IMU3_RATE_HZ = 20  # the models are trained at 10 Hz (D 10): re-rated to D 20 at configure


def imu3_models() -> list[st.StreamModel]:
    """Three small models with polynomial heads, one per gyro (seeded random weights)."""
    return [samples.random_model(1, 1, 1, 16, decimation=10, seed=100 + a, poly_head=True)
            for a in range(3)]


def imu3_inputs(axis: int) -> tuple[np.ndarray, np.ndarray]:
    """The inputs main.c computes, op for op in float32 / float64."""
    i = np.arange(SAMPLES)
    temp = (np.float32(-40.0) + i.astype(np.float32) * np.float32(0.0625)) \
        + np.float32(axis) * np.float32(0.5)
    temp = temp.astype(np.float32)
    temp[i % 331 == 17 + axis] = np.float32(np.nan)
    gyro = np.float32(10.0 * float(axis + 1)) + i.astype(np.float32) * np.float32(0.001)
    return temp, gyro


def parse(text: str) -> dict[str, np.ndarray]:
    """{axis: [SAMPLES, 3] uint64 rows of (sf bits, corrected bits, flags)}."""
    rows: dict[str, list[list[int]]] = {a: [] for a in AXES}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 5 and parts[0] in rows:
            assert int(parts[1], 16) == len(rows[parts[0]]), line
            rows[parts[0]].append([int(p, 16) for p in parts[2:]])
    return {a: np.array(r, dtype=np.uint64) for a, r in rows.items()}


need_tools = pytest.mark.skipif(
    arm_tools_missing() is not None or shutil.which("cmake") is None,
    reason=f"needs cmake and the Cortex-M4F tools: {arm_tools_missing() or 'cmake missing'}")


@pytest.fixture(scope="module")
def imu3_build(tmp_path_factory):
    root = tmp_path_factory.mktemp("imu3")
    models = imu3_models()
    for axis, model in zip(AXES, models, strict=True):
        model.save(root / "models" / axis)  # as `fogsf train --axis all --out models` writes
    build = root / "build"
    run_cmd(["cmake", "-S", str(EXAMPLE), "-B", str(build), f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}",
             f"-DIMU3_MODELS={root / 'models'}", f"-DFOGSF_EXECUTABLE={FOGSF}",
             f"-DIMU3_SAMPLE_RATE_HZ={IMU3_RATE_HZ}", "-DCMAKE_BUILD_TYPE=Release"],
            "cmake configure (imu3)")
    run_cmd(["cmake", "--build", str(build)], "cmake build (imu3)")
    return [m.at_rate(1.0 / IMU3_RATE_HZ) for m in models], build


@pytest.mark.slow
@need_tools
def test_imu3_under_qemu_is_bit_exact_per_axis(imu3_build) -> None:
    models, build = imu3_build
    proc = subprocess.run(qemu_cmd(build / "imu3.elf"), capture_output=True, text=True,
                          timeout=300)
    text = proc.stdout + proc.stderr  # QEMU's semihosting console
    assert proc.returncode == 0 and "imu3 done" in text, text[-2000:]
    got = parse(text)
    for a, (axis, model) in enumerate(zip(AXES, models, strict=True)):
        temp, gyro = imu3_inputs(a)
        ref = reference.replay(model, temp, gyro)
        assert got[axis].shape == (SAMPLES, 3), axis
        np.testing.assert_array_equal(got[axis][:, 0], ref.sf_ppm.view(np.uint32), err_msg=axis)
        np.testing.assert_array_equal(got[axis][:, 1],
                                      ref.corrected_dps.astype(np.float32).view(np.uint32),
                                      err_msg=axis)
        np.testing.assert_array_equal(got[axis][:, 2], ref.flags, err_msg=axis)
        assert (ref.flags & FLAG_TEMP_INVALID).any()  # the planted NaNs were seen
        assert model.decimation == 20, "SAMPLE_RATE_HZ re-rated the model"
    # three different models: the axes must not all give the same SF
    assert len({got[a][-1, 0] for a in AXES}) == 3


@need_tools
def test_cmake_raises_the_state_to_the_largest_model(imu3_build) -> None:
    _, build = imu3_build
    flags = (build / "CMakeFiles" / "imu3.dir" / "flags.make").read_text()
    assert "-DFOGSF_MAX_HIDDEN=16" in flags and "-DFOGSF_MAX_LAYERS=1" in flags, flags


@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("gcc") is None,
                    reason="needs cmake and gcc")
def test_fogsf_add_model_with_an_exported_dir_on_the_host(tmp_path) -> None:
    """DIR form on the host: a 2x24 model raises FOGSF_MAX_* and the library builds."""
    model = samples.random_model(2, 3, 2, 24, decimation=5, seed=9)
    from fogsf.export.header import write_model
    write_model(model, tmp_path / "app" / "gen", "big_one")  # beside the app: DIR gen
    (tmp_path / "app" / "main.c").write_text(
        '#include "big_one.h"\nint main(void)\n{\n    fogsf_state s;\n'
        "    return (int)fogsf_init(&big_one, &s, sizeof s);\n}\n")
    (tmp_path / "app" / "CMakeLists.txt").write_text(  # as a firmware project finds fogsf
        "cmake_minimum_required(VERSION 3.13)\nproject(app C)\n"
        "add_subdirectory(${FOGSF_DIR} fogsf)\nadd_executable(app main.c)\n"
        "fogsf_add_model(app NAME big_one DIR gen)\n")
    fogsf_dir = subprocess.run([sys.executable, "-c", "import fogsf; print(fogsf.cmake_dir)"],
                               capture_output=True, text=True, check=True).stdout.strip()
    run_cmd(["cmake", "-S", str(tmp_path / "app"), "-B", str(tmp_path / "b"),
             f"-DFOGSF_DIR={fogsf_dir}"], "cmake")
    run_cmd(["cmake", "--build", str(tmp_path / "b")], "cmake build")
    assert subprocess.run([str(tmp_path / "b" / "app")]).returncode == 0
    bad = tmp_path / "app" / "CMakeLists.txt"
    bad.write_text(bad.read_text().replace("DIR gen", "DIR /nonexistent"))
    proc = subprocess.run(["cmake", "-S", str(tmp_path / "app"), "-B", str(tmp_path / "c"),
                           f"-DFOGSF_DIR={fogsf_dir}"], capture_output=True, text=True)
    assert proc.returncode != 0 and "no big_one.h/.c" in proc.stderr, proc.stderr


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("gcc") is None,
                    reason="needs cmake and gcc")
def test_fogsf_add_model_sample_rate_is_passed_to_export(tmp_path) -> None:
    """MODEL with SAMPLE_RATE_HZ: the model exported at that rate (D = step * rate); with
    DIR (already exported) it is refused, as an unknown argument is."""
    model = samples.random_model(1, 1, 1, 4, decimation=10, seed=3)  # 10 Hz, 1 s step
    model.save(tmp_path / "app" / "m")
    (tmp_path / "app" / "main.c").write_text("int main(void)\n{\n    return 0;\n}\n")
    lists = tmp_path / "app" / "CMakeLists.txt"
    head = ("cmake_minimum_required(VERSION 3.13)\nproject(app C)\n"
            "add_subdirectory(${FOGSF_DIR} fogsf)\nadd_executable(app main.c)\n")
    fogsf_dir = ROOT / "firmware" / "c"

    def configure(call: str, build: str) -> subprocess.CompletedProcess:
        lists.write_text(head + call + "\n")
        return subprocess.run(["cmake", "-S", str(lists.parent), "-B", str(tmp_path / build),
                               f"-DFOGSF_DIR={fogsf_dir}", f"-DFOGSF_EXECUTABLE={FOGSF}"],
                              capture_output=True, text=True)

    proc = configure("fogsf_add_model(app NAME imu_x MODEL m SAMPLE_RATE_HZ 100)", "b")
    assert proc.returncode == 0, proc.stderr
    header = (tmp_path / "b" / "fogsf_models" / "imu_x" / "imu_x.h").read_text()
    assert "#define IMU_X_DECIMATION 100\n" in header  # 1 s at 100 Hz
    proc = configure("fogsf_add_model(app NAME imu_x MODEL m)", "c")
    assert proc.returncode == 0, proc.stderr
    assert "#define IMU_X_DECIMATION 10\n" in \
        (tmp_path / "c" / "fogsf_models" / "imu_x" / "imu_x.h").read_text()
    for call, says in (("fogsf_add_model(app NAME imu_x DIR gen SAMPLE_RATE_HZ 100)",
                        "SAMPLE_RATE_HZ re-rates a MODEL"),
                       ("fogsf_add_model(app NAME imu_x MODEL m SAMPLE_RATE 100)",
                        "unknown arguments"),
                       ("fogsf_add_model(app NAME imu_x MODEL m SAMPLE_RATE_HZ 9000)",
                        "fogsf export failed")):
        proc = configure(call, "d")
        assert proc.returncode != 0 and says in proc.stderr, (call, proc.stderr)
