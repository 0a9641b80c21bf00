"""The package's layout holds: imports run one way between the stage packages (the table of
docs/decisions.md, "One import package, a package a stage"), no module imports itself back at
import time, no module is over 600 lines, and an import inside a function is the exception
(kept for heavy dependencies: torch, onnx, matplotlib off the paths that do not need them)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "fogsf"
MAX_LINES = 400
MAX_MODULES = 15  # .py files in one folder, its __init__ included
MAX_INNER_IMPORTS = 15  # imports of fogsf's own modules inside functions, package-wide

# stage -> the stages it imports from directly (docs/decisions.md); below them, what those do
DIRECT: dict[str, set[str]] = {
    "errors": set(),
    "scratch": set(),
    "logs": {"errors"},
    "gsa": {"errors"},
    "sim": {"logs"},
    "models": {"logs", "sim"},
    "prior": {"logs", "models"},
    "training": {"logs", "models", "gsa", "sim", "prior"},
    "diagnose": {"logs", "sim", "models"},
    "export": {"models"},
    "plan": {"training", "sim", "gsa", "prior"},
    "fleet": {"training", "plan", "prior", "scratch"},
    "bindings": {"models", "export"},
    "cli": {"logs", "gsa", "sim", "models", "prior", "training", "diagnose", "export", "fleet",
            "plan", "bindings"},
}


def below(stage: str) -> set[str]:
    """Every stage `stage` may import from: its own, those of the table and theirs."""
    seen, todo = {stage}, [stage]
    while todo:
        for s in DIRECT[todo.pop()]:
            if s not in seen:
                seen.add(s)
                todo.append(s)
    return seen


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def stage_of(module: str) -> str | None:
    """The stage of `fogsf.X...` (None for the root package and `python -m fogsf`, which
    belong to no stage: the root holds paths only, __main__ is the CLI's)."""
    parts = module.split(".")
    if len(parts) < 2 or parts[1] == "__main__":
        return None if len(parts) < 2 else "cli"
    return parts[1]


MODULES = {module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


def imports(path: Path) -> list[tuple[str, int, bool]]:
    """(fogsf module imported, line, inside a function) for every import of a fogsf module;
    `from pkg import sub` names the submodule when `sub` is one."""
    tree = ast.parse(path.read_text())
    inner: set[int] = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inner.update(id(n) for n in ast.walk(fn) if n is not fn)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES
                     else node.module for a in node.names]
        else:
            continue
        out += [(n, node.lineno, id(node) in inner) for n in names
                if n.split(".")[0] == "fogsf"]
    return out


GRAPH = {m: imports(p) for m, p in MODULES.items()}


def test_every_stage_is_in_the_table() -> None:
    stages = {stage_of(m) for m in MODULES} - {None}
    assert stages <= set(DIRECT), f"stages not in the table: {stages - set(DIRECT)}"


def test_imports_run_down_the_table() -> None:
    """An import (at the top or inside a function) of a stage the table puts above or beside
    the importer's fails, with the line that does it."""
    bad = []
    for mod, edges in GRAPH.items():
        src = stage_of(mod)
        if src is None:
            continue
        for target, line, _ in edges:
            dst = stage_of(target)
            if dst is not None and dst not in below(src):
                bad.append(f"{MODULES[mod].relative_to(ROOT.parent)}:{line}: {src} imports "
                           f"{target} ({dst})")
    assert not bad, "imports against docs/decisions.md's table:\n" + "\n".join(bad)


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of `graph` (a path back to its start), or None."""
    state: dict[str, int] = {}  # 1: on the path, 2: done
    path: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        path.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return [*path[path.index(m):], m]
            if m not in state and (found := visit(m)) is not None:
                return found
        path.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (found := visit(n)) is not None:
            return found
    return None


def test_no_cycle_between_modules_or_stages() -> None:
    """The modules' imports at their top (what runs on import) hold no cycle, nor do the
    stages' imports, counting those inside functions too."""
    top = {m: {t for t, _, inner in e if not inner and t in MODULES and t != m}
           for m, e in GRAPH.items()}
    assert _cycle(top) is None, f"an import cycle: {' -> '.join(_cycle(top) or [])}"
    stages: dict[str, set[str]] = {}
    for mod, edges in GRAPH.items():
        src = stage_of(mod)
        for target, _, _ in edges:
            dst = stage_of(target)
            if src and dst and dst != src:
                stages.setdefault(src, set()).add(dst)
    assert _cycle(stages) is None, f"a cycle of stages: {' -> '.join(_cycle(stages) or [])}"


@pytest.mark.parametrize("graph, cyclic", [
    ({"a": {"b"}, "b": {"c"}, "c": set()}, False),
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, True),
    ({"a": {"a"}}, True),
])
def test_the_cycle_finder_finds_cycles(graph: dict[str, set[str]], cyclic: bool) -> None:
    assert (_cycle(graph) is not None) == cyclic


def test_an_arrow_up_is_refused() -> None:
    """The check itself: logs importing training, models importing training, cli imported
    by anything are all against the table; cli importing them all is not."""
    assert "training" not in below("logs") and "training" not in below("models")
    assert all("cli" not in below(s) for s in DIRECT if s != "cli")
    assert below("cli") == set(DIRECT)
    assert "plan" in below("fleet") and "fleet" not in below("plan")


def test_no_folder_over_15_modules() -> None:
    folders: dict[str, int] = {}
    for p in MODULES.values():
        key = str(p.parent.relative_to(ROOT.parent))
        folders[key] = folders.get(key, 0) + 1
    big = {k: n for k, n in folders.items() if n > MAX_MODULES}
    assert not big, f"folders over {MAX_MODULES} modules: {big}"


def test_no_module_over_400_lines() -> None:
    long = {str(p.relative_to(ROOT.parent)): n for p in MODULES.values()
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_imports_inside_functions_are_the_exception() -> None:
    inner = sorted({f"{MODULES[m].relative_to(ROOT.parent)}:{line}"
                    for m, e in GRAPH.items() for _, line, is_inner in e if is_inner})
    assert len(inner) <= MAX_INNER_IMPORTS, "\n".join(inner)
