"""The fitted models and the records of a diagnosis, shared by its stages.

`ModelFit` is one model (the base, or the base plus candidates) fitted on all windows with
its held-out residuals; `fit_model` builds one (profile_ls, then crossval). `CandidateResult`
is the score of one catalogue effect (selection.score), and `Diagnosis` what
verdict.diagnose returns. `visible_fraction` is the share of a candidate's column the base
cannot absorb; `weighted_rms` and `block_sums` are the held-out measures every rule uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsf.diagnose import crossval, profile_ls, runs
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects.catalogue import Candidate
from fogsf.diagnose.profile_ls import Stack


@dataclass
class ModelFit:
    """One model (base, or base + a candidate) fitted on all windows."""

    stack: Stack
    fit: profile_ls.Fit
    pred: np.ndarray  # in-sample prediction per window
    heldout: np.ndarray  # held-out residual per window
    chi2_red: float  # in-sample weighted SSE / dof

    @property
    def combo(self) -> profile_ls.Combo:
        return self.stack.combos[self.fit.index]

    def coef(self, name: str) -> float:
        return float(self.fit.beta[self.stack.names.index(name)])

    def coef_se(self, name: str) -> float:
        i = self.stack.names.index(name)
        return float(math.sqrt(max(self.fit.cov[i, i], 0.0) * max(1.0, self.chi2_red)))


@dataclass
class CandidateResult:
    name: str
    identifiable: bool
    visible: float  # fraction of the candidate's column the base cannot absorb
    params: dict[str, object] = field(default_factory=dict)
    heldout_before: float = float("nan")
    heldout_after: float = float("nan")
    gain_pct: float = 0.0
    p_value: float = 1.0
    blocks_better: int = 0
    blocks: int = 0
    significant: bool = False
    evidence: str = ""
    model: ModelFit | None = None
    effect: dict | None = None  # simulator effect entry
    confounded_with: list[str] = field(default_factory=list)  # "base" or candidate names
    separating_run: str = ""  # the run that would separate it from them
    added_gain_pct: float = 0.0  # forward selection: held-out gain over the causes before it


@dataclass
class Diagnosis:
    runs: list[runs.Run]
    ctxs: list[RunContext]
    y: np.ndarray
    sigma: np.ndarray
    run_ids: np.ndarray
    blocks: np.ndarray
    folds: np.ndarray
    base: ModelFit
    base_rms: float
    base_whiteness_p: float
    correlations: dict[str, dict[str, float]]
    candidates: list[CandidateResult]
    cause: str | None
    ambiguous: list[str]
    unexplained: bool
    structure: dict[str, float | list[str]]  # the figures; flagged_by: the tests that flag
    extended: ModelFit  # base + cause (the base when there is no cause)
    cv_mode: str
    window_s: float
    causes: list[str] = field(default_factory=list)  # forward selection, `cause` first
    model_floor_ppm: float = 0.0
    # the windows' own noise alone, RMS over every window of every log: for one log what
    # `fogsf inspect --window-s W` reports as its noise floor
    window_noise_ppm: float = 0.0
    # catalogue forms that could not apply, each {effect, stage, reason}: in the scoring
    # (verdict) or in the extended model's simulation (extend); skipped, never an error
    skipped: list[dict[str, str]] = field(default_factory=list)

    @property
    def noise_floor_ppm(self) -> float:
        """RMS over windows of each window's noise and the base's resolution in quadrature."""
        return float(np.sqrt(np.mean(self.sigma**2)))



def weighted_rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e * e)))


def block_sums(v: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    return np.bincount(blocks, weights=v)


def fit_model(ctxs: list[RunContext], cand: Candidate | None, y: np.ndarray, w: np.ndarray,
              folds: np.ndarray, combos: list[profile_ls.Combo] | None = None) -> ModelFit:
    stack = profile_ls.build(ctxs, cand, combos)
    rows = np.arange(y.shape[0])
    fit = profile_ls.solve(stack, y, w, rows)
    pred = profile_ls.predict(stack, fit)
    dof = max(1, y.shape[0] - stack.x.shape[2])
    chi2 = float(np.sum((y - pred) ** 2 * w)) / dof
    held = crossval.heldout_residuals(stack, y, w, folds)
    stack.release()  # stacked again if asked for (intervals, the chosen model's columns)
    return ModelFit(stack, fit, pred, held, chi2)


def visible_fraction(model: ModelFit, w: np.ndarray) -> float:
    """Share (RMS) of the candidate column not reproducible by the base columns."""
    x = model.stack.x[model.fit.index]
    col = x[:, -1]
    base = x[:, :-1]
    sw = np.sqrt(w)
    c = col * sw
    if not np.any(col != col[0]):
        return 0.0
    coef, *_ = np.linalg.lstsq(base * sw[:, None], c, rcond=None)
    r = c - (base * sw[:, None]) @ coef
    cm = c - sw * np.sum(col * w) / np.sum(w)
    return float(np.linalg.norm(r) / max(float(np.linalg.norm(cm)), 1e-300))
