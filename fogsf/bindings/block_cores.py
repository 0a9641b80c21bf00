"""The calibration block on the Cortex-M cores under QEMU: the golden vectors of the generated
C model (the host build's outputs), bit for bit, from a model read out of a block at a flash
address of its own.

`python -m fogsf.bindings.block_cores MODEL_DIR --out build/block-cores` writes the model's
block (`fogsf export --blob`), links it into an image for each core at BLOCK_ADDRESS (section
.fogsf_block, `--section-start`), the kernel and the loader compiled with the strict flags;
the image calls fogsf_model_from_block on it and runs the golden check
(firmware/c/test/golden_check.c) on that model: one PASS or FAIL line a core.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from fogsf.bindings.block import BLOCK_SOURCES
from fogsf.bindings.firmware import (
    ARM_CC,
    CORES,
    TEST_FLAGS,
    Core,
    arm_tools_missing,
    run_cmd,
    run_qemu,
    write_golden,
)
from fogsf.bindings.kernel import BOUND_NAME, C_DIR, SOURCES, STRICT, Kernel, build_kernel
from fogsf.errors import UserError
from fogsf.export.block import write_block
from fogsf.models.stream import StreamModel

# where the line writes a unit's block: a flash sector the image's code never reaches
BLOCK_ADDRESS = {"cortex-m4f": 0x00300000, "cortex-m3": 0x00300000, "cortex-m0": 0x00030000}
BLOCK_DATA = """/* the unit's calibration block, as the line writes it into its flash sector */
    .section .fogsf_block, "a"
    .balign 4
    .global fogsf_unit_block
fogsf_unit_block:
    .incbin "{path}"
    .global fogsf_unit_block_end
fogsf_unit_block_end:
"""


def block_golden(golden_dir: Path) -> None:
    """golden_vectors.h pointed at the model the image reads from its block."""
    path = golden_dir / "golden_vectors.h"
    text = path.read_text()
    old = f'#include "{BOUND_NAME}.h"\n#define FOGSF_GOLDEN_MODEL (&{BOUND_NAME})\n'
    if old not in text:
        raise UserError(f"{path}: no model line to point at the block")
    path.write_text(text.replace(old, '#include "fogsf_block.h"\nextern fogsf_block_model '
                                      'golden_block;\n#define FOGSF_GOLDEN_MODEL '
                                      '(&golden_block.model)\n'))


def build_block_image(core: Core, block: Path, golden_dir: Path, defines: tuple[str, ...],
                      out: Path) -> Path:
    """block.elf for one core: start-up, the golden check, block_main, the kernel and the
    loader (strict flags), the block at BLOCK_ADDRESS[core]."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "block_data.S").write_text(BLOCK_DATA.format(path=block.resolve()))
    inc = ["-I", str(golden_dir), "-I", str(C_DIR), "-I", str(C_DIR / "test"),
           "-I", str(C_DIR / "arm")]
    common = [*core.flags, "-O2", "-ffunction-sections", "-fdata-sections", *defines]
    objs = []
    srcs: list[tuple[Path, tuple[str, ...]]] = [(C_DIR / n, STRICT)
                                                for n in (*SOURCES, *BLOCK_SOURCES)]
    srcs += [(C_DIR / "test" / "golden_check.c", STRICT),
             (C_DIR / "arm" / "startup.c", TEST_FLAGS),
             (C_DIR / "arm" / "block_main.c", TEST_FLAGS), (out / "block_data.S", ())]
    for src, flags in srcs:
        obj = out / (src.stem + ".o")
        run_cmd([ARM_CC, *flags, *common, *inc, "-c", str(src), "-o", str(obj)],
                f"compiling {src.name} for {core.name}")
        objs.append(obj)
    elf = out / "block.elf"
    run_cmd([ARM_CC, *core.flags, "-nostdlib", "-nostartfiles", "-Wl,--gc-sections",
             f"-Wl,--section-start=.fogsf_block=0x{BLOCK_ADDRESS[core.name]:08x}",
             "-T", str(C_DIR / "arm" / core.linker_script), *map(str, objs), "-lgcc",
             "-o", str(elf)], f"linking {elf.name}")
    return elf


def block_cores(model_dir: Path, out: Path, cores: list[str]) -> int:
    missing = arm_tools_missing()
    if missing:
        print(f"block-cores: {missing}", file=sys.stderr)
        return 2
    model = StreamModel.load(model_dir)
    print(f"model {model_dir}: id {model.model_id}, {model.summary}")
    block = write_block(model, out / "unit.bin")
    print(f"block {block} ({block.stat().st_size} bytes)")
    build = build_kernel(model, root=out / "host")
    golden_dir = out / "golden"
    write_golden(model, Kernel(model, build), golden_dir)
    block_golden(golden_dir)
    failed = False
    for name in cores:
        core = CORES[name]
        elf = build_block_image(core, block, golden_dir, build.defines, out / name)
        ok, text = run_qemu(elf, timeout=600.0, machine=core.machine)
        where = re.search(r"^block at (0x[0-9a-f]+)", text, flags=re.M)
        last = [ln for ln in text.splitlines() if ln.startswith(("PASS", "FAIL"))]
        print(f"  {core.label} under qemu-system-arm -M {core.machine}, block at "
              f"{where[1] if where else '?'}: {'PASS' if ok else 'FAIL'}: "
              f"{re.sub(r'^(PASS|FAIL): ', '', last[-1]) if last else 'no result'}")
        if not ok:
            print("\n".join(f"    {ln}" for ln in text.strip().splitlines()[-12:]))
        failed |= not ok
    print("FAIL" if failed else f"PASS on {', '.join(cores)}: the block's model gives the "
          "generated C's golden vectors bit for bit")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.block_cores", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m fogsf.bindings.block_cores "
                                       "tests/fixtures/small_model --out build/block-cores")
    p.add_argument("model", type=Path, help="model directory (stream.json + weights)")
    p.add_argument("--out", type=Path, default=Path("build/block-cores"))
    p.add_argument("--cores", default=",".join(CORES),
                   help=f"comma-separated, of {', '.join(CORES)}")
    args = p.parse_args(argv)
    cores = [c for c in args.cores.split(",") if c]
    unknown = [c for c in cores if c not in CORES]
    if unknown:
        p.error(f"unknown core(s) {unknown}: choose from {', '.join(CORES)}")
    try:
        return block_cores(args.model, args.out, cores)
    except UserError as e:
        print(f"block-cores: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
