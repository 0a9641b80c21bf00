"""The default's structure, chosen by the training logs: held-out prediction of their parts.

The candidates, smallest and most physical first: physics nodes with 1, 2 and 3 nodes
(`physics1`..`physics3`, `models.physics_nodes`) and the lag bank (`bank`). One effective
node with a cubic (`node`, `--structure node`) is not among them: on development gyros its
held-out score chose it where it then left 4-30 x the noise floor on loops
(docs/decisions.md). The logs are cut into segments (from one ramp's start to the next,
so the first holds the soak before it; a log without a ramp is one segment). Each candidate
is fitted by least squares to the training logs with one fold held out, predicts it, and
scores the RMS of its error over 100 s windows; a candidate's score is the RMS over every
held-out fold. The folds and the rule depend on what the logs hold:
- one segment (one ramp; split into SPLIT_PARTS contiguous parts): its held-out parts test
  extrapolation in temperature, not in rate, so the data cannot tell the structures'
  rate dependence apart: the smaller, more physical structure first (physics nodes with
  1, 2, 3 nodes, then the bank), the first within CHOICE_TOLERANCE of the best;
- several segments (ramps at several rates or directions): every segment in SPLIT_PARTS
  parts, one part held out at a time. The other segments still hold the part's temperatures
  at their own rates, so the score tests interpolation in rate, what compensation at a rate
  between the trained ones asks (beyond MAX_PART_FOLDS parts, they are dealt to that many
  folds in turn). The lag bank unless a physics structure's score is
  EVIDENCE_FACTOR times better than the bank's; then the smallest physics structure within
  CHOICE_TOLERANCE of the best physics score. Holding out whole segments (extrapolation in
  rate, MULTI_SEGMENT_ORDER) chose physics structures that then lost to the bank on
  evaluation gyros (docs/decisions.md); it is kept for `choose(candidates=...)` and the
  probes.
When the bank is chosen from several segments and the logs hold at least
PENALTY_MIN_FOLDS held-out parts, its ridge penalty may go below the prior (BANK_LAMBDA)
and its quadratic gain cross terms, in steps, each taken when it predicts at least
PENALTY_WIN_SHARE of the held-out parts better than the current bank and lowers the score:
each of PENALTIES in turn, then the cross terms at the penalty reached, then with them each
lower penalty. With many parts the data, not the prior, can say how far the lags' fine
structure (a slow chain's delay, a part's quadratic law as a form in the lags) is
determined; with few, the steps chose themselves by chance and lost on the tests
(docs/decisions.md). With fewer parts the prior is LOOP_LAMBDA where the logs ramp both up
and down (`bank_prior`), else BANK_LAMBDA. The hysteresis check runs on the bank at
BANK_LAMBDA.
The orders, the tolerance, the factor and the penalty rule were chosen on development
gyros.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.columns import held
from fogsf.models.chain_nodes import chain_z, identify_chains, node_taus
from fogsf.models.features import MODEL_STEP_S, front_end_for, prepare
from fogsf.models.front_end import FrontEnd
from fogsf.models.lag_bank import (
    BANK_LAMBDA,
    LOOP_LAMBDA,
    bank_cross,
    bank_name,
    bank_penalty,
    fit_bank,
    n_curved,
)
from fogsf.models.least_squares import TAU_GRID_S, fit_candidates, node_candidates
from fogsf.models.physics_nodes import (
    NodeTemperatures,
    fit_coefficients,
    identify_taus,
)
from fogsf.training.transfer import ramp_segments

CANDIDATES = ("physics1", "physics2", "physics3", "bank")  # the order with one segment
# the several-segment rule tuned on development gyros; not the default (module docstring),
# kept for `choose(candidates=...)` and the probes
MULTI_SEGMENT_ORDER = ("bank", "physics1", "physics2", "physics3")
# A candidate within this fraction of the best held-out score counts as as good: the first
# such in CANDIDATES is chosen. Chosen on development gyros (docs/decisions.md).
CHOICE_TOLERANCE = 0.20
# Several segments: a physics structure replaces the bank when its held-out-part score is
# this many times better (development gyros 1-48: of 2, 2.5 and 3, the one that improved
# on the bank with no median or worst case above it, docs/decisions.md).
EVIDENCE_FACTOR = 2.5
PHYSICS = ("physics1", "physics2", "physics3")
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
# The bank's penalty: the lower ones tried in turn (multiples of the design's mean diagonal,
# as BANK_LAMBDA), and the held-out parts the logs must hold for the rule to run
# (development gyros 1-80, docs/decisions.md: the envelope's 18 parts, not a loop's or two
# ramps' 6).
PENALTIES = (1e-4, 1e-5, 1e-6)
PENALTY_MIN_FOLDS = 12
# the share of the held-out parts a lower penalty must predict better
PENALTY_WIN_SHARE = 2 / 3


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
    own least squares (e.g. with a hysteresis term, `training.hysteresis_choice`); `tick`
    is called after every fold's fit (a progress bar's update)."""
    return pooled_rms(heldout_folds(name, sd, fit, tick))


@dataclass
class PenaltyChoice:
    """The bank's penalty and cross terms, chosen by the held-out parts (module docstring)."""

    name: str  # the bank's structure name (`lag_bank.bank_name`)
    scores: dict[str, float]  # held-out RMS (ppm) per bank tried, in the order tried
    # per bank tried after the prior: the parts it predicts better than the bank in `against`
    wins: dict[str, int]
    folds: int  # held-out parts
    against: dict[str, str] = field(default_factory=dict)
    plain: str = "bank"  # the bank the penalty walk reached without the cross terms

    @property
    def penalty(self) -> float:
        lam = bank_penalty(self.name)
        assert lam is not None
        return lam

    @property
    def cross(self) -> bool:
        return bank_cross(self.name)

    def as_dict(self) -> dict:
        return {"penalty": self.penalty, "cross_terms": self.cross, "bank": self.name,
                "without_cross_terms": self.plain, "heldout_rms_ppm": self.scores,
                "wins": self.wins, "against": self.against, "parts": self.folds,
                "min_parts": PENALTY_MIN_FOLDS}


def step_won(new: list[list[float]], old: list[list[float]]) -> tuple[int, bool]:
    """(the held-out parts `new` predicts better than `old`, whether that is a step the rule
    takes: at least PENALTY_WIN_SHARE of the parts and a lower pooled score); both are
    `heldout_folds` on the same parts."""
    wins = int(sum(np.mean(a) < np.mean(b) for a, b in zip(new, old, strict=True)))
    return wins, wins >= PENALTY_WIN_SHARE * len(new) and pooled_rms(new) < pooled_rms(old)


def choose_penalty(sd: StepData, prior: list[list[float]],
                   tick: Callable[[], object] | None = None) -> PenaltyChoice:
    """From the prior's held-out folds `prior`: each of PENALTIES in turn, then the cross
    terms at the penalty reached, then (with them) each lower penalty in turn; each step is
    taken while it predicts at least PENALTY_WIN_SHARE of the parts better than the current
    bank and lowers the score."""
    pc = PenaltyChoice(bank_name(), {bank_name(): pooled_rms(prior)}, {}, sd.n_folds)
    cur_folds = prior

    def step(name: str) -> bool:
        nonlocal cur_folds
        folds = heldout_folds(name, sd, tick=tick)
        pc.scores[name] = pooled_rms(folds)
        pc.wins[name], taken = step_won(folds, cur_folds)
        pc.against[name] = pc.name
        if not taken:
            return False
        pc.name, cur_folds = name, folds
        return True

    def walk(cross: bool) -> None:
        for lam in PENALTIES:
            if lam < pc.penalty and not step(bank_name(lam, cross)):
                return

    walk(False)
    pc.plain = pc.name
    if step(bank_name(pc.penalty, cross=True)):
        walk(True)
    return pc


def ramps_both_ways(logs: list[ChamberLog]) -> bool:
    """Whether the logs, together, hold an up-ramp and a down-ramp (`ramp_segments`)."""
    signs = {math.copysign(1.0, sg.rate_c_per_min) for log in logs for sg in ramp_segments(log)}
    return signs == {1.0, -1.0}


def bank_prior(logs: list[ChamberLog], n_parts: int | None = None,
               step_s: float = MODEL_STEP_S) -> float:
    """The bank's penalty where the penalty rule does not run: LOOP_LAMBDA for logs that ramp
    both up and down and hold fewer than PENALTY_MIN_FOLDS held-out parts (`n_parts`, counted
    from the logs when not given), else BANK_LAMBDA (`lag_bank`), where the rule starts."""
    if not ramps_both_ways(logs):
        return BANK_LAMBDA
    if n_parts is None:
        sd = step_data(logs, choice_step_s(logs, step_s))
        n_parts = 1 if sd.one_segment else int(part_folds(sd).max()) + 1
    return LOOP_LAMBDA if n_parts < PENALTY_MIN_FOLDS else BANK_LAMBDA


@dataclass
class StructureChoice:
    name: str
    scores: dict[str, float]  # held-out RMS (ppm) per candidate, in the rule's order
    folds: int  # segments in the logs (one: split into parts)
    one_segment: bool
    tolerance: float = CHOICE_TOLERANCE
    factor: float | None = None  # several segments: EVIDENCE_FACTOR (None: `candidates=`)
    penalty: PenaltyChoice | None = None  # the bank's, where the rule ran
    cross_left_out: str | None = None  # why the trained bank lacks the cross terms chosen
    cross_with_term: dict | None = None  # the cross terms judged with a hysteresis term
    prior: float = BANK_LAMBDA  # the bank's penalty where the rule did not run (`bank_prior`)

    def message(self) -> str:
        return choice_message(self.as_dict())

    @property
    def bank(self) -> str:
        """The bank's structure name, its penalty and cross terms in it (`lag_bank.bank_name`;
        `fogsf train` may leave the cross terms out: `cross_left_out`)."""
        return self.penalty.name if self.penalty is not None else bank_name(self.prior)

    def structure(self) -> tuple[str, int]:
        """(structure, nodes) of `fogsf train` for the chosen candidate."""
        if self.name.startswith("physics"):
            return "physics", int(self.name.removeprefix("physics"))
        return self.name, 1

    def as_dict(self) -> dict:
        return {"chosen": self.name, "heldout_rms_ppm": self.scores, "segments": self.folds,
                "one_segment": self.one_segment, "tolerance": self.tolerance,
                "evidence_factor": self.factor,
                **({"bank_penalty": self.penalty.as_dict()} if self.penalty else {}),
                **({"bank_prior": self.prior} if self.prior != BANK_LAMBDA else {}),
                **({"cross_left_out": self.cross_left_out} if self.cross_left_out else {}),
                **({"cross_with_term": self.cross_with_term} if self.cross_with_term else {})}


def choice_message(d: dict) -> str:
    """What `fogsf train` prints about the choice (`StructureChoice.as_dict`'s content)."""
    scores: dict[str, float] = d["heldout_rms_ppm"]
    best = min(scores.values())
    cells = ", ".join(f"{k} {v:.1f}" for k, v in scores.items())
    tol = f"{100 * d['tolerance']:.0f} %"
    factor = d.get("evidence_factor")
    if d["one_segment"]:
        parts = f"one ramp, in {SPLIT_PARTS} parts"
        why = ("the best" if scores[d["chosen"]] == best else
               f"the smallest within {tol} of the best (one ramp cannot tell the structures' "
               "rate dependence apart)")
    elif factor is not None:
        parts = f"{d['segments']} ramps, each in {SPLIT_PARTS} parts"
        if d["segments"] * SPLIT_PARTS > MAX_PART_FOLDS:
            parts += f" dealt to {MAX_PART_FOLDS} folds"
        if d["chosen"] == "bank":
            why = (f"the lag bank, as no physics structure predicts the held-out parts "
                   f"{factor:g} x better")
        else:
            gain = scores["bank"] / scores[d["chosen"]]
            why = (f"it predicts the held-out parts {gain:.1f} x better than the lag bank "
                   f"(more than {factor:g} x), the smallest physics structure within {tol} "
                   "of the best")
    else:
        parts = f"{d['segments']} segments"
        why = (f"the lag bank within {tol} of the best" if d["chosen"] == "bank" else
               f"better than the lag bank by more than {tol}")
    out = (f"structure {d['chosen']}, chosen by held-out prediction on the training logs "
           f"({parts}; held-out RMS, ppm: {cells}): {why}")
    pen = d.get("bank_penalty")
    if pen is not None:
        out += "; " + penalty_message(pen)
    elif d.get("bank_prior") is not None and d["chosen"] == "bank":
        out += (f"; the bank's penalty {d['bank_prior']:g}, the prior of logs that ramp both "
                "up and down")
    if d.get("cross_left_out"):
        out += f"; the cross terms left out: {d['cross_left_out']}"
    elif d.get("cross_with_term"):
        c = d["cross_with_term"]
        out += (f"; with the hysteresis term the cross terms predicted {c['wins']} of the "
                f"{c['parts']} held-out parts better: kept")
    return out


def bank_label(name: str) -> str:
    """A bank structure name (`lag_bank.bank_name`) in words: its penalty, its cross terms."""
    return f"{bank_penalty(name):g}" + (" with cross terms" if bank_cross(name) else "")


def penalty_message(pen: dict) -> str:
    """The bank's penalty and cross terms (`PenaltyChoice.as_dict`) in a sentence: every step
    the rule tried, what it predicted, and what it kept."""
    n, rms, wins, against = pen["parts"], pen["heldout_rms_ppm"], pen["wins"], pen["against"]
    need = math.ceil(PENALTY_WIN_SHARE * n - 1e-9)
    tried = list(rms)  # the prior first, then each step in the order tried
    kept = pen["bank"]
    steps = []
    for name in tried[1:]:
        clause = f"{bank_label(name)} predicted {wins[name]} better"
        if name == kept or name in against.values():
            clause += f" (held-out RMS {rms[against[name]]:.1f} -> {rms[name]:.1f} ppm): taken"
        elif wins[name] < need:
            clause += ": not taken"
        else:
            clause += f" but raised the held-out RMS to {rms[name]:.1f} ppm: not taken"
        steps.append(clause)
    lowered = "the prior " if kept == tried[0] else ""
    return (f"the bank's penalty and cross terms, by the {n} held-out parts ({need} needed at "
            f"each step): {'; '.join(steps)}; kept {lowered}{bank_label(kept)}")


def choice_step_s(logs: list[ChamberLog], step_s: float = MODEL_STEP_S) -> float:
    """The step the choice scores at: `step_s`, or the smallest whole multiple of it that
    keeps the logs under MAX_CHOICE_STEPS steps."""
    total_s = sum(lg.duration_s for lg in logs)
    return step_s * max(1, math.ceil(total_s / step_s / MAX_CHOICE_STEPS))


def _bar(fits: int, desc: str, progress: bool):  # noqa: ANN202 - a tqdm bar
    """A bar over `fits` fits, drawn if `progress`."""
    from tqdm import tqdm

    return tqdm(total=fits, desc=desc, unit="fit", disable=not progress, leave=False)


def _folds(order: tuple[str, ...], sd: StepData, progress: bool
           ) -> dict[str, list[list[float]]]:
    """Every candidate's held-out folds, in `order`; a bar over the fits if `progress`."""
    with _bar(len(order) * sd.n_folds, "structure choice", progress) as bar:
        return {c: heldout_folds(c, sd, tick=bar.update) for c in order}


def _scores(order: tuple[str, ...], sd: StepData, progress: bool) -> dict[str, float]:
    """Every candidate's held-out score (`_folds` pooled)."""
    return {c: pooled_rms(f) for c, f in _folds(order, sd, progress).items()}


def _penalty(sd: StepData, prior: list[list[float]], progress: bool) -> PenaltyChoice:
    """`choose_penalty`, with a bar over its fits if `progress`."""
    with _bar((2 * len(PENALTIES) + 1) * sd.n_folds, "bank penalty", progress) as bar:
        return choose_penalty(sd, prior, tick=bar.update)


def choose(logs: list[ChamberLog], step_s: float = MODEL_STEP_S,
           latitude_deg: float | None = None,
           candidates: tuple[str, ...] | None = None,
           tolerance: float = CHOICE_TOLERANCE, progress: bool = False) -> StructureChoice:
    """The rule (module docstring); `candidates` in order replaces the rule's order (and,
    with several segments, scores whole segments held out, the rule tuned first);
    `progress`: a bar over the fits (a week of logs takes a minute)."""
    sd = step_data(logs, choice_step_s(logs, step_s), latitude_deg)
    if candidates is None and not sd.one_segment:
        segments = sd.n_folds
        sd.fold = part_folds(sd)
        folds = _folds((*PHYSICS, "bank"), sd, progress)
        scores = {c: pooled_rms(f) for c, f in folds.items()}
        best = min(scores[c] for c in PHYSICS)
        name = "bank"
        if EVIDENCE_FACTOR * best <= scores["bank"]:
            name = next(c for c in PHYSICS if scores[c] <= (1.0 + tolerance) * best)
        penalty = None
        if name == "bank" and sd.n_folds >= PENALTY_MIN_FOLDS:
            penalty = _penalty(sd, folds["bank"], progress)
        return StructureChoice(name, scores, segments, False, tolerance, EVIDENCE_FACTOR,
                               penalty, prior=bank_prior(logs, sd.n_folds) if name == "bank"
                               else BANK_LAMBDA)
    order = candidates or CANDIDATES
    scores = _scores(order, sd, progress)
    best = min(scores.values())
    name = next(c for c in order if scores[c] <= (1.0 + tolerance) * best)
    return StructureChoice(name, scores, sd.n_folds, sd.one_segment, tolerance)


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
            return held(steps, log.time_s, d.decimation)

        return predict

    return sd, {n: compensation(fit_candidate(n, sd, every)) for n in names}


def candidate_compensation(name: str, logs: list[ChamberLog], step_s: float = MODEL_STEP_S,
                           latitude_deg: float | None = None
                           ) -> Callable[[ChamberLog], np.ndarray]:
    """Candidate `name` by least squares on every step of `logs` (`candidate_compensations`).
    For benches and probes."""
    return candidate_compensations((name,), logs, step_s, latitude_deg)[1][name]
