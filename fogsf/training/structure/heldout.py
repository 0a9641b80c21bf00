"""The structure choice's held-out prediction: the training logs at the model rate (block
means of T, the SF targets) cut into segments, from one ramp's start to the next (the first
holds the soak before it; a log without a ramp is one segment), or into SPLIT_PARTS parts of
each; a candidate fitted by least squares on every fold but one predicts it, and its score is
the RMS of its error over 100 s windows of every held-out fold; the step the choice scores at
(`choice_step_s`); and the candidates fitted on every step (`candidate_compensations`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.read.columns import held, stand_in
from fogsf.models.features import MODEL_STEP_S, front_end_for, prepare
from fogsf.models.front_end import FrontEnd
from fogsf.models.structures.chain_nodes import chain_z, identify_chains, node_taus
from fogsf.models.structures.lag_bank import bank_cross, bank_penalty, fit_bank, n_curved
from fogsf.models.structures.least_squares import TAU_GRID_S, fit_candidates, node_candidates
from fogsf.models.structures.physics_nodes import (
    NodeTemperatures,
    fit_coefficients,
    identify_taus,
)
from fogsf.training.interval.transfer import ramp_segments

SPLIT_PARTS = 3
# Several segments: at most this many folds (every fold is one fit over the other steps, so
# a fold per part would make a week of ramps cost the square of its length); the parts are
# dealt to them in turn, so a fold's parts lie far apart. No training program of the benches
# holds more than 8 ramps, so their folds are the parts themselves.
MAX_PART_FOLDS = 24
# Logs longer than this many model steps (33 h at 5 s) are scored at a coarser step, a
# whole multiple of the model step: the choice is between thermal structures of minutes to
# hours, and every fold refits every candidate to all other steps (a week at 100 Hz: 244 s
# at 5 s, 24 folds). The chosen structure is then fitted at the model step.
MAX_CHOICE_STEPS = 24_000
SCORE_WINDOW_S = 100.0


@dataclass
class StepData:
    """The training logs at the model rate: block means of T (minus t_ref), targets, and
    the segment (fold) of every step, stacked over the logs."""

    fe: FrontEnd
    t_rel: list[np.ndarray]
    y: np.ndarray
    fold: np.ndarray
    one_segment: bool = False  # the logs hold one segment, split into parts
    nodes: NodeTemperatures = field(init=False)

    def __post_init__(self) -> None:
        self.nodes = NodeTemperatures(self.t_rel, self.fe.step_s)

    @property
    def n_folds(self) -> int:
        return int(self.fold.max()) + 1


def _log_folds(log: ChamberLog, n_steps: int, step_s: float) -> np.ndarray:
    """Segment index per model step of one log: a new segment starts at each ramp."""
    t = log.time_s[0] + np.arange(n_steps) * step_s
    starts = [sg.start_s for sg in ramp_segments(log)][1:]
    return np.searchsorted(np.asarray(starts), t, side="right")


def step_data(logs: list[ChamberLog], step_s: float = MODEL_STEP_S,
              latitude_deg: float | None = None) -> StepData:
    fe = front_end_for(logs, step_s, ())
    t_rel, ys, folds = [], [], []
    base = 0
    for lg in logs:
        d = prepare(lg, fe, None, latitude_deg)
        t_rel.append(d.s[:, 0].astype(np.float64))
        ys.append(d.target_ppm)
        f = _log_folds(lg, d.n_steps, d.step_s)
        folds.append(f + base)
        base += int(f.max()) + 1
    fold = np.concatenate(folds)
    if base == 1:  # one segment: contiguous parts
        fold = np.minimum(np.arange(fold.size) * SPLIT_PARTS // fold.size, SPLIT_PARTS - 1)
    return StepData(fe, t_rel, np.concatenate(ys), fold, base == 1)


def part_folds(sd: StepData) -> np.ndarray:
    """Every segment of `sd` in SPLIT_PARTS contiguous parts (fewer when it has fewer steps),
    one fold per part, numbered without gaps; beyond MAX_PART_FOLDS parts, part i goes to
    fold i mod MAX_PART_FOLDS."""
    out = np.empty_like(sd.fold)
    for k in range(sd.n_folds):
        idx = np.flatnonzero(sd.fold == k)
        out[idx] = k * SPLIT_PARTS + np.minimum(np.arange(idx.size) * SPLIT_PARTS // idx.size,
                                                SPLIT_PARTS - 1)
    return np.unique(out, return_inverse=True)[1].reshape(out.shape) % MAX_PART_FOLDS


Predictor = Callable[[NodeTemperatures], np.ndarray]  # steps' prediction (ppm) of any logs


def fit_candidate(name: str, sd: StepData, rows: np.ndarray) -> Predictor:
    """Candidate `name` fitted by least squares on the steps `rows` of `sd`."""
    y = sd.y[rows]
    lam = bank_penalty(name)
    if lam is not None:
        z = sd.nodes.z(TAU_GRID_S)
        scale = float(np.std(y)) or 1.0
        bank = fit_bank(z[rows], y / scale, lam, curved=n_curved(), cross=bank_cross(name))
        return lambda nt: bank.predict(nt.z(TAU_GRID_S)) * scale
    if name == "node":
        s = sd.nodes.z(TAU_GRID_S) * 50.0
        fits = fit_candidates(node_candidates(1), s[rows], y)
        pool = [f for f in fits if f.plausible] or fits
        best = min(pool, key=lambda f: f.sse)
        return lambda nt: best.cand.design(nt.z(TAU_GRID_S) * 50.0) @ best.coef
    if name.startswith("chain"):
        chains = identify_chains(sd.nodes, sd.y, int(name.removeprefix("chain")), rows)
        cfit = fit_coefficients(chain_z(sd.nodes, chains)[rows], y, node_taus(chains))
        return lambda nt: cfit.predict(chain_z(nt, chains))
    n_nodes = int(name.removeprefix("physics"))
    taus = identify_taus(sd.nodes, sd.y, n_nodes, rows)
    fit = fit_coefficients(sd.nodes.z(taus)[rows], y, taus)
    return lambda nt: fit.predict(nt.z(taus))


def _windowed_sq(err: np.ndarray, step_s: float) -> list[float]:
    win = max(1, int(round(SCORE_WINDOW_S / step_s)))
    n = err.size // win
    if n == 0:
        return [float(np.mean(err)) ** 2]
    return list(np.mean(err[:n * win].reshape(n, win), axis=1) ** 2)


def heldout_folds(name: str, sd: StepData,
                  fit: Callable[[StepData, np.ndarray], Predictor] | None = None,
                  tick: Callable[[], object] | None = None) -> list[list[float]]:
    """Per fold, the squared 100 s window means (ppm^2) of the candidate's error on it when
    fitted on the others (`heldout_score`'s arguments)."""
    out: list[list[float]] = []
    fitter = fit or (lambda s, r: fit_candidate(name, s, r))
    for k in range(sd.n_folds):
        held = sd.fold == k
        pred = fitter(sd, np.flatnonzero(~held))(sd.nodes)
        out.append(_windowed_sq(pred[held] - sd.y[held], sd.fe.step_s))
        if tick is not None:
            tick()
    return out


def pooled_rms(folds: list[list[float]]) -> float:
    """The held-out score of `heldout_folds`: RMS over every window of every fold."""
    return float(np.sqrt(np.mean([v for f in folds for v in f])))


def heldout_score(name: str, sd: StepData,
                  fit: Callable[[StepData, np.ndarray], Predictor] | None = None,
                  tick: Callable[[], object] | None = None) -> float:
    """RMS (ppm, 100 s windows) of the candidate's error on each segment when fitted on the
    others, over every segment; `fit` (steps data, fitted rows) instead of the candidate's
    own least squares (e.g. with a hysteresis term, `training.structure.hysteresis`); `tick`
    is called after every fold's fit (a progress bar's update)."""
    return pooled_rms(heldout_folds(name, sd, fit, tick))


def choice_step_s(logs: list[ChamberLog], step_s: float = MODEL_STEP_S) -> float:
    """The step the choice scores at: `step_s`, or the smallest whole multiple of it that
    keeps the logs under MAX_CHOICE_STEPS steps."""
    total_s = sum(lg.duration_s for lg in logs)
    return step_s * max(1, math.ceil(total_s / step_s / MAX_CHOICE_STEPS))


def candidate_compensations(names: tuple[str, ...], logs: list[ChamberLog],
                            step_s: float = MODEL_STEP_S, latitude_deg: float | None = None
                            ) -> tuple[StepData, dict[str, Callable[[ChamberLog], np.ndarray]]]:
    """Candidates `names`, each by least squares on every step of `logs`, and the steps data
    they were fitted to: per name, a function giving a log's SF error prediction (ppm vs
    nominal) per sample, held over each model step."""
    sd = step_data(logs, step_s, latitude_deg)
    every = np.arange(sd.y.size)

    def compensation(pred: Predictor) -> Callable[[ChamberLog], np.ndarray]:
        def predict(log: ChamberLog) -> np.ndarray:
            d = prepare(log, sd.fe, None, None)
            steps = pred(NodeTemperatures([d.s[:, 0].astype(np.float64)], sd.fe.step_s))
            return stand_in(held(steps, log.time_s, d.decimation))

        return predict

    return sd, {n: compensation(fit_candidate(n, sd, every)) for n in names}


def candidate_compensation(name: str, logs: list[ChamberLog], step_s: float = MODEL_STEP_S,
                           latitude_deg: float | None = None
                           ) -> Callable[[ChamberLog], np.ndarray]:
    """Candidate `name` by least squares on every step of `logs` (`candidate_compensations`).
    For benches and probes."""
    return candidate_compensations((name,), logs, step_s, latitude_deg)[1][name]
