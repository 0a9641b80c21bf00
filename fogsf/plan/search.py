"""The search: every candidate program on every gyro, ranked (the grid of templates)."""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np

from fogsf.gsa.executors import run_all
from fogsf.plan.evaluate import evaluate_gyro, interval_gyro
from fogsf.plan.programs import Limits, candidates, paper_protocol
from fogsf.plan.report import Scored, score
from fogsf.sim.config import SimConfig


def search(limits: Limits, rates: tuple[float, ...], gyros: list[tuple[int, int | SimConfig]],
           ex: Executor | None, interval_gyros: int = 0, axes: int = 1,
           progress: bool = True) -> tuple[list[Scored], Scored]:
    """Every candidate ranked best first, and the paper's protocol, scored on `gyros`
    ((noise seed, population seed or gyro) pairs; with `axes` > 1, consecutive groups of that
    many gyros are one IMU, scored by its worst axis); with `interval_gyros`, the three best
    and the paper's get the rate-transfer interval's upper end (median over that many gyros,
    at the envelope's middle rate)."""
    progs = candidates(limits)
    paper = paper_protocol(limits)
    results = run_all(ex, evaluate_gyro, gyros, [paper, *progs], limits, rates,
                      desc="gyros", unit="gyro", progress=progress)
    ranked = score(progs, results, axes)
    (paper_s,) = score([paper], results, axes)
    if interval_gyros > 0:
        shown = [*ranked[:3], paper_s]
        iv = run_all(ex, interval_gyro, gyros[:interval_gyros], [s.program for s in shown],
                     limits, rates[len(rates) // 2], desc="intervals", unit="gyro",
                     progress=progress)
        for s in shown:
            s.interval_x_floor = float(np.median([r[s.program.name] for r in iv]))
    return ranked, paper_s
