"""Build and run the libFuzzer harness of the C kernel (firmware/c/fuzz/fuzz_step.c).

`python -m fogsf.bindings.fuzz --out build/fuzz --steps 10000000` is what `make fuzz` runs: it
compiles the harness with clang -fsanitize=fuzzer,address,undefined (strict C99 flags) and a
generated model (`fuzz_model`, 1x16 with the polynomial head, a model step every 2 samples,
stuck detection after 5), replays the committed regression corpus firmware/c/fuzz/corpus/,
then fuzzes in rounds until the harness has made at least --steps fogsf_step calls. Any
sanitizer finding or totality violation stops it with the crash input in OUT/crashes/.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path

from fogsf.bindings.kernel import C_DIR, EVEN_TIME, SOURCES, STRICT
from fogsf.errors import UserError
from fogsf.export.header import write_model
from fogsf.models import samples
from fogsf.models import stream as st

FUZZ_DIR = C_DIR / "fuzz"
CORPUS = FUZZ_DIR / "corpus"
FUZZ_FLAGS = ("-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", "-g", "-O1")
FUZZ_MAX = ("-DFOGSF_MAX_LAYERS=2", "-DFOGSF_MAX_HIDDEN=16", "-DFOGSF_MAX_FEATURES=4",
            "-DFOGSF_MAX_FILTERS=4", "-DFOGSF_MAX_PLAYS=2")
STEPS_RE = re.compile(r"fuzz steps: (\d+)")


def fuzz_model() -> st.StreamModel:
    return samples.random_model(1, 1, 1, 16, decimation=2, seed=11, stuck_samples=5,
                           poly_head=True)


def build_fuzzer(out: Path, cc: str = "clang", even_time: bool = False) -> Path:
    """The harness binary (cached by nothing: a build takes a few seconds); `even_time`:
    against the kernel built with FOGSF_EVEN_TIME."""
    if shutil.which(cc) is None:
        raise UserError(f"{cc} not found: the fuzzer needs clang with libFuzzer "
                        "(run `make toolchain` as root)")
    out.mkdir(parents=True, exist_ok=True)
    write_model(fuzz_model(), out, "fuzz_model")
    exe = out / "fuzz_step"
    srcs = [FUZZ_DIR / "fuzz_step.c", *(C_DIR / name for name in SOURCES),
            out / "fuzz_model.c"]
    cmd = [cc, *STRICT, *FUZZ_FLAGS, *FUZZ_MAX, *((EVEN_TIME,) if even_time else ()),
           "-I", str(out), "-I", str(C_DIR),
           *map(str, srcs), "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"building the fuzzer failed: {' '.join(cmd)}\n{proc.stderr}")
    return exe


def run_fuzzer(exe: Path, args: list[str], timeout: float = 3600.0) -> tuple[int, str, int]:
    """(exit code, output, fogsf_step calls) of one libFuzzer run."""
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout)
    text = proc.stdout + proc.stderr
    found = STEPS_RE.findall(text)
    return proc.returncode, text, int(found[-1]) if found else 0


def regression(exe: Path) -> tuple[int, str, int]:
    """Every committed corpus input once (libFuzzer runs files given as arguments)."""
    files = sorted(str(p) for p in CORPUS.iterdir() if p.is_file())
    return run_fuzzer(exe, files) if files else (0, "no corpus", 0)


def fuzz(out: Path, steps: int, seed: int = 1, runs_per_round: int = 20000,
         even_time: bool = False) -> int:
    exe = build_fuzzer(out, even_time=even_time)
    rc, text, n = regression(exe)
    print(f"regression corpus {CORPUS}: exit {rc}, {n} steps")
    if rc != 0:
        print(text[-4000:])
        return 1
    work = out / "corpus"
    work.mkdir(exist_ok=True)
    crashes = out / "crashes"
    crashes.mkdir(exist_ok=True)
    total, rnd = 0, 0
    while total < steps:
        rc, text, n = run_fuzzer(exe, [f"-seed={seed + rnd}", f"-runs={runs_per_round}",
                                       "-max_len=4096", f"-artifact_prefix={crashes}/",
                                       "-print_final_stats=0", str(work), str(CORPUS)])
        total += n
        rnd += 1
        print(f"round {rnd}: {n} steps (total {total} of {steps}), exit {rc}", flush=True)
        if rc != 0:
            print(text[-4000:])
            print(f"FAIL: sanitizer finding or totality violation; input in {crashes}")
            return 1
    print(f"PASS: {total} fogsf_step calls fuzzed, no sanitizer finding")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.fuzz", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m fogsf.bindings.fuzz --out build/fuzz "
                                       "--steps 100000")
    p.add_argument("--out", type=Path, default=Path("build/fuzz"), help="build folder")
    p.add_argument("--steps", type=int, default=10_000_000,
                   help="fuzz until this many fogsf_step calls (default 1e7)")
    p.add_argument("--seed", type=int, default=1, help="libFuzzer seed of the first round")
    p.add_argument("--even-time", action="store_true",
                   help="fuzz the kernel's even-time build (FOGSF_EVEN_TIME)")
    args = p.parse_args(argv)
    try:
        return fuzz(args.out, args.steps, args.seed, even_time=args.even_time)
    except UserError as e:
        print(f"fuzz: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
