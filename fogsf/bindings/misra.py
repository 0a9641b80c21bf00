"""MISRA C:2012 check of the kernel and of generated models (`make misra`).

Exports a model of every shape through the export path (plain; bias head with the diagonal
quadratic; a play; the full quadratic with its cross terms on two layers; a rate part; with
--gsa also the largest LSTM the GSA search can give, 3x256, in a run of its own), then runs
cppcheck's MISRA addon over the kernel's sources and the generated `NAME.c` files in one
configuration (the state sized for the largest). Each finding gets its category from the
rule table below (MISRA C:2012 with Amendments 1 and 2: the addon reports only numbers).
Fails (exit 1) on any Mandatory or Required finding, on any cppcheck error, on any Advisory
rule firmware/c/MISRA.md does not record as `Rule N.M`, and where the kernel's sources name a
plain integer type (Dir 4.6; the addon does not see an `int` used as a boolean, 10.1/14.4).
Three checks of its own cover Required rules the addon misses (firmware/c/MISRA.md, the
coverage matrix): parameter names of fogsf.h's prototypes and the definitions (8.3), no
cast of a parenthesized expression (10.8), and gcc's warnings that map to rules (5.3, 8.2,
8.4, 9.1, 11.8, 13.2, 16.3, 16.4, 17.3, 17.4, 18.8, 20.9) as errors on the kernel's sources.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from fogsf.bindings.kernel import C_DIR, EVEN_TIME, SOURCES, STRICT, state_sizes
from fogsf.errors import UserError
from fogsf.export.header import write_model
from fogsf.models import samples
from fogsf.models.stream import StreamModel

CPPCHECK = "cppcheck"
MISRA_MD = C_DIR / "MISRA.md"
KERNEL_HEADERS = ("fogsf.h", "fogsf_fp.h")
# the calibration block loader (fogsf_block.c): flight code beside the kernel, checked as it is
LOADER = ("fogsf_block.c",)
LOADER_HEADER = "fogsf_block.h"

# MISRA C:2012 (third edition, with Amendments 1 and 2): the Mandatory and the Advisory rules;
# every other rule and directive is Required (an unknown number counts as Required too).
MANDATORY = frozenset({"9.1", "12.5", "13.6", "17.3", "17.4", "17.6", "19.1", "21.13",
                       "21.17", "21.18", "21.19", "21.20", "22.2", "22.4", "22.5", "22.6"})
ADVISORY = frozenset({
    "Dir 4.2", "Dir 4.4", "Dir 4.5", "Dir 4.6", "Dir 4.8", "Dir 4.9", "Dir 4.13",
    "1.2", "2.3", "2.4", "2.5", "2.6", "2.7", "4.2", "5.9", "8.7", "8.9", "8.11", "8.13",
    "10.5", "11.4", "11.5", "12.1", "12.3", "12.4", "13.3", "13.4", "15.1", "15.4", "15.5",
    "17.5", "17.8", "18.4", "18.5", "19.2", "20.1", "20.5", "20.10", "21.12"})


# the rules of each chapter and the directives (MISRA C:2012 with Amendments 1 and 2)
RULES_PER_CHAPTER = {1: 4, 2: 7, 3: 2, 4: 2, 5: 9, 6: 2, 7: 4, 8: 14, 9: 5, 10: 8, 11: 9, 12: 5,
                     13: 6, 14: 4, 15: 7, 16: 7, 17: 8, 18: 8, 19: 2, 20: 14, 21: 21, 22: 10}
DIRECTIVES = ("1.1", "2.1", "3.1", *(f"4.{i}" for i in range(1, 15)))


def all_rules() -> list[str]:
    """Every rule ("10.4") and directive ("Dir 4.6") of MISRA C:2012 with Amendments 1, 2."""
    return ([f"{c}.{i}" for c, n in RULES_PER_CHAPTER.items() for i in range(1, n + 1)]
            + [f"Dir {d}" for d in DIRECTIVES])


def category(rule: str) -> str:
    """'Mandatory', 'Required' or 'Advisory' for a rule number such as '10.4'."""
    if rule in MANDATORY:
        return "Mandatory"
    return "Advisory" if rule in ADVISORY else "Required"


# the largest LSTM the GSA search can give (fogsf/training/net/gsa_search.py, gsa_space: layers
# 1..3, hidden 4..256; tests/test_misra.py checks these against it). Its NAME.c (21 MB, 1.3 M
# floats) is checked on request only (--gsa, `make misra MISRA_GSA=1`), in a cppcheck run of
# its own with its own time limit: cppcheck 2.10's time grows with the square of an
# initializer's length, and its five 262 144-float tables take hours (firmware/c/MISRA.md).
GSA_LAYERS = 3
GSA_HIDDEN = 256
GSA_TIMEOUT_S = 4 * 3600.0


def gsa_model() -> StreamModel:
    """The GSA-sized model: one filter, one feature, GSA_LAYERS x GSA_HIDDEN."""
    return samples.random_model(1, 1, GSA_LAYERS, GSA_HIDDEN, 50, seed=6)


def shapes() -> dict[str, StreamModel]:
    """One model of every shape the export writes (seeded: the same files every run)."""
    return {
        "misra_plain": samples.random_model(3, 4, 1, 16, 10, seed=1),
        "misra_bias": samples.random_model(11, 12, 1, 16, 50, seed=2, poly_head=True,
                                           lstm_inputs=1, quad_diag=True, feat_diag=True,
                                           bias_head=True),
        "misra_play": samples.random_model(2, 4, 1, 16, 10, seed=3, poly_head=True,
                                           bias_head=True, plays=(((0.2, 0.5, 0.3), 2.0),)),
        "misra_cross": samples.random_model(3, 4, 2, 8, 10, seed=4, poly_head=True),
        "misra_rate": samples.random_model(2, 4, 1, 16, 10, seed=5, poly_head=True,
                                           bias_head=True, rate_part=(8, 3)),
    }


@dataclass(frozen=True)
class Finding:
    file: str
    line: int
    rule: str  # "10.4", or a cppcheck id for its own errors
    category: str  # Mandatory, Required, Advisory, or "cppcheck" (an error of the tool)
    message: str


LINE_RE = re.compile(r"^(?P<file>[^\n]*?):(?P<line>\d+):(?P<sev>\w+):(?P<id>[\w.-]+):(?P<msg>.*)$")


def parse(text: str, root: Path) -> list[Finding]:
    out = []
    for line in text.splitlines():
        m = LINE_RE.match(line.strip())
        if not m:
            continue
        path = Path(m["file"])
        name = str(path.relative_to(root)) if path.is_relative_to(root) else path.name
        rule = m["id"].removeprefix("misra-c2012-")
        if m["id"].startswith("misra-c2012-"):
            out.append(Finding(name, int(m["line"]), rule, category(rule), m["msg"]))
        elif m["sev"] == "error":
            out.append(Finding(name, int(m["line"]), m["id"], "cppcheck", m["msg"]))
    return out


def run_cppcheck(files: list[Path], defines: dict[str, int], includes: list[Path],
                 root: Path, timeout: float = 900.0) -> list[Finding]:
    """cppcheck --addon=misra over the files in one configuration (-D for every macro the
    kernel tests: FLT_EVAL_METHOD as a C99 compiler for IEEE float32 defines it)."""
    if shutil.which(CPPCHECK) is None:
        raise UserError("cppcheck not found: `apt-get install cppcheck` (make toolchain)")
    # its dump files in a folder of the run's own, never beside the sources (a killed run
    # would leave them in the kernel's folder)
    with tempfile.TemporaryDirectory(prefix="cppcheck-", dir=root) as build:
        cmd = [CPPCHECK, "--addon=misra", "--std=c99", "--quiet", "--error-exitcode=0",
               f"--cppcheck-build-dir={build}",
               "--template={file}:{line}:{severity}:{id}:{message}", "-DFLT_EVAL_METHOD=0",
               *(f"-D{k}={v}" for k, v in defines.items()),
               *(f"-I{p}" for p in includes), *map(str, files)]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    return parse(proc.stdout + proc.stderr, root)


PLAIN_TYPE = re.compile(r"\b(int|short|long|signed|unsigned)\b")


def plain_integer_lines(paths: list[Path]) -> list[Finding]:
    """Lines of the kernel's sources that name a plain integer type (comments and strings
    left out): Dir 4.6 wants sized types, and without them no `int` can act as a boolean
    (Rules 10.1 and 14.4, which the addon does not check there)."""
    out = []
    for path in paths:
        text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m[0].count("\n"), path.read_text(),
                      flags=re.DOTALL)
        for no, line in enumerate(text.splitlines(), 1):
            code = re.sub(r'"(\\.|[^"\\])*"', '""', line.split("//")[0])
            if PLAIN_TYPE.search(code):
                out.append(Finding(path.name, no, "Dir 4.6", "Required",
                                   f"plain integer type in the kernel: {code.strip()}"))
    return out


def recorded_rules(md: Path = MISRA_MD) -> set[str]:
    """The rules firmware/c/MISRA.md records as kept: its bullets `- **Rule N.M**` and
    `- **Dir N.M**` (the coverage matrix and the prose name rules without recording them)."""
    text = md.read_text() if md.is_file() else ""
    return ({m for m in re.findall(r"^- \*\*Rule (\d+\.\d+)\*\*", text, flags=re.M)}
            | {f"Dir {m}" for m in re.findall(r"^- \*\*Dir (\d+\.\d+)\*\*", text, flags=re.M)})


MATRIX_ROW = re.compile(r"^\| ((?:Dir )?\d+\.\d+) \| (\w+) \| ([^|]+?) \|", re.M)


def matrix_problems(md: Path = MISRA_MD) -> list[str]:
    """Where MISRA.md's coverage matrix falls short: a Required or Mandatory rule it does not
    list, a row whose category is not the rule's, or one that says nothing checks it."""
    text = md.read_text() if md.is_file() else ""
    rows = {m[1]: (m[2], m[3].strip()) for m in MATRIX_ROW.finditer(text)}
    out = []
    for rule in all_rules():
        cat = category(rule)
        if cat == "Advisory":
            continue
        if rule not in rows:
            out.append(f"{cat} rule {rule} missing from {md.name}'s coverage matrix")
        elif rows[rule][0] != cat or not rows[rule][1]:
            out.append(f"{md.name}'s coverage matrix: rule {rule} is {cat}, checked by "
                       f"something: row says {rows[rule]}")
    return out


def _code(path: Path) -> str:
    """The file without its comments (newlines kept, so line numbers hold)."""
    return re.sub(r"/\*.*?\*/", lambda m: "\n" * m[0].count("\n"), path.read_text(),
                  flags=re.DOTALL)


def _params(text: str) -> list[str]:
    """The parameter names of a C parameter list (`void`: none)."""
    names = []
    for p in text.split(","):
        words = re.findall(r"\w+", p.split("[")[0])
        if words and words != ["void"]:
            names.append(words[-1])
    return names


FUNC_DECL = re.compile(r"^[\w \*]*?\b(\w+)\(([^()]*)\);", re.M)
FUNC_DEF = re.compile(r"^[\w \*]*?\b(\w+)\(([^()]*)\)\s*\{", re.M)


def parameter_names(header: Path, sources: list[Path]) -> list[Finding]:
    """Rule 8.3: each function fogsf.h declares has, where a source defines it, the same
    parameter names (the addon leaves this to cppcheck's style checks, which `make misra`
    does not run)."""
    declared = {m[1]: _params(m[2]) for m in FUNC_DECL.finditer(_code(header))}
    out = []
    for path in sources:
        code = _code(path)
        for m in FUNC_DEF.finditer(code):
            if m[1] in declared and _params(m[2]) != declared[m[1]]:
                out.append(Finding(path.name, code[:m.start()].count("\n") + 1, "8.3",
                                   "Required", f"{m[1]}: parameters {_params(m[2])} where "
                                   f"{header.name} declares {declared[m[1]]}"))
    return out


CAST_OF_EXPRESSION = re.compile(
    r"\(\s*(?:const\s+)?(?:u?int(?:8|16|32|64)_t|float|double|size_t|bool)\s*\)\s*\(")


def composite_casts(paths: list[Path]) -> list[Finding]:
    """Rule 10.8 made strict: no cast of a parenthesized expression in the kernel (a composite
    expression is computed in a variable of its own type, and the variable cast), which the
    addon misses for a float expression cast to int32_t."""
    out = []
    for path in paths:
        for no, line in enumerate(_code(path).splitlines(), 1):
            if CAST_OF_EXPRESSION.search(line):
                out.append(Finding(path.name, no, "10.8", "Required",
                                   f"a cast of a parenthesized expression: {line.strip()}"))
    return out


# gcc's warnings that check a MISRA rule (or part of one) the addon does not, as errors
WARNING_RULES = {"-Wshadow": "5.3", "-Wstrict-prototypes": "8.2", "-Wold-style-definition": "8.2",
                 "-Wmissing-prototypes": "8.4", "-Wuninitialized": "9.1",
                 "-Wmaybe-uninitialized": "9.1", "-Wcast-qual": "11.8",
                 "-Wsequence-point": "13.2", "-Wimplicit-fallthrough": "16.3",
                 "-Wswitch-default": "16.4", "-Wimplicit-function-declaration": "17.3",
                 "-Wreturn-type": "17.4", "-Wvla": "18.8", "-Wundef": "20.9"}


def compiler_warnings(cc: str = "gcc") -> list[Finding]:
    """The kernel's sources compiled with the strict flags and WARNING_RULES as errors, in
    the default and the even-time build: each warning a finding of its rule."""
    if shutil.which(cc) is None:
        return [Finding("-", 0, f"{cc}-missing", "cppcheck", f"{cc} not found")]
    out = []
    for extra in ((), (EVEN_TIME,)):
        for name in (*SOURCES, *LOADER):
            proc = subprocess.run([cc, *STRICT, "-O2", *WARNING_RULES, *extra, "-I", str(C_DIR),
                                   "-fsyntax-only", str(C_DIR / name)],
                                  capture_output=True, text=True)
            for m in re.finditer(r"^[^\n:]*:(\d+):\d+: (?:error|warning): (.*?)\[(-W[\w=-]+)\]",
                                 proc.stderr, flags=re.M):
                rule = WARNING_RULES.get(m[3].replace("-Werror=", "-W"), m[3])
                out.append(Finding(name, int(m[1]), rule, category(rule), m[2].strip()))
            if proc.returncode != 0 and not out:
                out.append(Finding(name, 0, "compile", "cppcheck", proc.stderr[-500:]))
    return out


def check(out: Path, extra: Sequence[Path] = (), gsa: bool = False
          ) -> tuple[list[Finding], list[str]]:
    """(findings, problems): problems are what makes `make misra` fail. gsa: the GSA-sized
    model too (gsa_model), in a cppcheck run of its own."""
    gen = out / "models"
    models = shapes()
    files = [C_DIR / n for n in (*SOURCES, *LOADER)]
    for name, model in models.items():
        write_model(model, gen, name)
        files.append(gen / f"{name}.c")
    files += list(extra)
    sizes = {k: max(state_sizes(m)[k] for m in models.values())
             for k in state_sizes(next(iter(models.values())))}
    findings = run_cppcheck(files, sizes, [C_DIR, gen], out)
    # the kernel again in its even-time build (FOGSF_EVEN_TIME: the spread step, the
    # branch-free tanh); a finding both builds report is counted once
    seen = {(f.file, f.line, f.rule) for f in findings}
    findings += [f for f in run_cppcheck([C_DIR / n for n in SOURCES],
                                         {**sizes, "FOGSF_EVEN_TIME": 1}, [C_DIR], out)
                 if (f.file, f.line, f.rule) not in seen]
    if gsa:
        big = gsa_model()
        write_model(big, gen, "misra_gsa")
        seen = {(f.file, f.line, f.rule) for f in findings}
        findings += [f for f in run_cppcheck([gen / "misra_gsa.c"], state_sizes(big),
                                             [C_DIR, gen], out, timeout=GSA_TIMEOUT_S)
                     if (f.file, f.line, f.rule) not in seen]
    kernel = [C_DIR / n for n in (*SOURCES, *LOADER, *KERNEL_HEADERS, LOADER_HEADER)]
    findings += plain_integer_lines(kernel)
    findings += parameter_names(C_DIR / "fogsf.h", kernel)
    findings += parameter_names(C_DIR / LOADER_HEADER, kernel)
    findings += composite_casts(kernel)
    findings += compiler_warnings()
    problems = [f"{f.file}:{f.line}: {f.category} {'rule ' if f.category != 'cppcheck' else ''}"
                f"{f.rule}: {f.message}" for f in findings
                if f.category in ("Mandatory", "Required", "cppcheck")]
    recorded = recorded_rules()
    for rule in sorted({f.rule for f in findings if f.category == "Advisory"} - recorded):
        problems.append(f"Advisory rule {rule} found but not recorded in {MISRA_MD.name}")
    problems += matrix_problems()
    return findings, problems


def report(findings: list[Finding], problems: list[str]) -> str:
    counts = Counter((f.category, f.rule) for f in findings)
    order = {"Mandatory": 0, "Required": 1, "cppcheck": 2, "Advisory": 3}
    lines = [f"  {cat:<9} {('Rule ' if not rule.startswith('Dir') and cat != 'cppcheck' else '')}"
             f"{rule:<8} {n:>4}" for (cat, rule), n in
             sorted(counts.items(), key=lambda kv: (order[kv[0][0]], _key(kv[0][1])))]
    by_cat = Counter(f.category for f in findings)
    lines.append("findings: " + ", ".join(f"{c} {by_cat.get(c, 0)}"
                                          for c in ("Mandatory", "Required", "Advisory")))
    lines += [f"  {p}" for p in problems]
    lines.append("FAIL" if problems else
                 f"PASS: no Mandatory or Required finding; every Advisory rule recorded in "
                 f"{MISRA_MD.name}")
    return "\n".join(lines)


def _key(rule: str) -> tuple:
    nums = re.findall(r"\d+", rule)
    return (rule.startswith("Dir"), *(int(n) for n in nums)) if nums else (2, rule)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.misra", description=__doc__)
    p.add_argument("--out", type=Path, default=Path("build/misra"))
    p.add_argument("--json", type=Path, default=None, help="also write the findings here")
    p.add_argument("--gsa", action="store_true",
                   help=f"also the GSA-sized model ({GSA_LAYERS}x{GSA_HIDDEN} LSTM, a 21 MB "
                        "NAME.c: cppcheck takes more than 15 minutes over it)")
    p.add_argument("extra", nargs="*", type=Path, help="more C files to check with the kernel")
    args = p.parse_args(argv)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        print(f"cppcheck --addon=misra (MISRA C:2012) on {', '.join((*SOURCES, *LOADER))} "
              f"and models {', '.join([*shapes(), *(['misra_gsa'] if args.gsa else [])])}")
        findings, problems = check(args.out.resolve(), args.extra, args.gsa)
    except (UserError, subprocess.TimeoutExpired) as e:
        print(f"misra: error: {e}", file=sys.stderr)
        return 2
    print(report(findings, problems))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"findings": [asdict(f) for f in findings],
                                         "problems": problems}, indent=1))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
