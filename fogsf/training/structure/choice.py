"""The default's structure, chosen by the training logs: held-out prediction of their parts.

The candidates, smallest and most physical first: physics nodes with 1, 2 and 3 nodes
(`physics1`..`physics3`, `models.structures.physics_nodes`) and the lag bank (`bank`). One effective
node with a cubic (`node`, `--structure node`) is not among them: its held-out score chose
it on loops, where it then left the most (docs/decisions.md, "Not candidates"). The logs
are cut into segments (from one ramp's start to the next, so the first holds the soak
before it; a log without a ramp is one segment). Each candidate is fitted by least squares
to the training logs with one fold held out, predicts it, and scores the RMS of its error
over 100 s windows; a candidate's score is the RMS over every held-out fold. The folds and
the rule depend on what the logs hold:
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

from dataclasses import dataclass

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import MODEL_STEP_S
from fogsf.models.structures.lag_bank import BANK_LAMBDA, bank_name
from fogsf.training.structure.heldout import (
    MAX_PART_FOLDS,
    SPLIT_PARTS,
    StepData,
    choice_step_s,
    heldout_folds,
    part_folds,
    pooled_rms,
    step_data,
)
from fogsf.training.structure.penalty import (
    PENALTIES,
    PENALTY_MIN_FOLDS,
    PenaltyChoice,
    bank_prior,
    choose_penalty,
    penalty_message,
)

CANDIDATES = ("physics1", "physics2", "physics3", "bank")  # the order with one segment
# the several-segment rule tuned on development gyros; not the default (module docstring),
# kept for `choose(candidates=...)` and the probes
MULTI_SEGMENT_ORDER = ("bank", "physics1", "physics2", "physics3")
# A candidate within this fraction of the best held-out score counts as as good: the first
# such in CANDIDATES is chosen. Chosen on development gyros (docs/decisions.md).
CHOICE_TOLERANCE = 0.20
# Several segments: a physics structure replaces the bank when its held-out-part score is
# this many times better: a smaller factor loses to the bank in the tail, a larger one never
# leaves it (docs/decisions.md, "From several ramps").
EVIDENCE_FACTOR = 2.5
PHYSICS = ("physics1", "physics2", "physics3")


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
