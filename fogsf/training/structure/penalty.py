"""The lag bank's ridge penalty and cross terms where several segments choose the bank: the
rule that lowers the penalty from the prior and adds the cross terms, each step taken when it
predicts at least PENALTY_WIN_SHARE of the held-out parts better and lowers the held-out score
(`choose_penalty`, on logs of at least PENALTY_MIN_FOLDS parts); the prior where the rule
does not run (`bank_prior`: LOOP_LAMBDA for logs that ramp both ways); and the sentence
`fogsf train` prints about them (`penalty_message`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import MODEL_STEP_S
from fogsf.models.structures.lag_bank import (
    BANK_LAMBDA,
    LOOP_LAMBDA,
    bank_cross,
    bank_name,
    bank_penalty,
)
from fogsf.training.interval.transfer import ramp_segments
from fogsf.training.structure.heldout import (
    StepData,
    choice_step_s,
    heldout_folds,
    part_folds,
    pooled_rms,
    step_data,
)

# The bank's penalty: the lower ones tried in turn (multiples of the design's mean diagonal,
# as BANK_LAMBDA), and the held-out parts the logs must hold for the rule to run: an
# envelope's 18, not a loop's or two ramps' 6, on which the rule lost (docs/decisions.md;
# benchmarks/probes/README.md, "The penalty walk").
PENALTIES = (1e-4, 1e-5, 1e-6)
PENALTY_MIN_FOLDS = 12
# the share of the held-out parts a lower penalty must predict better
PENALTY_WIN_SHARE = 2 / 3


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
