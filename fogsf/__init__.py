"""fogsf: FOG thermal scale-factor error from chamber data to firmware.

One package a stage, imports pointing one way (docs/decisions.md, "One import package, a
package a stage"): `fogsf.logs` (read, write, measure), `fogsf.sim` (the physics simulator),
`fogsf.models` (the streaming artifact and its structures), `fogsf.gsa` (the optimizer),
`fogsf.prior` (a design's units as a population), `fogsf.training`, `fogsf.diagnose`,
`fogsf.plan`, `fogsf.fleet` (the fleet database), `fogsf.export` (ONNX and the generated C
model), `fogsf.bindings` (the compiled C kernel through cffi) and `fogsf.cli` (the `fogsf`
commands). The C kernel ships with the package;
a firmware project finds it here, as emlearn users find `emlearn.includedir`:

    cmake -DFOGSF_DIR="$(python -c 'import fogsf; print(fogsf.cmake_dir)')" ...
    add_subdirectory(${FOGSF_DIR} fogsf)   # the `fogsf` library and fogsf_add_model()
"""

from __future__ import annotations

from pathlib import Path

__version__ = "0.1.0"

_HERE = Path(__file__).resolve().parent
# An installed wheel holds the firmware folder inside the package; a checkout has it beside.
_FIRMWARE = _HERE / "firmware" if (_HERE / "firmware" / "c").is_dir() else _HERE.parent / "firmware"

in_checkout: bool = _FIRMWARE != _HERE / "firmware"
"""True when run from a source checkout (firmware/ beside the package), not an installed wheel."""
firmware_dir: str = str(_FIRMWARE)
"""The firmware folder: c/ (kernel and CMake), cmake/ (toolchain files), examples/."""
cmake_dir: str = str(_FIRMWARE / "c")
"""For CMake's add_subdirectory: the kernel library `fogsf` and fogsf_add_model()."""
includedir: str = cmake_dir
"""The folder that holds fogsf.h."""
toolchain_file: str = str(_FIRMWARE / "cmake" / "cortex-m4f.cmake")
"""CMAKE_TOOLCHAIN_FILE for a Cortex-M4F build with arm-none-eabi-gcc."""
examples_dir: str = str(_FIRMWARE / "examples")
"""imu3: three models in one Cortex-M4F image, run under QEMU."""
