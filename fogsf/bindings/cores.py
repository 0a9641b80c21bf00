"""The kernel on three Cortex-M cores under QEMU, and a stack bound from the linked image.

`python -m fogsf.bindings.cores MODEL_DIR --out build/cores` is what `make firmware-cores`
runs: the golden vectors (the host build's outputs, bit for bit) in an image for each core of
`CORES` (Cortex-M4F hard float on mps2-an386, Cortex-M3 on mps2-an385 and Cortex-M0 on
microbit, both soft float), one PASS or FAIL line a core with the image's flash, RAM and
stack bound. `stack_bound` walks the call graph of a linked image (arm-none-eabi-objdump:
every function's frame from its prologue, `bl` and tail-call edges), libgcc included.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

from fogsf.bindings.firmware import (
    CORES,
    Core,
    arm_tools_missing,
    build_arm,
    run_cmd,
    run_qemu,
    section_sizes,
    write_golden,
)
from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.errors import UserError
from fogsf.models.stream import StreamModel

OBJDUMP = "arm-none-eabi-objdump"
STEP_ROOTS = ("fogsf_step",)  # what firmware calls once a sample
INIT_ROOTS = ("fogsf_init", "fogsf_reset", "fogsf_model_check", "fogsf_selftest")

FUNC_RE = re.compile(r"^([0-9a-f]+) <([^>]+)>:$")
INSN_RE = re.compile(r"^\s+[0-9a-f]+:\s+([a-z][\w.]*)\s*(.*)$")
TARGET_RE = re.compile(r"<([^>+]+)(\+0x[0-9a-f]+)?>")


@dataclass
class Function:
    frame: int = 0  # bytes the function moves SP down by (pushes, vpush, sub sp)
    calls: set[str] = field(default_factory=set)
    dynamic: bool = False  # SP moved by a register (a VLA or alloca): no static bound
    indirect: bool = False  # calls through a register


def _regs(text: str) -> list[str]:
    """The registers of a {r4, r5-r7, lr} list, ranges expanded."""
    body = text[text.index("{") + 1:text.index("}")]
    out: list[str] = []
    for part in (p.strip() for p in body.split(",")):
        m = re.fullmatch(r"([a-z]+)(\d+)-[a-z]+(\d+)", part)
        out += ([f"{m[1]}{i}" for i in range(int(m[2]), int(m[3]) + 1)] if m else [part])
    return out


def parse_image(disassembly: str) -> dict[str, Function]:
    """Frames and call edges of every function of an objdump -d listing (Thumb)."""
    funcs: dict[str, Function] = {}
    cur: str | None = None
    for line in disassembly.splitlines():
        m = FUNC_RE.match(line)
        if m:
            cur = m[2]
            funcs.setdefault(cur, Function())
            continue
        m = INSN_RE.match(line)
        if cur is None or not m:
            continue
        op, args = m[1], m[2].split(";")[0].split("@")[0].strip()
        f = funcs[cur]
        base = op.split(".")[0]
        if base == "push" or (base == "stmdb" and args.startswith("sp!")):
            f.frame += 4 * len(_regs(args))
        elif base == "vpush":
            f.frame += sum(8 if r.startswith("d") else 4 for r in _regs(args))
        elif base in ("sub", "subw") and re.match(r"sp,\s*(sp,\s*)?#", args):
            f.frame += int(args.rsplit("#", 1)[1].split()[0], 0)
        elif base in ("sub", "subw") and args.startswith("sp,"):
            f.dynamic = True
        elif base in ("mov", "add") and re.match(r"sp,\s*(sp,\s*)?r\d", args) and base == "add":
            f.dynamic = True
        elif base in ("bl", "blx", "b"):
            t = TARGET_RE.search(args)
            if t and not t[2] and t[1] != cur:
                f.calls.add(t[1])  # a call, or a tail call into another function's start
            elif base == "blx" and not t:
                f.indirect = True
    return funcs


@dataclass
class StackBound:
    bytes: int
    path: list[str]  # the deepest chain
    unbounded: list[str]  # functions on a reachable path without a static bound


def walk(funcs: dict[str, Function], roots: tuple[str, ...]) -> StackBound:
    """The deepest frame sum over the call graph from the roots present in the image."""
    memo: dict[str, tuple[int, list[str]]] = {}
    unbounded: set[str] = set()

    def depth(name: str, stack: tuple[str, ...]) -> tuple[int, list[str]]:
        if name in stack:  # recursion: no bound
            unbounded.add(name)
            return 0, [name]
        if name in memo:
            return memo[name]
        f = funcs.get(name)
        if f is None:
            unbounded.add(name)  # called but not in the image
            return 0, [name]
        if f.dynamic or f.indirect:
            unbounded.add(name)
        best, path = 0, []
        for callee in sorted(f.calls):
            d, p = depth(callee, (*stack, name))
            if d > best:
                best, path = d, p
        memo[name] = (f.frame + best, [name, *path])
        return memo[name]

    present = [r for r in roots if r in funcs]
    if not present:
        raise UserError(f"stack walk: none of {roots} in the image")
    best = max((depth(r, ()) for r in present), key=lambda dp: dp[0])
    return StackBound(best[0], best[1], sorted(unbounded))


def stack_bound(elf: Path, roots: tuple[str, ...] = STEP_ROOTS) -> StackBound:
    text = run_cmd([OBJDUMP, "-d", "--no-show-raw-insn", str(elf)], "objdump").stdout
    return walk(parse_image(text), roots)


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


def firmware_cores(model_dir: Path, out: Path, cores: list[str]) -> int:
    missing = arm_tools_missing()
    if missing:
        print(f"firmware-cores: {missing}", file=sys.stderr)
        return 2
    model = StreamModel.load(model_dir)
    print(f"model {model_dir}: id {model.model_id}, {model.summary}")
    build = build_kernel(model, root=out / "host")
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
    print("FAIL" if failed else f"PASS on {', '.join(cores)}")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.cores", description=__doc__)
    p.add_argument("model", type=Path, help="model directory (stream.json + weights)")
    p.add_argument("--out", type=Path, default=Path("build/cores"))
    p.add_argument("--cores", default=",".join(CORES),
                   help=f"comma-separated, of {', '.join(CORES)}")
    args = p.parse_args(argv)
    cores = [c for c in args.cores.split(",") if c]
    unknown = [c for c in cores if c not in CORES]
    if unknown:
        p.error(f"unknown core(s) {unknown}: choose from {', '.join(CORES)}")
    try:
        return firmware_cores(args.model, args.out, cores)
    except UserError as e:
        print(f"firmware-cores: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
