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
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

from fogsf.bindings.firmware import (
    ARM_CC,
    CORES,
    Core,
    arm_tools_missing,
    build_arm,
    run_qemu,
    section_sizes,
    write_golden,
)
from fogsf.bindings.kernel import EVEN_TIME, STRICT, Kernel, build_kernel
from fogsf.bindings.stack import INIT_ROOTS, STEP_ROOTS, StackBound, stack_bound
from fogsf.errors import UserError
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


def run_core(core: Core, build_dir: Path, golden_dir: Path, out: Path, defines: tuple[str, ...],
             toolchain: Toolchain = TOOLCHAINS["gcc-c99"]) -> CoreResult:
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
    return CoreResult(core.name, verdict, text, text_b + data,
                      data + bss + max(step.bytes, init.bytes), step, init)


BUILDS = {"default": False, "even-time": True}  # the kernel's builds: FOGSF_EVEN_TIME


def firmware_cores(model_dir: Path, out: Path, cores: list[str],
                   builds: tuple[str, ...] = tuple(BUILDS),
                   toolchains: tuple[str, ...] = DEFAULT_TOOLCHAINS) -> int:
    missing = arm_tools_missing()
    if missing:
        print(f"firmware-cores: {missing}", file=sys.stderr)
        return 2
    model = StreamModel.load(model_dir)
    print(f"model {model_dir}: id {model.model_id}, {model.summary}")
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
            r = run_core(core, build.directory, golden_dir, out / tc.name, build.defines, tc)
            seen.add(r.verdict)
            failed |= r.verdict == "FAIL"
            if r.verdict == "REFUSED":
                print(f"  {core.label}: REFUSED to compile: {r.output}")
                continue
            lines = r.output.strip().splitlines()
            last = [ln for ln in lines if ln.startswith(("PASS", "FAIL"))]
            selftest = [ln for ln in lines if ln.startswith("selftest")]
            detail = re.sub(r"^(PASS|FAIL): ", "", last[-1]) if last else "no result"
            print(f"  {core.label} under qemu-system-arm -M {core.machine}: {r.verdict}: "
                  f"{detail}" + (f"; {selftest[0]}" if selftest else ""))
            if r.step_stack is not None and r.init_stack is not None:
                print(f"    flash {r.flash_bytes} B, RAM {r.ram_bytes} B (stack bound: "
                      f"fogsf_step {r.step_stack.bytes} B via {' > '.join(r.step_stack.path)}; "
                      f"init {r.init_stack.bytes} B)")
                if r.step_stack.unbounded:
                    print(f"    no static stack bound through: "
                          f"{', '.join(r.step_stack.unbounded)}")
            if r.verdict == "FAIL":
                print("\n".join(f"    {ln}" for ln in lines[-12:]))
    return not failed, seen


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.cores", description=__doc__)
    p.add_argument("model", type=Path, help="model directory (stream.json + weights)")
    p.add_argument("--out", type=Path, default=Path("build/cores"))
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
    try:
        return firmware_cores(args.model, args.out, cores, builds, toolchains)
    except UserError as e:
        print(f"firmware-cores: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
