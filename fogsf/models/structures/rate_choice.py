"""The rate form chosen by the data: every candidate of `rate_forms.forms` fitted on all
training plateaus but a fold and scored on that fold, over three kinds of fold that stand
for the ways a model is used beyond its data (docs/train.md, "Plateau tables"): each
temperature group left out in turn, the run cut into TIME_FOLDS blocks in time order, and
every INTERLEAVE-th plateau. A form's score is the geometric mean over the kinds of its
held-out RMS within each kind, so that no kind (the extrapolating ones err most) decides
alone; the lowest score wins, the simpler form on a tie.

The choice prices each term at (log(n) - 1) / n times the noise variance the rows show (the
residual of the richest form, `noise_var`), added to each kind's held-out mean square: a
held-out score already pays ~1 such unit a term, so the sum is BIC's price; the lowest of
hundreds of noisy scores otherwise favours terms the noise does not repay (docs/decisions.md,
"The plateau model's form")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.models.structures.rate_forms import RateForm, design, forms, solve

TIME_FOLDS = 4
INTERLEAVE = 5


@dataclass(frozen=True)
class RateRows:
    """Training plateaus: x = output / full scale, tau, y = (rate - output) / full scale,
    each row's temperature group and its place in time."""

    x: np.ndarray
    tau: np.ndarray
    y: np.ndarray
    group: np.ndarray  # int, one per temperature group
    order: np.ndarray  # int, the row's rank in time

    def __len__(self) -> int:
        return int(self.x.shape[0])


@dataclass(frozen=True)
class FormChoice:
    """The chosen form, its score (a held-out RMS in units of full scale, unpriced), every
    candidate's, how many folds scored them, and the noise that priced the terms."""

    form: RateForm
    score: float
    scores: dict[RateForm, float]
    folds: int
    noise: float = 0.0  # the per-plateau noise RMS the rows show (units of full scale)

    def score_of(self, form: RateForm) -> float:
        return self.scores[form]


def fold_kinds(rows: RateRows) -> list[list[np.ndarray]]:
    """Boolean masks of the held-out rows, per kind of fold (temperature groups when there
    are three or more, time blocks, interleaved); a fold that would leave fewer training
    rows than half the table is dropped, and so is a kind left with no fold."""
    n = len(rows)
    groups = np.unique(rows.group)
    kinds = [[rows.group == g for g in groups] if groups.size > 2 else []]
    edges = np.linspace(0, n, TIME_FOLDS + 1).round().astype(int)
    kinds.append([(rows.order >= a) & (rows.order < b)
                  for a, b in zip(edges[:-1], edges[1:], strict=True)])
    kinds.append([rows.order % INTERLEAVE == k for k in range(INTERLEAVE)])
    kept = [[m for m in ms if m.any() and (~m).sum() >= n // 2] for ms in kinds]
    return [ms for ms in kept if ms]


def heldout_rms(rows: RateRows, form: RateForm, masks: list[np.ndarray]) -> float:
    """RMS of the form's held-out errors over the folds that can fit it: a fold whose
    training rows hold fewer temperature groups than the form's degree in T needs, or
    fewer rows than terms, cannot, and is left out (nan when none can)."""
    a = design(rows.x, rows.tau, form)
    need = max(form.temp_degree, form.rate_temp_degree) + 1
    sq, count = 0.0, 0
    for held in masks:
        train = ~held
        if train.sum() <= form.n_terms or np.unique(rows.group[train]).size < need:
            continue
        coef = solve(a[train], rows.y[train])
        err = a[held] @ coef - rows.y[held]
        sq += float(err @ err)
        count += int(held.sum())
    return float(np.sqrt(sq / count)) if count else float("nan")


def noise_var(rows: RateRows, cands: list[RateForm]) -> float:
    """The per-plateau noise variance: the residual mean square of the candidate with the
    most terms that leaves at least half the rows free (0 when none does)."""
    free = [f for f in cands if 2 * f.n_terms <= len(rows)]
    if not free:
        return 0.0
    rich = max(free, key=lambda f: f.n_terms)
    a = design(rows.x, rows.tau, rich)
    err = a @ solve(a, rows.y) - rows.y
    return float(err @ err) / (len(rows) - rich.n_terms)


def _score(per_kind: list[float], price_sq: float = 0.0) -> float:
    """The geometric mean over the kinds that could score the form (inf when none) of each
    kind's held-out RMS, `price_sq` added to its mean square."""
    ok = [max(float(np.sqrt(v * v + price_sq)), 1e-30) for v in per_kind if np.isfinite(v)]
    return float(np.exp(np.mean(np.log(ok)))) if ok else float("inf")


def choose_form(rows: RateRows, candidates: list[RateForm] | None = None,
                allow_rate_part: bool = True) -> FormChoice:
    """The form the held-out folds choose (a linear SF only when `allow_rate_part` is False:
    a table at one |rate| cannot measure a rate part)."""
    cands = candidates if candidates is not None else forms()
    if not allow_rate_part:
        cands = [f for f in cands if not f.has_rate_part]
    # a polynomial of degree Q in T needs Q + 1 temperatures: the scatter inside a group
    # would otherwise pin the higher terms, wildly between the groups
    top = np.unique(rows.group).size - 1
    cands = [f for f in cands if f.temp_degree <= top and f.rate_temp_degree <= top] or [
        f for f in cands if f.temp_degree == 0 and f.rate_temp_degree == 0]
    kinds = fold_kinds(rows)
    if not kinds:
        raise ValueError("too few plateaus to hold any out")
    per_kind = {f: [heldout_rms(rows, f, ms) for ms in kinds] for f in cands}
    scores = {f: _score(v) for f, v in per_kind.items()}
    noise = noise_var(rows, cands)
    n = len(rows)
    price = max(np.log(n) - 1.0, 0.0) * noise / n
    priced = {f: _score(v, price * f.n_terms) for f, v in per_kind.items()}
    pick = min(cands, key=lambda f: priced[f])  # the first of equals: the simpler
    return FormChoice(pick, scores[pick], scores, sum(len(ms) for ms in kinds),
                      float(np.sqrt(noise)))
