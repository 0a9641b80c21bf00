"""What a plateau table says the simulator's gyro gets wrong about rate (docs/diagnose.md,
"Plateau tables"): the simulator's SF is linear in rate; each rate term is added to that
base in turn, scored on held-out plateaus (`training.rate.choice`'s folds and score), and
the terms that win are named, forward: first the best of them, then each further one that
wins over the model so far.

The terms: an open-loop FOG's sine (the output A sin(k w) inverted: w = arcsin(m x) / m
times the SF, m the sine of the phase at full scale, moving linearly with temperature), an
odd polynomial x^3 .. x^P (a closed-loop FOG's nonlinearity), the asymmetry |x|, and even
terms x^2 .. x^P. The sine and the odd polynomial are two forms of one cause, the rate
nonlinearity: the one with the lower held-out score names the form (`sine` when it ties,
having fewer terms). A term is found when it lowers the held-out RMS FOUND_GAIN times."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from fogsf.models.structures.rate_choice import RateRows, choose_form, fold_kinds
from fogsf.models.structures.rate_forms import MAX_POWER, RateForm, design, solve

FOUND_GAIN = 1.3
# the sine's m = sin(phase at full scale), and its relative change per 10 C
SINE_M = np.linspace(0.02, 0.98, 25)
SINE_SLOPE = np.linspace(-0.02, 0.02, 5)

Columns = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (x, tau) -> [n, k] columns


@dataclass(frozen=True)
class TermScore:
    """One term added to the model so far: its held-out RMS (deg/h) and, for the sine, its
    phase at full scale (rad) and that phase's change per C (ppm/C)."""

    term: str
    heldout_dph: float
    phase_rad: float | None = None
    phase_ppm_per_c: float | None = None


@dataclass
class RateDiagnosis:
    """The base's held-out RMS, each step's candidates, the named terms in order, and the
    plateau model's (the polynomial `fogsf train` fits) for the gain."""

    base_dph: float
    steps: list[list[TermScore]] = field(default_factory=list)
    named: list[TermScore] = field(default_factory=list)
    model_form: str = ""
    model_dph: float = float("nan")
    rate_part_measured: bool = True

    @property
    def nonlinearity_form(self) -> str | None:
        """"sine" or "polynomial" when a rate nonlinearity is named, else None."""
        for t in self.named:
            if t.term in ("sine", "odd polynomial"):
                return "sine" if t.term == "sine" else "polynomial"
        return None

    @property
    def asymmetry(self) -> bool:
        return any(t.term == "asymmetry" for t in self.named)


def _cv(rows: RateRows, cols: Columns, target: np.ndarray, degree: int) -> float:
    """The held-out score of a model whose columns `cols` gives, of degree `degree` in T:
    geometric mean over the fold kinds of the RMS in each (units of full scale), over the
    folds whose training rows hold degree + 1 temperature groups (`rate_choice`'s rule)."""
    a = cols(rows.x, rows.tau)
    per = []
    for masks in fold_kinds(rows):
        sq, n = 0.0, 0
        for held in masks:
            if np.unique(rows.group[~held]).size < degree + 1:
                continue
            coef = solve(a[~held], target[~held])
            err = a[held] @ coef - target[held]
            sq, n = sq + float(err @ err), n + int(held.sum())
        if n:
            per.append(np.sqrt(sq / n))
    return float(np.exp(np.mean(np.log(np.maximum(per, 1e-30))))) if per else float("inf")


def _temp(tau: np.ndarray, degree: int) -> np.ndarray:
    return np.stack([tau ** q for q in range(degree + 1)], axis=1)


def _sine_columns(m0: float, slope: float, q: int) -> Columns:
    def cols(x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        m = np.clip(m0 * (1.0 + slope * tau), 1e-3, 0.999)
        arc = np.arcsin(np.clip(m * x, -1.0, 1.0)) / m
        return np.hstack([_temp(tau, q), arc[:, None] * _temp(tau, q)])
    return cols


def _poly_columns(form: RateForm) -> Columns:
    return lambda x, tau: design(x, tau, form)


def _power_columns(powers: list[int], abs_term: bool, r: int) -> Columns:
    def cols(x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        terms = [np.abs(x)] if abs_term else []
        terms += [x ** p for p in powers]
        if not terms:
            return np.zeros((x.shape[0], 0))
        return np.hstack([t[:, None] * _temp(tau, r) for t in terms])
    return cols


def _join(*parts: Columns) -> Columns:
    return lambda x, tau: np.hstack([p(x, tau) for p in parts])


def _sse(rows: RateRows, cols: Columns, target: np.ndarray) -> float:
    a = cols(rows.x, rows.tau)
    err = a @ solve(a, target) - target
    return float(err @ err)


def _best_sine(rows: RateRows, target: np.ndarray, q: int, extra: Columns
               ) -> tuple[float, float, float]:
    """(held-out score, m0, slope) of the sine whose (m0, slope) fit all plateaus best: a
    grid, then a pattern search halving its steps (the two are the sine's nonlinear
    parameters; the rest is least squares inside), then the held-out score at them."""
    def sse(m0: float, slope: float) -> float:
        return _sse(rows, _join(_sine_columns(m0, slope, q), extra), target)

    _, m0, slope = min((sse(m, k), float(m), float(k)) for m in SINE_M for k in SINE_SLOPE)
    dm, dk = float(SINE_M[1] - SINE_M[0]), float(SINE_SLOPE[1] - SINE_SLOPE[0])
    best = sse(m0, slope)
    while dm > 1e-6:
        moves = [(sse(m0 + a * dm, slope + b * dk), m0 + a * dm, slope + b * dk)
                 for a in (-1, 0, 1) for b in (-1, 0, 1) if (a, b) != (0, 0)
                 and 0.0 < m0 + a * dm < 1.0]
        trial = min(moves)
        if trial[0] < best:
            best, m0, slope = trial
        else:
            dm, dk = dm / 2, dk / 2
    return _cv(rows, _join(_sine_columns(m0, slope, q), extra), target, q), m0, slope


def diagnose_rate(rows: RateRows, full_scale_dps: float, allow: bool = True
                  ) -> RateDiagnosis:
    """Name the rate terms `rows` (a table's plateaus, y = (rate - output) / FS) measure."""
    to_dph = full_scale_dps * 3600.0
    target = rows.y + rows.x  # the rate over FS: the sine form has no x column to absorb it
    # the bias and SF's degree in T as the full model chooses it: chosen without the rate
    # terms it would answer the nonlinearity's residual, and confound the terms' comparison
    model = choose_form(rows, allow_rate_part=allow)
    q = model.form.temp_degree
    linear = _poly_columns(RateForm(1, False, q, 0))
    out = RateDiagnosis(base_dph=_cv(rows, linear, target, q) * to_dph,
                       rate_part_measured=allow)
    if not allow:
        return out
    odd = [p for p in range(3, MAX_POWER + 1, 2)]
    even = [p for p in range(2, MAX_POWER + 1, 2)]
    current: list[Columns] = []
    current_score = out.base_dph / to_dph
    have: set[str] = set()
    uses_sine = False
    while True:
        extra = _join(*current) if current else _power_columns([], False, 0)
        cands: list[tuple[float, TermScore, Columns]] = []
        if not have & {"sine", "odd polynomial"}:
            s, m0, slope = _best_sine(rows, target, q, extra)
            phase = float(np.arcsin(m0))
            cands.append((s, TermScore("sine", s * to_dph, phase,
                                       slope * m0 / np.sqrt(1 - m0 ** 2) / phase / 10.0 * 1e6),
                          _sine_columns(m0, slope, q)))
            for top in range(3, MAX_POWER + 1, 2):
                cols = _power_columns([p for p in odd if p <= top], False, 1)
                s = _cv(rows, _join(linear, extra, cols), target, max(q, 1))
                cands.append((s, TermScore("odd polynomial", s * to_dph), cols))
        if "asymmetry" not in have:
            cols = _power_columns([], True, 1)
            base = extra if uses_sine else _join(linear, extra)
            s = _cv(rows, _join(base, cols), target, max(q, 1))
            cands.append((s, TermScore("asymmetry", s * to_dph), cols))
        if "even terms" not in have:
            for top in range(2, MAX_POWER + 1, 2):
                cols = _power_columns([p for p in even if p <= top], False, 1)
                base = extra if uses_sine else _join(linear, extra)
                s = _cv(rows, _join(base, cols), target, max(q, 1))
                cands.append((s, TermScore("even terms", s * to_dph), cols))
        if not cands:
            break
        step = _best_per_term(cands)
        out.steps.append([c[1] for c in step])
        s, term, cols = step[0]
        if s * FOUND_GAIN > current_score:
            break
        out.named.append(term)
        have.add(term.term)
        uses_sine = uses_sine or term.term == "sine"
        current.append(cols)
        current_score = s
    out.model_form, out.model_dph = model.form.describe(), model.score * to_dph
    return out


def _best_per_term(cands: list[tuple[float, TermScore, Columns]]
                   ) -> list[tuple[float, TermScore, Columns]]:
    """Each term's best candidate, best first; the sine before an odd polynomial it ties."""
    best: dict[str, tuple[float, TermScore, Columns]] = {}
    for c in cands:
        if c[1].term not in best or c[0] < best[c[1].term][0]:
            best[c[1].term] = c
    order = {"sine": 0, "odd polynomial": 1, "asymmetry": 2, "even terms": 3}
    return sorted(best.values(), key=lambda c: (c[0], order[c[1].term]))
