"""`fogsf train --prior FLEET`: a new unit fitted under its design's prior.

The prior is learned from the fleet database's unit summaries (`design_prior.learn`); the unit's
response is its posterior under the prior in the space of responses
(`response_prior.function_fit`), its physics-node law (`FunctionFit.law`) carried exactly in
the default model's polynomial head, the LSTM on what it leaves (as `fogsf train`'s lag-lstm:
its validation keeps the least-squares start where the LSTM does not earn its place). The
model directory is an ordinary model (no firmware change). When the unit's data disagree
with the design (`MapFit.disagrees`, the check of the unit's parameters against the
design's, `map_estimate.map_fit`), the unit is fitted alone, as `fogsf train` would.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import front_end_for, prepare
from fogsf.models.reference import expand
from fogsf.models.structures.node_fit import RidgeFit
from fogsf.models.structures.physics_nodes import NODE_LAMBDA, head_from_ridge
from fogsf.prior.design_prior import DesignPrior, learn
from fogsf.prior.map_estimate import DISAGREE_LEVEL, NOISE_SCALE, map_fit
from fogsf.prior.response_prior import FunctionFit, function_fit
from fogsf.prior.unit_fit import (
    Play,
    StepSeries,
    UnitFit,
    all_steps,
    design_matrix,
    step_series,
)
from fogsf.prior.unit_summary import series_of
from fogsf.training.fitted_model import Fitted
from fogsf.training.metrics_file import write_metrics
from fogsf.training.options import TrainOptions
from fogsf.training.sf.fit import fit_physics_head
from fogsf.training.train import run_training


def prior_from_summaries(summaries: dict[str, dict]) -> DesignPrior:
    """The design's prior from units' `unit_summary` dicts (by unit name)."""
    series = {sn: series_of(s) for sn, s in summaries.items()}
    first: dict[int, dict[str, UnitFit]] = {}
    for sn, s in summaries.items():
        for k, f in s.get("fits", {}).items():
            first.setdefault(int(k), {})[sn] = UnitFit.from_dict(f)
    return learn(series, first=first)


# the interval's upper end: the floor and this many posterior standard deviations of the
# response and of its misfit on the unit's own runs (`benchmarks.probes.fleet_response_prior`;
# benchmarks/probes/README.md, "Fleet prior: where it stops")
INTERVAL_Z = 2.0
# `train --prior` says the design's structure misses the fleet's units when it leaves more
# than this on their own programs (`DesignPrior.structure_misfit`, 1: noise only): there the
# prior's figures are not to be trusted (benchmarks/probes/README.md, "Fleet structure: the
# nodes' cubes")
STRUCTURE_MISS = 1.2






def train_with_prior(opts: TrainOptions, train_logs: list[ChamberLog],
                     test_log: ChamberLog | None, out_dir: Path, prior: DesignPrior
                     ) -> tuple[dict, Fitted]:
    """Train the unit under `prior` (or alone, when its data disagree with the design);
    metrics.json gains `prior` (what the prior carried, the check, the interval)."""

    series = step_series(train_logs, opts.model_step_s, opts.latitude_deg)
    mf = map_fit(series, prior)
    rec = {"used": not mf.disagrees, "units": len(prior.units), "left_out": prior.left_out,
           "nodes": prior.k, "design_taus_s": np.exp(prior.mu[:prior.k]).tolist(),
           "structure_misfit": prior.structure_misfit, "noise_scale": NOISE_SCALE,
           "level": DISAGREE_LEVEL, **mf.as_dict()}
    if mf.disagrees:
        metrics, fitted = run_training(opts, train_logs, test_log, out_dir)
    else:
        ff = function_fit(series, prior, mf.s2)
        theta = ff.law()
        taus = tuple(float(t) for t in np.exp(theta[:prior.k]))
        rec["taus_s"], rec["theta"] = list(taus), theta.tolist()
        term = None if prior.play is None else prior.play.term(np.asarray(taus))
        if term is not None:
            rec["play"] = term.as_dict()

        def head(ti):  # noqa: ANN001, ANN202 - training.train.TrainingInputs / NodeFit
            return law_head(theta, prior.k, ti.offset, ti.scale, term is not None)

        metrics, fitted = run_training(
            opts, train_logs, test_log, out_dir,
            fit=lambda o, logs: fit_physics_head(o, logs, taus, head, term))
        if test_log is not None:
            rec["interval_ppm"] = prior_interval(ff, test_log, opts,
                                                 metrics["noise_floor_ppm"])
    metrics["prior"] = rec
    write_metrics(out_dir, metrics)
    return metrics, fitted


def law_head(theta: np.ndarray, k: int, offset: float, scale: float,  # noqa: ANN201
             play: bool = False):
    """The law theta = [log taus, coefficients] as the head's NodeFit (normalised target:
    (y - offset) / scale); with `play`, the play's feature after the nodes (linear)."""
    coef = theta[k:]
    rf = RidgeFit((float(coef[0]) - offset) / scale, coef[1:] / scale, 0.0, float(coef.size))
    return head_from_ridge(rf, k + 1 + int(play), tuple(float(t) for t in np.exp(theta[:k])),
                           NODE_LAMBDA, cube_nodes=True)


def test_series(log: ChamberLog, step_s: float, latitude_deg: float | None
                ) -> tuple[StepSeries, int]:
    """A log's every step as a series (to predict on), and its decimation."""
    fe = front_end_for([log], step_s, ())
    d = prepare(log, fe, None, latitude_deg)
    return all_steps(StepSeries([d.s[:, 0].astype(np.float64)], np.zeros(0),
                                np.zeros(0, dtype=np.int64), fe.step_s)), d.decimation


def prior_interval(ff: FunctionFit, test_log: ChamberLog, opts: TrainOptions,
                   floor_ppm: float) -> list[float]:
    """The expected test RMS (ppm) with the posterior's spread: [the floor, sqrt(floor^2 +
    INTERVAL_Z^2 (mean_t var_t + m))], var_t the posterior variance of the unit's response
    at step t of the test (`FunctionFit.variance`), m the slow misfit its mean leaves on the
    unit's own runs (`FunctionFit.misfit_ppm2`)."""
    s, _ = test_series(test_log, opts.model_step_s, opts.latitude_deg)
    var = float(np.mean(ff.variance(s))) + ff.misfit_ppm2()
    return [floor_ppm, math.sqrt(floor_ppm**2 + INTERVAL_Z**2 * max(var, 0.0))]


def law_prediction(theta: np.ndarray, k: int, log: ChamberLog, step_s: float = 5.0,
                   play: Play | None = None) -> np.ndarray:
    """The law's SF error prediction (ppm) per sample of `log`, held over each step."""

    s, dec = test_series(log, step_s, None)
    return expand(design_matrix(s, np.exp(theta[:k]), play) @ theta[k:], len(log), dec)


def prior_lines(rec: dict) -> list[str]:
    """What `fogsf train --prior` prints about the prior."""
    share = ", ".join(f"{g} {100 * v:.0f} %" for g, v in rec["prior_share"].items())
    taus = ", ".join(f"{t:.0f}" for t in rec["design_taus_s"])
    head = (f"design's prior: {rec['nodes']} physics nodes (time constants {taus} s), learned "
            f"from {rec['units']} units")
    if rec["left_out"]:
        head += (" (left out as unlike the line: "
                 + ", ".join(u["unit"] for u in rec["left_out"]) + ")")
    head += (f"; on their own programs it leaves {rec['structure_misfit']:.2f} x their noise"
             + (" (the design's structure misses them: the prior's figures are optimistic)"
                if rec["structure_misfit"] > STRUCTURE_MISS else ""))
    chi = (f"chi-square of the unit's own fit against the design {rec['chi2']:.1f}, limit "
           f"{rec['chi2_limit']:.1f} at {rec['level']:g}")
    tail = [rec["recorded"]] if "recorded" in rec else []
    if not rec["used"]:
        return [head, f"the unit's data disagree with the design ({chi}): fitted alone, as "
                "fogsf train would", *tail]
    lines = [head, f"the prior's share of the posterior precision: {share} (100 %: the "
             f"unit's data added nothing); {chi}: the unit agrees with the design",
             "unit's time constants " + ", ".join(f"{t:.0f}" for t in rec["taus_s"]) + " s"
             + (f"; the design's hysteresis {rec['play']['form']}" if "play" in rec else "")]
    if "interval_ppm" in rec:
        lo, hi = rec["interval_ppm"]
        lines.append(f"expected test RMS with the prior's spread: {lo:.2f}-{hi:.2f} ppm")
    return lines + tail

