"""`fogsf plan --prior FLEET --target X`: the shortest program that reaches X times the noise
floor for a new unit of the design.

Units are drawn from the design's prior (theta ~ N(mu, Sigma): time constants and law of
its physics nodes) and simulated at the model rate: the board temperature follows the
chamber through the default gyro's housing and board lags (the prior knows the unit from
its board thermometer on, not the chamber's air), the SF error is the unit's law plus white
noise at the fleet's median residual level per step. Each candidate program of the planner
(`plan.programs.candidates`, shortest first) is fitted under the prior (its posterior mean
response, `response_prior.function_fit`, as `fogsf train --prior` fits it, the run's noise
taken NOISE_SCALE times its level, the posterior mean read directly rather than through the
law it exports) and scored on the planner's test loops across the envelope: sqrt(floor^2 +
the law's error over 100 s windows) / floor. The first program whose median over units and
rates is at or under the target is the answer.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsf.models.features import MODEL_STEP_S, T_REF_C
from fogsf.models.structures.node_fit import discrete_lag, lag_alpha
from fogsf.plan.evaluate import envelope_program
from fogsf.plan.programs import Limits, Program, candidates, write_program_csv
from fogsf.prior.design_prior import DesignPrior
from fogsf.prior.response_prior import function_fit
from fogsf.prior.unit_fit import Play, StepSeries, all_steps, design_matrix, window_means
from fogsf.sim.config import ThermalConfig

FINE_S = 1.0  # the chamber's path through the housing and board lags at this step


def board_steps(points: tuple[tuple[float, float], ...], step_s: float = MODEL_STEP_S
                ) -> np.ndarray:
    """The board temperature's block means minus T_REF_C per model step of a run: the
    chamber path through the default gyro's housing and board lags, from equilibrium."""

    nodes = {n.name: n for n in ThermalConfig().nodes}
    t_end = points[-1][0]
    t = np.arange(0.0, t_end, FINE_S)
    air = np.interp(t, [p[0] for p in points], [p[1] for p in points])
    housing = discrete_lag(air, lag_alpha(nodes["housing"].tau_s, FINE_S))
    board = discrete_lag(housing, lag_alpha(nodes["board"].tau_s, FINE_S))
    per = int(round(step_s / FINE_S))
    n = board.size // per
    return board[:n * per].reshape(n, per).mean(axis=1) - T_REF_C


@dataclass
class PlanResult:
    program: Program
    median: float
    worst: float
    ratios: list[float]


def _series(runs: list[np.ndarray], theta: np.ndarray | None, k: int, noise: float,
            rng: np.random.Generator | None, play: Play | None = None) -> StepSeries:
    n = sum(r.size for r in runs)
    s = all_steps(StepSeries(runs, np.zeros(0), np.zeros(0, dtype=np.int64), MODEL_STEP_S))
    if theta is not None:
        s.y = design_matrix(s, np.exp(theta[:k]), play) @ theta[k:]
        if rng is not None:
            s.y = s.y + rng.normal(0.0, noise, n)
    return s


def _ratio(err: np.ndarray, noise: float) -> float:
    means, w = window_means(err, MODEL_STEP_S)
    mse = float(np.mean(means**2))
    floor2 = noise**2 / w
    return math.sqrt((floor2 + mse) / floor2)


def draw_units(prior: DesignPrior, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng([seed, 0x9A11])
    return [rng.multivariate_normal(prior.mu, prior.sigma, check_valid="ignore")
            for _ in range(n)]


def evaluate(program: Program, prior: DesignPrior, units: list[np.ndarray],
             tests: list[np.ndarray], seed: int) -> PlanResult:
    k = prior.k
    noise = math.sqrt(prior.step_noise_ppm2)
    runs = [board_steps(r) for r in program.runs]
    ratios = []
    for i, theta in enumerate(units):
        rng = np.random.default_rng([seed, i])
        ff = function_fit(_series(runs, theta, k, noise, rng, prior.play), prior, noise**2)
        for t in tests:
            s = _series([t], None, k, noise, None)
            truth = design_matrix(s, np.exp(theta[:k]), prior.play) @ theta[k:]
            pred = ff.predict(s)
            ratios.append(_ratio(pred - truth, noise))
    return PlanResult(program, float(np.median(ratios)), float(np.max(ratios)), ratios)


def shortest(prior: DesignPrior, limits: Limits, rates: tuple[float, ...], target: float,
             n_units: int = 6, seed: int = 0,
             progress: Callable[[PlanResult], None] | None = None
             ) -> tuple[PlanResult | None, list[PlanResult]]:
    """The shortest candidate whose median reaches `target`, and every program tried."""

    units = draw_units(prior, n_units, seed)
    tests = [board_steps(run) for run in envelope_program(limits, rates).runs]
    tried: list[PlanResult] = []
    for p in sorted(candidates(limits), key=lambda p: (p.hours, p.name)):
        res = evaluate(p, prior, units, tests, seed)
        tried.append(res)
        if progress is not None:
            progress(res)
        if res.median <= target:
            return res, tried
    return None, tried


def write(out: Path, best: PlanResult | None, tried: list[PlanResult], meta: dict) -> None:
    """OUT/program.csv (the program found) and OUT/plan-prior.json (every program tried)."""

    out.mkdir(parents=True, exist_ok=True)
    if best is not None:
        for i, run in enumerate(best.program.runs):
            name = "program.csv" if len(best.program.runs) == 1 else f"program-run{i + 1}.csv"
            write_program_csv(out / name, run)
    rows = [{"program": r.program.name, "hours": r.program.hours, "median": r.median,
             "worst": r.worst} for r in tried]
    tmp = out / "plan-prior.json.tmp"
    tmp.write_text(json.dumps({**meta, "found": best.program.name if best else None,
                               "tried": rows}, indent=2) + "\n")
    tmp.replace(out / "plan-prior.json")
