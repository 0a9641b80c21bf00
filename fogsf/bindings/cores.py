"""The kernel on three Cortex-M cores under QEMU, and a stack bound from the linked image.

`python -m fogsf.bindings.cores MODEL_DIR --out build/cores` is what `make firmware-cores`
runs: the golden vectors (the host build's outputs, bit for bit) in an image for each core of
`CORES` (Cortex-M4F hard float on mps2-an386, Cortex-M3 on mps2-an385 and Cortex-M0 on
microbit, both soft float), one PASS or FAIL line a core with the image's flash, RAM and
stack bound (fogsf.bindings.stack: a call-graph walk of the linked image, libgcc included),
for the default build of the kernel and its even-time build (FOGSF_EVEN_TIME, whose golden
vectors come from its own host build).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from fogsf.bindings.firmware import (
    CORES,
    Core,
    arm_tools_missing,
    build_arm,
    run_qemu,
    section_sizes,
    write_golden,
)
from fogsf.bindings.kernel import EVEN_TIME, Kernel, build_kernel
from fogsf.bindings.stack import INIT_ROOTS, STEP_ROOTS, StackBound, stack_bound
from fogsf.errors import UserError
from fogsf.models.stream import StreamModel


@dataclass
class CoreResult:
    core: str
    passed: bool
    output: str
    flash_bytes: int
    ram_bytes: int  # data + bss + the deeper of the step's and the init's stack bound
    step_stack: StackBound
    init_stack: StackBound


def run_core(core: Core, build_dir: Path, golden_dir: Path, out: Path, defines: tuple[str, ...]
             ) -> CoreResult:
    arm = build_arm(build_dir, golden_dir, out / core.name, defines=defines, core=core)
    assert arm.golden_elf is not None
    ok, text = run_qemu(arm.golden_elf, timeout=600.0, machine=core.machine)
    text_b, data, bss = section_sizes(arm.size_elf)
    step = stack_bound(arm.size_elf, STEP_ROOTS)
    init = stack_bound(arm.size_elf, INIT_ROOTS)
    return CoreResult(core.name, ok and not step.unbounded, text, text_b + data,
                      data + bss + max(step.bytes, init.bytes), step, init)


BUILDS = {"default": False, "even-time": True}  # the kernel's builds: FOGSF_EVEN_TIME


def firmware_cores(model_dir: Path, out: Path, cores: list[str],
                   builds: tuple[str, ...] = tuple(BUILDS)) -> int:
    missing = arm_tools_missing()
    if missing:
        print(f"firmware-cores: {missing}", file=sys.stderr)
        return 2
    model = StreamModel.load(model_dir)
    print(f"model {model_dir}: id {model.model_id}, {model.summary}")
    failed = False
    for kind in builds:
        even = BUILDS[kind]
        print(f"build: {kind}" + (f" ({EVEN_TIME})" if even else ""))
        failed |= not cores_of(model, out / kind, cores, even)
    print("FAIL" if failed else f"PASS on {', '.join(cores)} ({', '.join(builds)})")
    return 1 if failed else 0


def cores_of(model: StreamModel, out: Path, cores: list[str], even_time: bool) -> bool:
    """The golden vectors of one build of the kernel on each core; True when all pass."""
    build = build_kernel(model, root=out / "host", even_time=even_time)
    golden_dir = out / "golden"
    write_golden(model, Kernel(model, build), golden_dir)
    failed = False
    for name in cores:
        core = CORES[name]
        r = run_core(core, build.directory, golden_dir, out, build.defines)
        last = [ln for ln in r.output.strip().splitlines() if ln.startswith(("PASS", "FAIL"))]
        print(f"{core.label} under qemu-system-arm -M {core.machine}: "
              f"{'PASS' if r.passed else 'FAIL'}: {last[-1] if last else 'no result'}")
        print(f"  flash {r.flash_bytes} B, RAM {r.ram_bytes} B (stack bound: fogsf_step "
              f"{r.step_stack.bytes} B via {' > '.join(r.step_stack.path)}; init "
              f"{r.init_stack.bytes} B)")
        if r.step_stack.unbounded:
            print(f"  no static stack bound through: {', '.join(r.step_stack.unbounded)}")
        if not r.passed:
            print("\n".join(f"  {ln}" for ln in r.output.strip().splitlines()[-12:]))
        failed |= not r.passed
    return not failed


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.cores", description=__doc__)
    p.add_argument("model", type=Path, help="model directory (stream.json + weights)")
    p.add_argument("--out", type=Path, default=Path("build/cores"))
    p.add_argument("--cores", default=",".join(CORES),
                   help=f"comma-separated, of {', '.join(CORES)}")
    p.add_argument("--builds", default=",".join(BUILDS),
                   help=f"comma-separated, of {', '.join(BUILDS)}")
    args = p.parse_args(argv)
    cores = [c for c in args.cores.split(",") if c]
    unknown = [c for c in cores if c not in CORES]
    if unknown:
        p.error(f"unknown core(s) {unknown}: choose from {', '.join(CORES)}")
    builds = tuple(b for b in args.builds.split(",") if b)
    if not builds or set(builds) - set(BUILDS):
        p.error(f"--builds {args.builds!r}: choose from {', '.join(BUILDS)}")
    try:
        return firmware_cores(args.model, args.out, cores, builds)
    except UserError as e:
        print(f"firmware-cores: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
