"""The search: every candidate program on every gyro, ranked (the grid of templates)."""

from __future__ import annotations

from concurrent.futures import Executor

from trainer.executors import run_all
from trainer.plan.evaluate import evaluate_gyro, interval_gyro
from trainer.plan.programs import Limits, Program, candidates, paper_protocol
from trainer.plan.report import Scored, score


def search(limits: Limits, rates: tuple[float, ...], seeds: list[int], ex: Executor | None,
           interval_gyros: int = 0, extra: list[Program] | None = None,
           progress: bool = True) -> tuple[list[Scored], Scored]:
    """Every candidate (and `extra`) ranked best first, and the paper's protocol, scored on
    `seeds`; with `interval_gyros`, the three best and the paper's get the rate-transfer
    interval's upper end (median over that many gyros, at the envelope's middle rate)."""
    progs = candidates(limits) + list(extra or [])
    paper = paper_protocol(limits)
    results = run_all(ex, evaluate_gyro, seeds, [paper, *progs], limits, rates,
                      desc="gyros", unit="gyro", progress=progress)
    ranked = score(progs, results)
    (paper_s,) = score([paper], results)
    if interval_gyros > 0:
        shown = [*ranked[:3], paper_s]
        iv = run_all(ex, interval_gyro, seeds[:interval_gyros], [s.program for s in shown],
                     limits, rates[len(rates) // 2], desc="intervals", unit="gyro",
                     progress=progress)
        for s in shown:
            s.interval_x_floor = float(sorted(r[s.program.name] for r in iv)[len(iv) // 2])
    return ranked, paper_s
