"""The kernel on three Cortex-M cores under QEMU, and a stack bound from the linked image.

`python -m fogsf.bindings.cores MODEL_DIR --out build/cores` is what `make firmware-cores`
runs: the golden vectors (the host build's outputs, bit for bit) and the power-on self-test
(fogsf_selftest) in an image for each core of `CORES` (Cortex-M4F hard float on mps2-an386,
Cortex-M3 on mps2-an385 and Cortex-M0 on microbit, both soft float), one line a core with the
image's flash, RAM and stack bound (fogsf.bindings.stack: a call-graph walk of the linked
image, libgcc included), for the default build of the kernel and its even-time build
(FOGSF_EVEN_TIME, whose golden vectors come from its own host build), and for each
toolchain of `TOOLCHAINS` the kernel's sources are compiled with (the strict flags; gcc's GNU
default; clang): PASS (every output bit for bit, self-test 0), REFUSED (the kernel stops the
build: fogsf_fp.h's #error), CAUGHT (it compiles, the self-test fails: FOGSF_SELFTEST_AT_INIT
refuses the model at init) or FAIL (other bits with a passing self-test, or another error).
With the strict flags it also counts each core's instructions per sample (fogsf.bindings.icount:
worst, mean over a decimation period, and the worst of a sample without a model step).

`--target block` (`make block-cores`) checks the calibration block instead: it writes the
model's block (`fogsf export --blob`), links it into an image for each core at BLOCK_ADDRESS
(section .fogsf_block, `--section-start`), the kernel and the loader compiled with the strict
flags; the image calls fogsf_model_from_block on it and runs the golden check
(firmware/c/test/golden_check.c) on that model: one PASS or FAIL line a core.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

from fogsf.bindings.block import BLOCK_SOURCES
from fogsf.bindings.firmware import (
    ARM_CC,
    CORES,
    TEST_FLAGS,
    Core,
    arm_tools_missing,
    build_arm,
    run_cmd,
    run_qemu,
    section_sizes,
    write_golden,
)
from fogsf.bindings.icount import SampleCounts, sample_counts
from fogsf.bindings.kernel import (
    BOUND_NAME,
    C_DIR,
    EVEN_TIME,
    SOURCES,
    STRICT,
    Kernel,
    build_kernel,
)
from fogsf.bindings.stack import INIT_ROOTS, STEP_ROOTS, StackBound, stack_bound
from fogsf.errors import UserError
from fogsf.export.block import write_block
from fogsf.models.stream import StreamModel


@dataclass(frozen=True)
class Toolchain:
    """How the kernel's and the models' sources are compiled (the drivers and the link are
    arm-none-eabi-gcc's)."""
    name: str
    cc: tuple[str, ...]
    flags: tuple[str, ...]
    label: str


WARN = ("-Wall", "-Wextra", "-Werror")
CLANG = ("clang", "--target=arm-none-eabi", "-fshort-enums")  # arm-none-eabi-gcc's enums
TOOLCHAINS = {
    "gcc-c99": Toolchain("gcc-c99", (ARM_CC,), STRICT,
                         "arm-none-eabi-gcc, the strict flags (-std=c99 -ffp-contract=off)"),
    "gcc-gnu": Toolchain("gcc-gnu", (ARM_CC,), WARN,
                         "arm-none-eabi-gcc's GNU default (no -std: gnu17, -ffp-contract=fast)"),
    "clang": Toolchain("clang", CLANG, ("-std=c99", *WARN, "-pedantic"),
                       "clang, its defaults (-ffp-contract=on)"),
    "clang-contract-fast": Toolchain("clang-contract-fast", CLANG,
                                     ("-std=c99", *WARN, "-pedantic", "-ffp-contract=fast"),
                                     "clang -ffp-contract=fast"),
    # the value-changing flags, for `--toolchains`: what each one does on the cores
    "gcc-fast-math": Toolchain("gcc-fast-math", (ARM_CC,), (*STRICT, "-ffast-math"),
                               "arm-none-eabi-gcc -ffast-math"),
    "clang-reciprocal-math": Toolchain("clang-reciprocal-math", CLANG,
                                       ("-std=c99", *WARN, "-freciprocal-math"),
                                       "clang -freciprocal-math (no macro announces it)"),
    "clang-no-honor-nans": Toolchain("clang-no-honor-nans", CLANG,
                                     ("-std=c99", *WARN, "-fno-honor-nans"),
                                     "clang -fno-honor-nans (no macro announces it)"),
    "clang-no-signed-zeros": Toolchain("clang-no-signed-zeros", CLANG,
                                       ("-std=c99", *WARN, "-fno-signed-zeros"),
                                       "clang -fno-signed-zeros (no macro announces it)"),
    "clang-no-honor-infinities": Toolchain("clang-no-honor-infinities", CLANG,
                                           ("-std=c99", *WARN, "-fno-honor-infinities"),
                                           "clang -fno-honor-infinities (no macro announces it)"),
    "clang-associative-math": Toolchain(
        "clang-associative-math", CLANG,
        ("-std=c99", *WARN, "-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math"),
        "clang -fassociative-math -fno-signed-zeros -fno-trapping-math (no macro)"),
}
# the value-changing flags no macro announces: each compiles, and the self-test fails
UNANNOUNCED = ("clang-reciprocal-math", "clang-no-honor-nans", "clang-no-signed-zeros",
               "clang-no-honor-infinities", "clang-associative-math")
DEFAULT_TOOLCHAINS = ("gcc-c99", "gcc-gnu", "clang", "clang-contract-fast")


@dataclass
class CoreResult:
    core: str
    verdict: str  # PASS, REFUSED, CAUGHT or FAIL
    output: str
    flash_bytes: int = 0
    ram_bytes: int = 0  # data + bss + the deeper of the step's and the init's stack bound
    step_stack: StackBound | None = None
    init_stack: StackBound | None = None
    counts: SampleCounts | None = None  # instructions per sample of the bench image (PASS)


def run_core(core: Core, build_dir: Path, golden_dir: Path, out: Path, defines: tuple[str, ...],
             toolchain: Toolchain = TOOLCHAINS["gcc-c99"], decimation: int = 0) -> CoreResult:
    """The golden image's verdict, sizes and stack bound on `core`; with a decimation D,
    also the bench image's instructions per sample over 2D + 1 samples (a PASS only)."""
    try:
        arm = build_arm(build_dir, golden_dir, out / core.name, defines=defines, core=core,
                        kernel_cc=toolchain.cc, kernel_flags=toolchain.flags)
    except UserError as e:
        refused = re.search(r'#error "(fogsf: built with[^"]*)"', str(e))
        return CoreResult(core.name, "REFUSED" if refused else "FAIL",
                          refused[1] if refused else str(e))
    assert arm.golden_elf is not None
    ok, text = run_qemu(arm.golden_elf, timeout=600.0, machine=core.machine)
    text_b, data, bss = section_sizes(arm.size_elf)
    step = stack_bound(arm.size_elf, STEP_ROOTS)
    init = stack_bound(arm.size_elf, INIT_ROOTS)
    selftest = re.search(r"^selftest (\d+)", text, flags=re.M)
    if ok and not step.unbounded:
        verdict = "PASS"
    elif selftest is not None and selftest[1] != "0":
        verdict = "CAUGHT"
    else:
        verdict = "FAIL"
    counts = (sample_counts(arm.bench_elf, decimation, core)
              if verdict == "PASS" and decimation > 0 else None)
    return CoreResult(core.name, verdict, text, text_b + data,
                      data + bss + max(step.bytes, init.bytes), step, init, counts)


BUILDS = {"default": False, "even-time": True}  # the kernel's builds: FOGSF_EVEN_TIME


def firmware_cores(model: StreamModel, out: Path, cores: list[str],
                   builds: tuple[str, ...] = tuple(BUILDS),
                   toolchains: tuple[str, ...] = DEFAULT_TOOLCHAINS) -> int:
    failed = False
    verdicts: set[str] = set()
    for kind in builds:
        even = BUILDS[kind]
        print(f"build: {kind}" + (f" ({EVEN_TIME})" if even else ""))
        ok, seen = cores_of(model, out / kind, cores, even, toolchains)
        failed |= not ok
        verdicts |= seen
    print("FAIL" if failed else f"PASS on {', '.join(cores)} ({', '.join(builds)}; "
          f"{', '.join(toolchains)}: every build bit for bit or refused"
          + (", or caught by the self-test" if "CAUGHT" in verdicts else "") + ")")
    return 1 if failed else 0


def cores_of(model: StreamModel, out: Path, cores: list[str], even_time: bool,
             toolchains: tuple[str, ...] = ("gcc-c99",)) -> tuple[bool, set[str]]:
    """The golden vectors of one build of the kernel on each core, compiled by each
    toolchain: (True when none FAILs, the verdicts seen)."""
    build = build_kernel(model, root=out / "host", even_time=even_time)
    golden_dir = out / "golden"
    write_golden(model, Kernel(model, build), golden_dir)
    failed = False
    seen: set[str] = set()
    for tname in toolchains:
        tc = TOOLCHAINS[tname]
        print(f" toolchain {tc.name}: {tc.label}")
        if shutil.which(tc.cc[0]) is None:
            print(f"  skipped: {tc.cc[0]} not installed")
            continue
        for name in cores:
            core = CORES[name]
            # instructions counted for the strict build only: the one the bound is stated for
            r = run_core(core, build.directory, golden_dir, out / tc.name, build.defines, tc,
                         model.decimation if tc.name == "gcc-c99" else 0)
            seen.add(r.verdict)
            failed |= r.verdict == "FAIL"
            if r.verdict == "REFUSED":
                print(f"  {core.label}: REFUSED to compile: {r.output}")
                continue
            lines = r.output.strip().splitlines()
            selftest = [ln for ln in lines if ln.startswith("selftest")]
            detail = result_detail(r.output)
            print(f"  {core.label} under qemu-system-arm -M {core.machine}: {r.verdict}: "
                  f"{detail}" + (f"; {selftest[0]}" if selftest else ""))
            if r.step_stack is not None and r.init_stack is not None:
                print(f"    flash {r.flash_bytes} B, RAM {r.ram_bytes} B (stack bound: "
                      f"fogsf_step {r.step_stack.bytes} B via {' > '.join(r.step_stack.path)}; "
                      f"init {r.init_stack.bytes} B)")
                if r.counts is not None:
                    c = r.counts
                    print(f"    instructions per sample: worst {c.worst}, mean {c.mean:.0f} "
                          f"(worst / mean {c.worst_over_mean:.1f}; a sample without a model "
                          f"step: worst {c.non_step_worst})")
                if r.step_stack.unbounded:
                    print(f"    no static stack bound through: "
                          f"{', '.join(r.step_stack.unbounded)}")
            if r.verdict == "FAIL":
                print("\n".join(f"    {ln}" for ln in lines[-12:]))
    return not failed, seen


def result_detail(text: str) -> str:
    """The image's last PASS or FAIL line, without the verdict."""
    last = [ln for ln in text.strip().splitlines() if ln.startswith(("PASS", "FAIL"))]
    return re.sub(r"^(PASS|FAIL): ", "", last[-1]) if last else "no result"


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


def block_cores(model: StreamModel, out: Path, cores: list[str]) -> int:
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
        print(f"  {core.label} under qemu-system-arm -M {core.machine}, block at "
              f"{where[1] if where else '?'}: {'PASS' if ok else 'FAIL'}: "
              f"{result_detail(text)}")
        if not ok:
            print("\n".join(f"    {ln}" for ln in text.strip().splitlines()[-12:]))
        failed |= not ok
    print("FAIL" if failed else f"PASS on {', '.join(cores)}: the block's model gives the "
          "generated C's golden vectors bit for bit")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.cores", description=__doc__)
    p.add_argument("model", type=Path, help="model directory (stream.json + weights)")
    p.add_argument("--target", choices=("kernel", "block"), default="kernel",
                   help="the generated C model (default) or the model read from its "
                        "calibration block")
    p.add_argument("--out", type=Path, default=None,
                   help="build folder (default build/cores, build/block-cores)")
    p.add_argument("--cores", default=",".join(CORES),
                   help=f"comma-separated, of {', '.join(CORES)}")
    p.add_argument("--builds", default=",".join(BUILDS),
                   help=f"comma-separated, of {', '.join(BUILDS)}")
    p.add_argument("--toolchains", default=",".join(DEFAULT_TOOLCHAINS),
                   help=f"comma-separated, of {', '.join(TOOLCHAINS)}")
    args = p.parse_args(argv)
    cores = [c for c in args.cores.split(",") if c]
    unknown = [c for c in cores if c not in CORES]
    if unknown:
        p.error(f"unknown core(s) {unknown}: choose from {', '.join(CORES)}")
    builds = tuple(b for b in args.builds.split(",") if b)
    if not builds or set(builds) - set(BUILDS):
        p.error(f"--builds {args.builds!r}: choose from {', '.join(BUILDS)}")
    toolchains = tuple(t for t in args.toolchains.split(",") if t)
    if not toolchains or set(toolchains) - set(TOOLCHAINS):
        p.error(f"--toolchains {args.toolchains!r}: choose from {', '.join(TOOLCHAINS)}")
    what = "block-cores" if args.target == "block" else "firmware-cores"
    missing = arm_tools_missing()
    if missing:
        print(f"{what}: {missing}", file=sys.stderr)
        return 2
    try:
        model = StreamModel.load(args.model)
        print(f"model {args.model}: id {model.model_id}, {model.summary}")
        if args.target == "block":
            return block_cores(model, args.out or Path("build/block-cores"), cores)
        return firmware_cores(model, args.out or Path("build/cores"), cores, builds,
                              toolchains)
    except UserError as e:
        print(f"{what}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
