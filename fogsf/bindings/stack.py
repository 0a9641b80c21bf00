"""A stack bound from the call graph of a linked Cortex-M image (libgcc included).

arm-none-eabi-objdump disassembles the image; every function's frame is what its
instructions move SP down by (push / stmdb sp!, vpush, sub sp, #N: summed, a bound), its
edges are its `bl` calls and its tail calls (`b` to another function's first instruction).
The bound of a root is its frame plus the deepest of its callees'; recursion, an SP moved by
a register (a VLA) or a call through a register leave a path without a static bound, and
the walk names the functions.
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from fogsf.errors import UserError

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
            if t and not t[2] and (t[1] != cur or base == "bl"):
                f.calls.add(t[1])  # a call (to itself: recursion), or a tail call
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
    proc = subprocess.run([OBJDUMP, "-d", "--no-show-raw-insn", str(elf)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"{OBJDUMP} -d {elf} failed: {proc.stderr}")
    return walk(parse_image(proc.stdout), roots)
