"""Build and run a libFuzzer harness: the C kernel's (`--target step`,
firmware/c/fuzz/fuzz_step.c) or the calibration block loader's (`--target block`,
firmware/c/fuzz/fuzz_block.c).

`python -m fogsf.bindings.fuzz --out build/fuzz --steps 10000000` is what `make fuzz` runs: it
compiles the step harness with clang -fsanitize=fuzzer,address,undefined (strict C99 flags)
and a generated model (`fuzz_model`, 1x16 with the polynomial head, a model step every 2
samples, stuck detection after 5), replays the committed regression corpus
firmware/c/fuzz/corpus/, then fuzzes in rounds until the harness has made at least --steps
fogsf_step calls. Any sanitizer finding or totality violation stops it with the crash input
in OUT/crashes/.

`python -m fogsf.bindings.fuzz --target block --out build/fuzz-block --inputs 10000000` is
`make fuzz-block`: the block harness with the kernel's state sized for small models, seed
blocks of four small models (plain; polynomial and bias heads with a play on two layers; the
diagonal quadratic and feature map on z[0:1]; a rate part with R 3 of the state's 4), each as
given, resealed and shifted (the harness's mode byte), then rounds until it has loaded at
least --inputs blocks. A sanitizer finding or a broken promise (a block accepted that
fogsf_init refuses, a non-finite output, a refused block leaving a model) stops it with the
input in OUT/crashes/.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from fogsf.bindings.block import BLOCK_SOURCES
from fogsf.bindings.kernel import C_DIR, EVEN_TIME, SOURCES, STRICT
from fogsf.errors import UserError
from fogsf.export.block import block_bytes
from fogsf.export.header import write_model
from fogsf.models import samples
from fogsf.models import stream as st

FUZZ_DIR = C_DIR / "fuzz"
CORPUS = FUZZ_DIR / "corpus"
FUZZ_FLAGS = ("-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", "-g", "-O1")
FUZZ_MAX = ("-DFOGSF_MAX_LAYERS=2", "-DFOGSF_MAX_HIDDEN=16", "-DFOGSF_MAX_FEATURES=4",
            "-DFOGSF_MAX_FILTERS=4", "-DFOGSF_MAX_PLAYS=2")
BLOCK_MAX = ("-DFOGSF_MAX_LAYERS=2", "-DFOGSF_MAX_HIDDEN=4", "-DFOGSF_MAX_FEATURES=4",
             "-DFOGSF_MAX_FILTERS=2", "-DFOGSF_MAX_PLAYS=2", "-DFOGSF_MAX_RATE_ROWS=4")
STEPS_RE = re.compile(r"fuzz steps: (\d+)")
INPUTS_RE = re.compile(r"fuzz blocks: (\d+) \(accepted (\d+)\)")
PLAY = (((0.2, 0.5, 0.3), 2.0),)


@dataclass(frozen=True)
class Target:
    """One harness: its source, the kernel's sizes, what it counts and how it says so."""
    name: str
    harness: str
    sizes: tuple[str, ...]
    max_len: int
    seeds: str  # what the first run replays, for its line
    fail: str  # what a non-zero exit means


TARGETS = {
    "step": Target("step", "fuzz_step", FUZZ_MAX, 4096, "regression corpus",
                   "sanitizer finding or totality violation"),
    "block": Target("block", "fuzz_block", BLOCK_MAX, 8192, "seeds",
                    "sanitizer finding or broken promise"),
}


def fuzz_model() -> st.StreamModel:
    return samples.random_model(1, 1, 1, 16, decimation=2, seed=11, stuck_samples=5,
                                poly_head=True)


def seed_models() -> dict[str, st.StreamModel]:
    """The block target's seeds: small models that fit BLOCK_MAX, every optional table
    present in one of them."""
    return {
        "plain": samples.random_model(1, 2, 1, 4, 2, seed=1, stuck_samples=5),
        "heads_play": samples.random_model(2, 4, 2, 4, 2, seed=2, poly_head=True,
                                           bias_head=True, plays=PLAY, stuck_samples=5),
        "diag": samples.random_model(2, 4, 1, 4, 2, seed=3, poly_head=True, quad_diag=True,
                                     feat_diag=True, lstm_inputs=1, plays=PLAY),
        "rate": samples.random_model(2, 3, 1, 4, 2, seed=4, bias_head=True, rate_part=(3, 2),
                                     rate_fs_dps=20.0, stuck_samples=5),
    }


def write_seeds(out: Path) -> Path:
    """One file a model and mode (0 as given, 1 resealed, 2 shifted): the mode byte first."""
    out.mkdir(parents=True, exist_ok=True)
    for name, model in seed_models().items():
        data = block_bytes(model)
        for mode in (0, 1, 2):
            (out / f"{name}_mode{mode}").write_bytes(bytes([mode]) + data)
    return out


def build_fuzzer(out: Path, cc: str = "clang", even_time: bool = False,
                 target: str = "step") -> Path:
    """The harness binary (cached by nothing: a build takes a few seconds); `even_time`:
    against the kernel built with FOGSF_EVEN_TIME."""
    t = TARGETS[target]
    if shutil.which(cc) is None:
        raise UserError(f"{cc} not found: the fuzzer needs clang with libFuzzer "
                        "(run `make toolchain` as root)")
    out.mkdir(parents=True, exist_ok=True)
    exe = out / t.harness
    srcs = [FUZZ_DIR / f"{t.harness}.c", *(C_DIR / name for name in SOURCES)]
    if target == "step":
        write_model(fuzz_model(), out, "fuzz_model")
        srcs.append(out / "fuzz_model.c")
    else:
        srcs += [C_DIR / name for name in BLOCK_SOURCES]
    cmd = [cc, *STRICT, *FUZZ_FLAGS, *t.sizes, *((EVEN_TIME,) if even_time else ()),
           "-I", str(out), "-I", str(C_DIR), *map(str, srcs), "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"building the fuzzer failed: {' '.join(cmd)}\n{proc.stderr}")
    return exe


def run_round(exe: Path, args: list[str], timeout: float = 7200.0) -> tuple[int, str, int, int]:
    """(exit code, output, count, blocks accepted) of one libFuzzer run: the count is
    fogsf_step calls for the step harness, blocks loaded for the block harness."""
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout)
    text = proc.stdout + proc.stderr
    blocks = INPUTS_RE.findall(text)
    if blocks:
        return proc.returncode, text, int(blocks[-1][0]), int(blocks[-1][1])
    steps = STEPS_RE.findall(text)
    return proc.returncode, text, int(steps[-1]) if steps else 0, 0


def run_fuzzer(exe: Path, args: list[str], timeout: float = 3600.0) -> tuple[int, str, int]:
    """(exit code, output, fogsf_step calls) of one run of the step harness."""
    rc, text, n, _ = run_round(exe, args, timeout)
    return rc, text, n


def regression(exe: Path) -> tuple[int, str, int]:
    """Every committed corpus input once (libFuzzer runs files given as arguments)."""
    files = sorted(str(p) for p in CORPUS.iterdir() if p.is_file())
    return run_fuzzer(exe, files) if files else (0, "no corpus", 0)


def counted(target: str, n: int, ok: int) -> str:
    return f"{n} steps" if target == "step" else f"{n} blocks, {ok} accepted"


def fuzz(out: Path, count: int, seed: int = 1, per_round: int = 0, even_time: bool = False,
         target: str = "step") -> int:
    """The seeds once, then rounds until `count` (fogsf_step calls or blocks): a step round
    is `per_round` runs (default 20 000, each many steps), a block round at most `per_round`
    blocks (default 1e6)."""
    t = TARGETS[target]
    exe = build_fuzzer(out, even_time=even_time, target=target)
    seeds = CORPUS if target == "step" else write_seeds(out / "seeds")
    rc, text, n, ok = run_round(exe, sorted(str(p) for p in seeds.iterdir() if p.is_file()))
    print(f"{t.seeds} {seeds}: exit {rc}, {counted(target, n, ok)}")
    if rc != 0 or (target == "block" and ok == 0):
        print(text[-4000:])
        return 1
    work, crashes = out / "corpus", out / "crashes"
    work.mkdir(exist_ok=True)
    crashes.mkdir(exist_ok=True)
    per_round = per_round or (20_000 if target == "step" else 1_000_000)
    total = accepted = rnd = 0
    while total < count:
        runs = per_round if target == "step" else min(per_round, count - total)
        rc, text, n, ok = run_round(exe, [f"-seed={seed + rnd}", f"-runs={runs}",
                                          f"-max_len={t.max_len}", f"-artifact_prefix={crashes}/",
                                          "-print_final_stats=0", str(work), str(seeds)])
        total, accepted, rnd = total + n, accepted + ok, rnd + 1
        print(f"round {rnd}: {counted(target, n, ok)} (total {total} of {count}), exit {rc}",
              flush=True)
        if rc != 0:
            print(text[-4000:])
            print(f"FAIL: {t.fail}; input in {crashes}")
            return 1
    print(f"PASS: {total} fogsf_step calls fuzzed, no sanitizer finding" if target == "step"
          else f"PASS: {total} blocks fuzzed ({accepted} accepted and stepped), no finding")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.fuzz", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m fogsf.bindings.fuzz --out build/fuzz "
                                       "--steps 100000")
    p.add_argument("--target", choices=tuple(TARGETS), default="step",
                   help="the kernel's step harness (default) or the block loader's")
    p.add_argument("--out", type=Path, default=None,
                   help="build folder (default build/fuzz, build/fuzz-block)")
    p.add_argument("--steps", "--inputs", dest="count", type=int, default=10_000_000,
                   help="fuzz until this many fogsf_step calls (step) or blocks loaded "
                        "(block); default 1e7")
    p.add_argument("--seed", type=int, default=1, help="libFuzzer seed of the first round")
    p.add_argument("--even-time", action="store_true",
                   help="fuzz the kernel's even-time build (FOGSF_EVEN_TIME)")
    args = p.parse_args(argv)
    out = args.out or Path("build/fuzz" if args.target == "step" else "build/fuzz-block")
    try:
        return fuzz(out, args.count, args.seed, even_time=args.even_time, target=args.target)
    except UserError as e:
        print(f"fuzz: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
