"""The bias model's structure chosen by the training targets: each candidate of
`training.bias.structure` is fitted with one fold of blocks held out (`block_folds`),
predicts it, and scores the RMS of its error over 100 s windows (a pair is a window); the
choice is the first candidate, in CANDIDATES' order, within CHOICE_TOLERANCE of the best
score: a larger structure has to predict held-out segments clearly better. One exception:
where the cubic in T scores more than SHUPE_EVIDENT times the best (a Shupe term) and `lead`
is a candidate, `lead`. Chosen on development gyros (docs/decisions.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.training.bias.structure import CANDIDATES, NODES, CandidateFit, Columns, fit_candidate

CHOICE_TOLERANCE = 0.10
# the cubic in T's held-out score over the best: above this the log shows a Shupe term and,
# with a front end of its own, the bias takes `lead` (the gap between logs with and without
# a Shupe term: benchmarks/probes/README.md, "Bias structure")
SHUPE_EVIDENT = 3.0
SCORE_WINDOW_S = 100.0


def _window_groups(group: np.ndarray) -> np.ndarray:
    return np.unique(group, return_inverse=True)[1]


def heldout_errors(name: str, cols: Columns, y: np.ndarray, fold: np.ndarray,
                   group: np.ndarray) -> np.ndarray:
    """The candidate's error (deg/h) on every held-out scoring window (`group`: the error
    averaged over each first), each fold predicted by a fit to the others; the windows in
    one order for every candidate."""
    out: list[np.ndarray] = []
    for k in np.unique(fold):
        held = np.flatnonzero(fold == k)
        rest = np.flatnonzero(fold != k)
        fit = fit_candidate(name, cols, rest, y[rest])
        err = fit.predict(cols, held) - y[held]
        g = _window_groups(group[held])
        out.append(np.bincount(g, weights=err) / np.bincount(g))
    return np.concatenate(out)


def heldout_score(name: str, cols: Columns, y: np.ndarray, fold: np.ndarray,
                  group: np.ndarray) -> float:
    """RMS (deg/h) of the candidate's held-out window errors (`heldout_errors`)."""
    return float(np.sqrt(np.mean(heldout_errors(name, cols, y, fold, group) ** 2)))


@dataclass
class BiasChoice:
    name: str
    scores: dict[str, float]  # held-out RMS (deg/h) per candidate, in the rule's order
    folds: int
    taus_s: tuple[float, ...]  # the chosen candidate's node time constants
    tolerance: float = CHOICE_TOLERANCE
    free_tau: bool = True  # by varpro (lead: a grid), else one of z's lags
    left_out: str = ""  # why a candidate was not tried (metrics.json `left_out`)

    def as_dict(self) -> dict:
        out = {"chosen": self.name, "heldout_rms_dph": self.scores, "folds": self.folds,
               "node_taus_s": list(self.taus_s), "tolerance": self.tolerance,
               "free_tau": self.free_tau}
        if self.left_out:
            out["left_out"] = self.left_out
        return out


def choice_message(d: dict) -> str:
    """What `fogsf train` prints about the bias structure (`BiasChoice.as_dict`)."""
    scores: dict[str, float] = d["heldout_rms_dph"]
    cells = ", ".join(f"{k} {v:.3f}" for k, v in scores.items())
    best = min(scores.values())
    tol = f"{100 * d['tolerance']:.0f} %"
    why = ("the best" if scores[d["chosen"]] == best and d["chosen"] == next(iter(scores))
           else "the smallest within " + tol + " of the best")
    if d["chosen"] == "lead" and scores.get("cubic", 0.0) > SHUPE_EVIDENT * best:
        why = (f"the cubic in T misses them by {scores['cubic'] / best:.1f} x the best (over "
               f"{SHUPE_EVIDENT:g} x: a Shupe term), so the coil's own rate of change")
    tau = ""
    if d.get("node_taus_s"):
        how = ("the coil's by a grid" if d["chosen"] == "lead"
               else "by variable projection" if d["free_tau"]
               else "the best of the features' lags")
        taus = ", ".join(f"{t:.0f}" for t in d["node_taus_s"])
        tau = f"; node time constants {taus} s ({how})"
    left = f"; {d['left_out']}" if d.get("left_out") else ""
    return (f"bias structure {d['chosen']}, chosen on held-out blocks of the training "
            f"targets ({d['folds']} folds of {BLOCK_S:.0f} s blocks; held-out RMS, deg/h: "
            f"{cells}): {why}{tau}{left}")


def choose(cols: Columns, y: np.ndarray, fold: np.ndarray, group: np.ndarray,
           candidates: tuple[str, ...] = CANDIDATES,
           tolerance: float = CHOICE_TOLERANCE) -> tuple[BiasChoice, CandidateFit]:
    """The rule (module docstring), and the chosen candidate fitted on every target."""
    order = [c for c in candidates if cols.taus is None
             or (c == "lead" and cols.own is not None)
             or (c != "lead" and NODES[c] <= len(cols.taus))]
    errs = {c: heldout_errors(c, cols, y, fold, group) for c in order}
    scores = {c: float(np.sqrt(np.mean(e * e))) for c, e in errs.items()}
    best = min(scores.values())
    name = next(c for c in order if scores[c] <= (1.0 + tolerance) * best)
    if "lead" in scores and scores.get("cubic", 0.0) > SHUPE_EVIDENT * best:
        # the cubic in T misses by far: a Shupe term; held-out blocks cannot tell the node
        # structures apart at the bias windows' noise, and the coil's own rate is the physics
        name = "lead"
    fit = fit_candidate(name, cols, np.arange(y.size), y)
    return (BiasChoice(name, scores, int(np.unique(fold).size), fit.taus_s, tolerance,
                       cols.taus is None or name == "lead"), fit)


# Held-out segments: blocks of BLOCK_S dealt to N_FOLDS folds in turn, so that every fold
# holds parts of every ramp and soak. Holding out whole ramps (the SF's choice) leaves a
# loop of one up- and one down-ramp two folds, each fitted on one direction of the Shupe
# term alone (docs/decisions.md).
BLOCK_S = 1200.0
N_FOLDS = 5


def block_folds(idx: np.ndarray, step_s: float) -> np.ndarray:
    """The fold of each target at model steps `idx` of one log."""
    return (idx * step_s // BLOCK_S).astype(np.int64) % N_FOLDS
