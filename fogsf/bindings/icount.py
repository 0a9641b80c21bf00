"""Instructions per sample of an image's fogsf_step calls, counted exactly under QEMU.

The bench image (firmware/c/arm/bench_main.c) brackets each of its 2D + 1 samples with calls
to fogsf_bench_begin / fogsf_bench_end; QEMU run with -singlestep and -d exec,nochain traces
one line per instruction, so the lines between the markers are that sample's instructions
(deterministic: the same image gives the same counts). `make firmware-cores` and `make bench`
print these.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

from fogsf.bindings.firmware import M4F, Core, qemu_cmd
from fogsf.errors import UserError


def counts_of(bench_elf: Path, decimation: int, core: Core = M4F) -> list[int]:
    """The instructions of each of the 2D + 1 samples of the bench image, in order."""
    cmd = qemu_cmd(bench_elf, "-singlestep", "-d", "exec,nochain", machine=core.machine)
    counts: list[int] = []
    inside, n = False, 0
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          bufsize=1 << 20) as proc:
        assert proc.stdout is not None
        for line in proc.stdout:
            if not line.startswith("Trace"):
                continue
            sym = line.rsplit(" ", 1)[-1].strip()
            if sym == "fogsf_bench_begin":
                inside, n = True, 0
            elif sym == "fogsf_bench_end":
                if inside:
                    counts.append(n)
                inside = False
            elif inside:
                n += 1
    if proc.returncode != 0 or len(counts) != 2 * decimation + 1:
        raise UserError(f"instruction count: QEMU exited {proc.returncode} with "
                        f"{len(counts)} marked calls (expected {2 * decimation + 1})")
    return counts


@dataclass(frozen=True)
class SampleCounts:
    worst: int  # over every sample counted (with FOGSF_EVEN_TIME any may be the worst)
    mean: float  # over one steady decimation period, samples D+1 .. 2D
    non_step_worst: int  # over the samples that start no model step

    @property
    def worst_over_mean(self) -> float:
        return self.worst / self.mean


def sample_counts(bench_elf: Path, decimation: int, core: Core = M4F) -> SampleCounts:
    """Worst, mean and non-step worst instructions per sample: calls 0, D and 2D start a
    model step; the bench image plants every front-end path among the others."""
    counts = counts_of(bench_elf, decimation, core)
    period = counts[decimation + 1:2 * decimation + 1]
    plain = max((c for i, c in enumerate(counts) if i % decimation != 0), default=0)
    return SampleCounts(max(counts), sum(period) / len(period), plain)
