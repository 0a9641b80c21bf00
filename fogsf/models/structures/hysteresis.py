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

Whether a structure gets the term is for held-out blocks of its training logs to say
(`training.structure.hysteresis`): the term is kept when it lowers their RMS by more than
HYST_GAIN, so gyros without hysteresis keep the structure they had.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.models.features import PHYSICAL_SCALE_C, FeatureSpec
from fogsf.models.structures.node_fit import RidgeFit
from fogsf.sim.effects import play_operator

# the play's width (C): from a loop too narrow to matter to wider than any the population
# draws (docs/population.md: 4-10 C); chosen on development gyros, refined below
WIDTH_GRID_C = tuple(float(w) for w in np.arange(1.0, 16.01, 1.0))
REFINE_STEP_C = 0.25  # the best grid width refined by this step within +-1 grid step
# Sources: T and the structure's lags up to MAX_SOURCE_TAU_S (a play of a lag slower than
# a coil's, which settles in 10-50 min, is a node by another name), alone or two of them
# mixed in MIX_FRACTIONS (a coil wound in layers sits between two lags).
MAX_SOURCE_TAU_S = 3000.0
MIX_FRACTIONS = (0.25, 0.5, 0.75)
MIX_BATCH = 16  # mixes whose plays run at once (memory: steps x 16 x widths columns)
# the term is kept when it lowers the held-out RMS by more than this fraction (development
# gyros, docs/decisions.md)
HYST_GAIN = 0.10


@dataclass(frozen=True)
class HystTerm:
    """The play, of width `width_c`, of frac * lag(T, tau_a) + (1 - frac) * lag(T, tau_b)
    (a time constant 0: T itself)."""

    tau_a_s: float
    tau_b_s: float
    frac: float
    width_c: float

    def describe(self) -> str:
        def name(t: float) -> str:
            return "T" if t == 0 else f"lag(T,{t:.0f}s)"

        src = name(self.tau_a_s) if self.frac == 1.0 else \
            f"{self.frac:g} {name(self.tau_a_s)} + {1 - self.frac:g} {name(self.tau_b_s)}"
        return f"play({src}, {self.width_c:g} C)"

    def as_dict(self) -> dict:
        return {"tau_a_s": self.tau_a_s, "tau_b_s": self.tau_b_s, "frac": self.frac,
                "width_c": self.width_c, "form": self.describe()}


def sources(taus_s: tuple[float, ...] | list[float]) -> list[float]:
    """0 (T) and the structure's lags up to MAX_SOURCE_TAU_S."""
    return [0.0] + [float(t) for t in taus_s if t <= MAX_SOURCE_TAU_S]


def mixes(taus_s: tuple[float, ...] | list[float]) -> list[tuple[float, float, float]]:
    """Every source alone, and every pair in MIX_FRACTIONS: (tau_a, tau_b, frac)."""
    src = sources(taus_s)
    out = [(a, a, 1.0) for a in src]
    out += [(a, b, f) for i, a in enumerate(src) for b in src[i + 1:] for f in MIX_FRACTIONS]
    return out


def plays_batch(x: np.ndarray, widths_c: np.ndarray) -> np.ndarray:
    """play(x_m, w_m) - x_m for many columns at once: x [n, M], widths [M] -> [n, M], each
    primed at its first value."""
    xs = np.asarray(x, dtype=np.float64)
    half = 0.5 * np.asarray(widths_c, dtype=np.float64)
    out = np.empty(xs.shape)
    if xs.shape[0] == 0:
        return out
    p = xs[0].copy()
    for i in range(xs.shape[0]):
        v = xs[i]
        p = np.minimum(np.maximum(p, v - half), v + half)
        out[i] = p - v
    return out


def mixed(source_x: dict[float, list[np.ndarray]], tau_a: float, tau_b: float, frac: float
          ) -> list[np.ndarray]:
    return [frac * a + (1.0 - frac) * b
            for a, b in zip(source_x[tau_a], source_x[tau_b], strict=True)]


def column(x_logs: list[np.ndarray], width_c: float) -> np.ndarray:
    """h = (play(x, w) - x) / 50 C per step, the play primed at each log's first step (as
    the front end primes it), stacked over the logs."""
    return np.concatenate([play_operator(x, width_c) - x for x in x_logs]) / PHYSICAL_SCALE_C


def term_column(source_x: dict[float, list[np.ndarray]], term: HystTerm) -> np.ndarray:
    return column(mixed(source_x, term.tau_a_s, term.tau_b_s, term.frac), term.width_c)


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
    a = g + pen * np.diag(pen_mask) + 1e-12 * float(np.trace(g)) * np.eye(g.shape[0])
    coef = np.linalg.solve(a, xc.T @ yc)
    resid = yc - xc @ coef
    return RidgeFit(ym - float(mu @ coef), coef, float(resid @ resid),
                    float(np.trace(np.linalg.solve(a, g))) + 1.0)


def _sse_batch(x: np.ndarray, hs: np.ndarray, y: np.ndarray, lam: float, free: int
               ) -> np.ndarray:
    """The SSE of ridge_fit_free for design x with column `free` replaced by each column of
    hs [n, M] (x's own column `free` is ignored), all at once (the Schur complement of the
    bordered normal equations)."""
    base = np.delete(np.asarray(x, dtype=np.float64), free, axis=1)
    mu, ym = base.mean(axis=0), float(np.mean(y))
    bc, yc = base - mu, y - ym
    hc = hs - hs.mean(axis=0)
    g = bc.T @ bc
    a = g + lam * float(np.mean(np.diag(g))) * np.eye(g.shape[0])
    by, hy = bc.T @ yc, hc.T @ yc
    bh = bc.T @ hc  # [p, M]
    hh = np.einsum("nm,nm->m", hc, hc)
    a_bh = np.linalg.solve(a, bh)
    b0 = np.linalg.solve(a, by)
    schur = hh - np.einsum("pm,pm->m", bh, a_bh)
    c = (hy - bh.T @ b0) / np.where(schur > 1e-12 * (hh + 1e-300), schur, np.inf)
    b = b0[:, None] - a_bh * c[None, :]  # [p, M]
    fit_y = np.einsum("pm,p->m", b, by) + c * hy
    quad = np.einsum("pm,pm->m", b, g @ b) + 2.0 * c * np.einsum("pm,pm->m", b, bh) \
        + c * c * hh
    return float(yc @ yc) - 2.0 * fit_y + quad


def choose_term(design: Callable[[np.ndarray], np.ndarray], y: np.ndarray, rows: np.ndarray,
                source_x: dict[float, list[np.ndarray]], lam: float, free: int,
                candidates: list[tuple[float, float, float]] | None = None
                ) -> tuple[HystTerm, RidgeFit]:
    """The term (source mix, width) whose column h fits `rows` of y with the least squared
    error in design(h) (the structure's design holding h as column `free`, unpenalised):
    every mix of `candidates` (default: all of source_x's, `mixes`) at every width of
    WIDTH_GRID_C, then the best width refined."""
    cands = candidates if candidates is not None else mixes(
        [t for t in source_x if t > 0])
    x0 = design(np.zeros(y.size))[rows]
    yr = y[rows]
    widths = np.asarray(WIDTH_GRID_C)
    # (mix, width) columns in batches of MIX_BATCH mixes (their plays run at once)
    best: tuple[float, tuple[tuple[float, float, float], float]] | None = None
    for i in range(0, len(cands), MIX_BATCH):
        grid = [(m, float(w)) for m in cands[i:i + MIX_BATCH] for w in widths]
        sse = _sse_batch(x0, _columns(source_x, grid)[rows], yr, lam, free)
        k = int(np.argmin(sse))
        if best is None or sse[k] < best[0]:
            best = (float(sse[k]), grid[k])
    assert best is not None
    (a, b, f), w0 = best[1]
    step = widths[1] - widths[0]
    fine = [(( a, b, f), float(w)) for w in np.arange(w0 - step + REFINE_STEP_C, w0 + step,
                                                     REFINE_STEP_C) if w > 0]
    sse = _sse_batch(x0, _columns(source_x, fine)[rows], yr, lam, free)
    term = HystTerm(a, b, f, round(fine[int(np.argmin(sse))][1], 4))
    x = design(term_column(source_x, term))
    return term, ridge_fit_free(x[rows], yr, lam, [free])


def _columns(source_x: dict[float, list[np.ndarray]],
             grid: list[tuple[tuple[float, float, float], float]]) -> np.ndarray:
    """h = (play - x) / 50 C for every ((tau_a, tau_b, frac), width) of `grid`, stacked over
    the logs [n, len(grid)]."""
    n_logs = len(next(iter(source_x.values())))
    out = []
    for i in range(n_logs):
        x = np.column_stack([f * source_x[a][i] + (1.0 - f) * source_x[b][i]
                             for (a, b, f), _ in grid])
        out.append(plays_batch(x, np.array([w for _, w in grid])))
    return np.vstack(out) / PHYSICAL_SCALE_C


def source_weights(term: HystTerm, taus_s: tuple[float, ...]) -> tuple[float, ...]:
    """The term's source as weights over [T, lag_1..lag_K] of a spec with `taus_s`."""
    w = [0.0] * (1 + len(taus_s))
    for tau, f in ((term.tau_a_s, term.frac), (term.tau_b_s, 1.0 - term.frac)):
        if f == 0.0:
            continue
        if tau == 0:
            w[0] += f
            continue
        match = [i for i, t in enumerate(taus_s) if abs(t - tau) < 1e-6]
        if not match:
            raise ValueError(f"the structure has no lag of {tau:g} s")
        w[1 + match[0]] += f
    return tuple(w)


def spec_with_play(spec: FeatureSpec, term: HystTerm) -> FeatureSpec:
    """`spec` with the feature play(x) - x appended, x the term's source (weights over T
    and the spec's lags)."""
    k = len(spec.taus_s)
    src = source_weights(term, spec.taus_s)
    rows = [tuple(r) + (0.0,) for r in spec.rows]
    row = [-v for v in src] + [0.0] * (len(spec.plays) + 1)
    row[-1] = 1.0
    rows.append(tuple(row))
    assert len(row) == 1 + k + len(spec.plays) + 1
    return FeatureSpec(spec.taus_s, tuple(rows), (*spec.names, term.describe()),
                       (*spec.plays, (src, float(term.width_c))))
