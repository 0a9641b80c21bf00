"""Build and run the libFuzzer harness of the block loader (firmware/c/fuzz/fuzz_block.c).

`python -m fogsf.bindings.fuzz_block --out build/fuzz-block --inputs 10000000` compiles the
harness with clang -fsanitize=fuzzer,address,undefined (strict C99 flags) and the kernel's
state sized for small models, writes seed blocks of four small models (plain; polynomial and
bias heads with a play on two layers; the diagonal quadratic and feature map on z[0:1]; a
rate part with R 3 of the state's 4), each as given, resealed and shifted (the harness's mode
byte), then fuzzes in rounds until the harness has loaded at least --inputs blocks. A
sanitizer finding or a broken promise (a block accepted that fogsf_init refuses, a
non-finite output, a refused block leaving a model) stops it with the input in
OUT/crashes/.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path

from fogsf.bindings.block import BLOCK_SOURCES
from fogsf.bindings.fuzz import FUZZ_DIR, FUZZ_FLAGS
from fogsf.bindings.kernel import C_DIR, SOURCES, STRICT
from fogsf.errors import UserError
from fogsf.export.block import block_bytes
from fogsf.models import samples
from fogsf.models.stream import StreamModel

BLOCK_MAX = ("-DFOGSF_MAX_LAYERS=2", "-DFOGSF_MAX_HIDDEN=4", "-DFOGSF_MAX_FEATURES=4",
             "-DFOGSF_MAX_FILTERS=2", "-DFOGSF_MAX_PLAYS=2", "-DFOGSF_MAX_RATE_ROWS=4")
INPUTS_RE = re.compile(r"fuzz blocks: (\d+) \(accepted (\d+)\)")
PLAY = (((0.2, 0.5, 0.3), 2.0),)


def seed_models() -> dict[str, StreamModel]:
    """Small models that fit BLOCK_MAX, every optional table present in one of them."""
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


def build_block_fuzzer(out: Path, cc: str = "clang") -> Path:
    if shutil.which(cc) is None:
        raise UserError(f"{cc} not found: the fuzzer needs clang with libFuzzer "
                        "(run `make toolchain` as root)")
    out.mkdir(parents=True, exist_ok=True)
    exe = out / "fuzz_block"
    srcs = [FUZZ_DIR / "fuzz_block.c", *(C_DIR / n for n in (*SOURCES, *BLOCK_SOURCES))]
    cmd = [cc, *STRICT, *FUZZ_FLAGS, *BLOCK_MAX, "-I", str(C_DIR), *map(str, srcs),
           "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"building the block fuzzer failed: {' '.join(cmd)}\n{proc.stderr}")
    return exe


def run_round(exe: Path, args: list[str], timeout: float = 7200.0) -> tuple[int, str, int, int]:
    """(exit code, output, blocks loaded, blocks accepted) of one libFuzzer run."""
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout)
    text = proc.stdout + proc.stderr
    found = INPUTS_RE.findall(text)
    n, ok = (int(found[-1][0]), int(found[-1][1])) if found else (0, 0)
    return proc.returncode, text, n, ok


def fuzz_block(out: Path, inputs: int, seed: int = 1, per_round: int = 1_000_000) -> int:
    exe = build_block_fuzzer(out)
    seeds = write_seeds(out / "seeds")
    rc, text, n, ok = run_round(exe, sorted(map(str, seeds.iterdir())))
    print(f"seeds {seeds}: exit {rc}, {n} blocks, {ok} accepted")
    if rc != 0 or ok == 0:
        print(text[-4000:])
        return 1
    work, crashes = out / "corpus", out / "crashes"
    work.mkdir(exist_ok=True)
    crashes.mkdir(exist_ok=True)
    total = accepted = rnd = 0
    while total < inputs:
        runs = min(per_round, inputs - total)
        rc, text, n, ok = run_round(exe, [f"-seed={seed + rnd}", f"-runs={runs}",
                                          "-max_len=8192", f"-artifact_prefix={crashes}/",
                                          "-print_final_stats=0", str(work), str(seeds)])
        total, accepted, rnd = total + n, accepted + ok, rnd + 1
        print(f"round {rnd}: {n} blocks, {ok} accepted (total {total} of {inputs}), "
              f"exit {rc}", flush=True)
        if rc != 0:
            print(text[-4000:])
            print(f"FAIL: sanitizer finding or broken promise; input in {crashes}")
            return 1
    print(f"PASS: {total} blocks fuzzed ({accepted} accepted and stepped), no finding")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.bindings.fuzz_block", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m fogsf.bindings.fuzz_block --out "
                                       "build/fuzz-block --inputs 100000")
    p.add_argument("--out", type=Path, default=Path("build/fuzz-block"), help="build folder")
    p.add_argument("--inputs", type=int, default=10_000_000,
                   help="fuzz until the harness has loaded this many blocks (default 1e7)")
    p.add_argument("--seed", type=int, default=1, help="libFuzzer seed of the first round")
    args = p.parse_args(argv)
    try:
        return fuzz_block(args.out, args.inputs, args.seed)
    except UserError as e:
        print(f"fuzz_block: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
