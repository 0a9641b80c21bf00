"""A hysteresis term in a compensation structure: the play (backlash) operator of T or of one
of the structure's lags.

Real coils show rate-independent hysteresis of the SF (potting stress that sticks and
releases: the simulator's `hysteresis` effect), which no filter of T represents: it holds
its value through a soak and depends on where the temperature turned back, not on the rate.
The term is one feature h = (play(x, w) - x) / 50 C, x the block-mean temperature T (source
0) or one of the structure's lag filters (source k), w the play's width: the firmware's
front end runs the play (docs/stream-contract.md, "Play operators"), so the model stays
exact in C. The structure's coefficients are fitted as before (ridge) with h's coefficient
unpenalised (its scale is the hysteresis strength in ppm/C; shrinking it would leave half
the loop). (source, width) are chosen on a grid by the fitted rows' squared error.

Whether a structure gets the term is for its held-out segments to say
(`training.structure_choice`): the term is kept when it lowers the leave-one-segment-out
RMS by more than HYST_GAIN, so gyros without hysteresis keep the structure they had.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.trainer.models.features import PHYSICAL_SCALE_C, FeatureSpec
from fogsf.trainer.models.node_fit import RidgeFit
from fogsf.trainer.sim.effects import play_operator

# the play's width (C): from a loop too narrow to matter to wider than any the population
# draws (docs/population.md: 4-10 C); chosen on development gyros, refined below
WIDTH_GRID_C = tuple(float(w) for w in np.arange(1.0, 16.01, 1.0))
REFINE_STEP_C = 0.25  # the best grid width refined by this step within +-1 grid step
# Sources slower than this are not tried: a play of a lag slower than the coil's (a small
# FOG's coil settles in 10-50 min) is a node by another name.
MAX_SOURCE_TAU_S = 3000.0
# the term is kept when it lowers the held-out RMS by more than this fraction (development
# gyros, docs/decisions.md)
HYST_GAIN = 0.05


@dataclass(frozen=True)
class HystTerm:
    """The play of source `source_tau_s` (0: T itself) with width `width_c`."""

    source_tau_s: float
    width_c: float

    def describe(self) -> str:
        src = "T" if self.source_tau_s == 0 else f"lag(T,{self.source_tau_s:.0f}s)"
        return f"play({src}, {self.width_c:g} C)"


def sources(taus_s: tuple[float, ...] | list[float]) -> list[float]:
    """0 (T) and the structure's lags up to MAX_SOURCE_TAU_S."""
    return [0.0] + [float(t) for t in taus_s if t <= MAX_SOURCE_TAU_S]


def column(x_logs: list[np.ndarray], width_c: float) -> np.ndarray:
    """h = (play(x, w) - x) / 50 C per step, the play primed at each log's first step (as
    the front end primes it), stacked over the logs."""
    return np.concatenate([play_operator(x, width_c) - x for x in x_logs]) / PHYSICAL_SCALE_C


def ridge_fit_free(x: np.ndarray, y: np.ndarray, lam: float, free: list[int]) -> RidgeFit:
    """Ridge of y on the columns of x, the intercept and the columns `free` unpenalised, the
    penalty `lam` times the mean diagonal of the penalised columns' centred Gram matrix (so
    the others are penalised as they would be alone)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    mu, ym = x.mean(axis=0), float(np.mean(y))
    xc, yc = x - mu, y - ym
    g = xc.T @ xc
    pen_mask = np.ones(x.shape[1])
    pen_mask[free] = 0.0
    pen = lam * float(np.mean(np.diag(g)[pen_mask > 0])) if pen_mask.any() else 0.0
    a = g + pen * np.diag(pen_mask)
    coef = np.linalg.solve(a + 1e-12 * np.trace(g) * np.eye(g.shape[0]), xc.T @ yc)
    resid = yc - xc @ coef
    h = np.linalg.solve(a + 1e-12 * np.trace(g) * np.eye(g.shape[0]), g)
    return RidgeFit(ym - float(mu @ coef), coef, float(resid @ resid),
                    float(np.trace(h)) + 1.0)


def choose_term(design: Callable[[np.ndarray], np.ndarray], y: np.ndarray, rows: np.ndarray,
                source_x: dict[float, list[np.ndarray]], lam: float, free: int
                ) -> tuple[HystTerm, RidgeFit]:
    """The (source, width) whose column h fits `rows` of y with the least squared error in
    design(h) (the structure's design holding h as column `free`, unpenalised), on
    WIDTH_GRID_C, then refined."""
    best: tuple[float, HystTerm, RidgeFit] | None = None

    def try_term(term: HystTerm) -> None:
        nonlocal best
        h = column(source_x[term.source_tau_s], term.width_c)
        x = design(h)
        fit = ridge_fit_free(x[rows], y[rows], lam, [free])
        if best is None or fit.sse < best[0]:
            best = (fit.sse, term, fit)

    for src in source_x:
        for w in WIDTH_GRID_C:
            try_term(HystTerm(src, w))
    assert best is not None
    step = WIDTH_GRID_C[1] - WIDTH_GRID_C[0]
    src, w0 = best[1].source_tau_s, best[1].width_c
    for w in np.arange(w0 - step + REFINE_STEP_C, w0 + step, REFINE_STEP_C):
        if w > 0 and abs(w - w0) > 1e-9:
            try_term(HystTerm(src, round(float(w), 4)))
    return best[1], best[2]


def spec_with_play(spec: FeatureSpec, term: HystTerm) -> FeatureSpec:
    """`spec` with the feature play(x) - x appended (x: T, or the spec's lag of the term's
    source time constant)."""
    k = len(spec.taus_s)
    if term.source_tau_s == 0:
        src = 0
    else:
        match = [i for i, t in enumerate(spec.taus_s) if abs(t - term.source_tau_s) < 1e-6]
        if not match:
            raise ValueError(f"the structure has no lag of {term.source_tau_s:g} s")
        src = 1 + match[0]
    rows = [tuple(r) + (0.0,) for r in spec.rows]
    row = [0.0] * (1 + k + len(spec.plays) + 1)
    row[-1], row[src] = 1.0, -1.0
    rows.append(tuple(row))
    return FeatureSpec(spec.taus_s, tuple(rows), (*spec.names, term.describe()),
                       (*spec.plays, (src, float(term.width_c))))
