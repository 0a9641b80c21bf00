"""The bias model's candidate structures and their fits to the training targets.

The candidates, smallest first (bias in deg/h, T the board temperature, n = lag(T, tau) a
coil node behind it):
- `cubic`: a + b T + c T^2 + d T^3, the autopilots' law (PX4, ArduPilot);
- `shupe`: the cubic in T plus e n: a Shupe term e' (T - n) / tau, the rate of change of
  the node (d n/dt = (T - n) / tau), carried by the linear terms of T and n;
- `node`: a + b T + c n + d n^2 + e n^3: the cubic law on the coil node and its Shupe term;
- `shupe2`: the cubic in T plus two lags linearly (a Shupe term of a node two lags away);
- `lead`: a cubic in the lead-lag node c = w T + (1 - w) lag(T, tau_c) and its rate of
  change dc/dt = w dT/dt + (T - c)/tau_c as one column (dT/dt from a 20 s lag): a coil
  behind the housing seen from a board behind the same housing is exactly such a node (w =
  the board's time constant over the coil's, > 1 when the coil is the faster), and the
  Shupe term is the coil's own rate; (tau_c, w) by the profile over a grid; its filters
  are its own (`Columns.own`): on the SF model's z it adds them to the SF model's front end;
- `bank`: the lag bank's polynomial of every feature (T, its lags at 11 time constants,
  cubes up to 2000 s) by ridge with the penalty chosen by GCV (`fit_gcv`).
Time constants are identified by variable projection (`models.structures.node_fit.varpro`, from the
best of a grid; lead's by its grid) when the bias model has its own front end (a bias-only model, or
an SF model without a firmware form); when the bias head shares the SF model's features z,
they are z's own lags (the best by least squares): the firmware's bias head reads z and
nothing else, so no new filter is needed.
The choice among them is `training.bias.choice`'s.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.models.structures.lag_bank import BankFit, bank_design, fit_bank, head_terms
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import ridge_fit, varpro
from fogsf.models.structures.physics_nodes import TAU_MAX_S, TAU_MIN_S

CANDIDATES = ("cubic", "shupe", "node", "shupe2", "lead", "bank")
# a whisker of ridge (a multiple of the centred design's mean diagonal) so that nearly
# collinear T and node columns do not cancel with huge coefficients
SMALL_LAMBDA = 1e-8


class Columns:
    """The columns a candidate is built from, at the training targets' steps: `t` (the
    board temperature, normalised), `lag(tau)` (a lag of it, the same unit) and `z` (every
    feature of the bank, for `bank`). `taus` is None when any time constant may be used
    (varpro), else the time constants available; then `own`, if given, are the same
    steps' columns at any time constant, which `lead` reads (filters of its own)."""

    def __init__(self, t: np.ndarray, lag: Callable[[float], np.ndarray],
                 taus: tuple[float, ...] | None, z: np.ndarray, curved: int,
                 own: Columns | None = None) -> None:
        self.t, self.lag, self.taus, self.z, self.curved = t, lag, taus, z, curved
        self.own = own
        self.lead_fast_s = LEAD_FAST_S  # the lag `lead` takes the board's rate from

    def any_tau(self) -> Columns | None:
        """Columns at any time constant: these, or `own`; None when there are none."""
        return self if self.taus is None else self.own


NODES = {"cubic": 0, "shupe": 1, "node": 1, "shupe2": 2, "lead": 2, "bank": 0}
# lead: the board's derivative from a 20 s lag (on the SF model's z, its fastest lag if at
# most LEAD_FAST_MAX_S: the bank's 60 s, no filter more, as good within the noise;
# benchmarks/probes/README.md, "Bias structure"); the coil's time constant
# and the lead-lag weight profiled over a grid (a coil lags the housing by 100-3000 s in
# the population, and w = the board's time constant over the coil's)
LEAD_FAST_S = 20.0
LEAD_FAST_MAX_S = 60.0
LEAD_TAU_GRID_S = tuple(float(x) for x in np.round(np.geomspace(100.0, 3000.0, 30), 1))
LEAD_W_GRID = tuple(float(x) for x in np.round(np.linspace(0.0, 3.0, 31), 2))
# The rate-transfer interval's `lead` set (`lead_set`): the grid points within the 95 %
# region of a two-parameter profile (chi-square, 2 degrees of freedom) of the best, at most
# LEAD_SET_MOST of them refitted. On a loop that ramps slower than the test, the training
# pairs hold models on both sides of the reversal target (`benchmarks.probes.
# bias_consistent`, docs/decisions.md).
LEAD_SET_CHI2 = 5.99
LEAD_SET_MOST = 12


def lead_node(t: np.ndarray, lag_c: np.ndarray, w: float) -> np.ndarray:
    """The coil as a lead-lag node of the board: w T + (1 - w) lag(T, tau_c) (a node behind
    the housing, seen from a board behind the same housing, is exactly this, w = the
    board's time constant / the coil's)."""
    return w * t + (1.0 - w) * lag_c


def lead_rate(t: np.ndarray, fast: np.ndarray, c: np.ndarray, taus: tuple[float, ...],
              w: float) -> np.ndarray:
    """The lead-lag node's rate of change: dc/dt = w dT/dt + (T - c) / tau_c, dT/dt from
    the fast lag, (T - lag(T, fast)) / fast."""
    return w * (t - fast) / taus[0] + (t - c) / taus[1]


def design(name: str, t: np.ndarray, n: list[np.ndarray], w: float | None = None,
           taus: tuple[float, ...] = ()) -> np.ndarray:
    """The candidate's columns (no intercept): T, T^2, T^3 and the lags linearly (cubic,
    shupe, shupe2), T, n, n^2, n^3 (node), or the lead-lag node c, its square and cube and
    its rate of change as one column (lead: the Shupe term tied to the node's own time
    constants, n = [lag(T, fast), lag(T, tau_c)], taus = (fast, tau_c))."""
    if name == "node":
        return np.column_stack([t, n[0], n[0] ** 2, n[0] ** 3])
    if name == "lead":
        assert w is not None
        c = lead_node(t, n[1], w)
        return np.column_stack([c, c * c, c * c * c, lead_rate(t, n[0], c, taus, w)])
    return np.column_stack([t, t * t, t * t * t, *n])


@dataclass
class CandidateFit:
    """A fitted candidate: predict(cols) on any Columns; `taus_s` its nodes' time constants."""

    name: str
    taus_s: tuple[float, ...]
    coef: np.ndarray  # design's coefficients (cubic/shupe/shupe2/node)
    intercept: float
    bank: BankFit | None = None
    w: float | None = None  # the lead-lag node's weight on T (lead)

    def predict(self, cols: Columns, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        if self.bank is not None:
            return self.bank.predict(cols.z[rows])
        return self.intercept + self.columns(cols, rows) @ self.coef

    def columns(self, cols: Columns, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """The design (no intercept) at `rows` of `cols`."""
        if self.bank is not None:
            return bank_design(cols.z[rows], cols.curved)
        if self.name == "lead":
            cols = _lead_columns(cols)
        n = [cols.lag(tau)[rows] for tau in self.taus_s]
        return design(self.name, cols.t[rows], n, self.w, self.taus_s)


def _fixed_taus(name: str, cols: Columns, rows: np.ndarray, y: np.ndarray,
                taus: tuple[float, ...], w: float | None = None) -> CandidateFit:
    f = ridge_fit(design(name, cols.t[rows], [cols.lag(tau)[rows] for tau in taus], w, taus),
                  y, SMALL_LAMBDA)
    return CandidateFit(name, taus, f.coef, f.intercept, None, w)


def _lead_columns(cols: Columns) -> Columns:
    own = cols.any_tau()
    if own is None:
        raise ValueError("lead needs lags at any time constant (Columns.own)")
    return own


def lead_profile(cols: Columns, rows: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The least-squares profile of `lead` (its SSE on the targets y at `rows`) over
    LEAD_TAU_GRID_S x LEAD_W_GRID: the coil's time constant by the lead-lag weight."""
    cols = _lead_columns(cols)
    sse = np.empty((len(LEAD_TAU_GRID_S), len(LEAD_W_GRID)))
    for i, tc in enumerate(LEAD_TAU_GRID_S):
        taus = (cols.lead_fast_s, tc)
        n = [cols.lag(tau)[rows] for tau in taus]
        for j, w in enumerate(LEAD_W_GRID):
            sse[i, j] = ridge_fit(design("lead", cols.t[rows], n, w, taus), y,
                                  SMALL_LAMBDA).sse
    return sse


def _fit_lead(cols: Columns, rows: np.ndarray, y: np.ndarray) -> CandidateFit:
    """The lead candidate: the coil's time constant and the lead-lag weight by the profile
    of the least-squares fit over LEAD_TAU_GRID_S x LEAD_W_GRID (the tied rate column makes
    the profile sharp enough to find the coil; a free derivative column did not)."""
    own = _lead_columns(cols)
    sse = lead_profile(own, rows, y)
    i, j = np.unravel_index(int(np.nanargmin(sse)), sse.shape)  # the first minimum
    return _lead_at(own, rows, y, int(i), int(j))


def _lead_at(own: Columns, rows: np.ndarray, y: np.ndarray, i: int, j: int) -> CandidateFit:
    """`lead` fitted at grid point (LEAD_TAU_GRID_S[i], LEAD_W_GRID[j]) of `own`."""
    return _fixed_taus("lead", own, rows, y, (own.lead_fast_s, LEAD_TAU_GRID_S[i]),
                       LEAD_W_GRID[j])


def lead_allowed(sse: np.ndarray, sigma2: float) -> np.ndarray:
    """The grid points [i, j] of a `lead_profile` whose SSE lies within LEAD_SET_CHI2 x
    sigma2 of its minimum (a two-parameter 95 % region), by SSE, the best first."""
    ok = np.argwhere(sse <= np.nanmin(sse) + LEAD_SET_CHI2 * sigma2)
    return ok[np.argsort(sse[ok[:, 0], ok[:, 1]], kind="stable")]


def lead_set(cols: Columns, y: np.ndarray, sigma2: float,
             most: int = LEAD_SET_MOST) -> list[CandidateFit]:
    """`lead` at the grid points the training targets cannot tell from its best: SSE
    within LEAD_SET_CHI2 x sigma2 (one target's noise variance) of the profile's minimum
    (a two-parameter 95 % region); at most `most` of them: the best, the extremes of each
    parameter among them, then evenly by SSE rank. Empty where the profile has no finite
    minimum."""
    rows = np.arange(y.size)
    own = _lead_columns(cols)
    sse = lead_profile(own, rows, y)
    if not np.isfinite(sse).any():
        return []
    ok = lead_allowed(sse, sigma2)
    keep = [0]
    for axis in (0, 1):  # the set's ends in tau and in w
        keep += [int(np.argmin(ok[:, axis])), int(np.argmax(ok[:, axis]))]
    keep += np.linspace(0, len(ok) - 1, min(most, len(ok))).astype(int).tolist()
    chosen = list(dict.fromkeys(keep))[:most]
    return [_lead_at(own, rows, y, int(i), int(j)) for i, j in ok[sorted(chosen)]]


def fit_candidate(name: str, cols: Columns, rows: np.ndarray, y: np.ndarray) -> CandidateFit:
    """Candidate `name` fitted to targets y at `rows` of `cols`."""
    if name == "bank":
        return CandidateFit(name, (), np.zeros(0), 0.0, fit_gcv(cols.z[rows], y, cols.curved))
    if name == "lead":
        return _fit_lead(cols, rows, y)
    k = NODES[name]
    grid = cols.taus if cols.taus is not None else TAU_GRID_S
    fits = [_fixed_taus(name, cols, rows, y, combo)
            for combo in itertools.combinations(sorted(grid), k)]
    sse = [float(np.sum((y - f.predict(cols, rows)) ** 2)) for f in fits]
    best = fits[int(np.argmin(sse))]
    if cols.taus is not None or k == 0:
        return best

    def columns(theta: np.ndarray) -> np.ndarray:
        return design(name, cols.t[rows], [cols.lag(float(math.exp(v)))[rows] for v in theta])

    vp = varpro(columns, y, np.log(np.asarray(best.taus_s)),
                np.full(k, math.log(TAU_MIN_S)), np.full(k, math.log(TAU_MAX_S)),
                SMALL_LAMBDA)
    return _fixed_taus(name, cols, rows, y, tuple(sorted(float(math.exp(v))
                                                         for v in vp.theta)))


def as_bank_fit(fit: CandidateFit, i_t: int, i_n: list[int], n_features: int) -> BankFit:
    """The candidate as the bias head's diagonal polynomial over z (n_features columns),
    T at column i_t, the nodes at i_n."""
    lin, quad, cube = np.zeros(n_features), np.zeros(n_features), np.zeros(n_features)
    c = fit.coef
    if fit.name == "node":
        lin[i_t] += c[0]
        lin[i_n[0]] += c[1]
        quad[i_n[0]], cube[i_n[0]] = c[2], c[3]
    else:
        lin[i_t], quad[i_t], cube[i_t] = c[0], c[1], c[2]
        for j, i in enumerate(i_n):
            lin[i] += c[3 + j]
    return BankFit(fit.intercept, lin, quad, cube, SMALL_LAMBDA, float(c.size + 1))


def pure_columns(feat_w: np.ndarray) -> tuple[int | None, dict[int, int]]:
    """(the feature that is T alone, {filter k: the feature that is lag k alone})."""
    i_t: int | None = None
    lags: dict[int, int] = {}
    for i, row in enumerate(np.asarray(feat_w, dtype=np.float64)):
        nz = np.flatnonzero(row)
        if nz.size != 1:
            continue
        if nz[0] == 0 and i_t is None:
            i_t = i
        elif nz[0] > 0 and int(nz[0]) - 1 not in lags:
            lags[int(nz[0]) - 1] = i
    return i_t, lags


# The bias's ridge penalties (multiples of the design's mean diagonal), chosen per fit by
# generalised cross-validation. Unlike the SF's fixed prior (lag_bank.BANK_LAMBDA, 1e-3):
# a bias target is white noise about the law (the gyro's angle random walk over a model
# step or a pair), which GCV is made for, and a Shupe term needs large coefficients of
# opposite sign on neighbouring lags (T - lag is a rate of change) that 1e-3 shrinks away
# (docs/decisions.md; benchmarks/probes/README.md, "Bias penalty").
BIAS_LAMBDAS = tuple(10.0 ** e for e in range(-8, 0))


def fit_gcv(z: np.ndarray, y: np.ndarray, curved: int) -> BankFit:
    """`fit_bank` at the penalty of BIAS_LAMBDAS with the least GCV score n RSS / (n - dof)^2;
    the design's SVD is taken once for every penalty (`fit_bank`'s arithmetic otherwise)."""
    x = bank_design(z, curved)
    y = np.asarray(y, dtype=np.float64)
    mu, ym = x.mean(axis=0), float(np.mean(y))
    u, sv, vt = np.linalg.svd(x - mu, full_matrices=False)
    uy = u.T @ (y - ym)
    scale = float(np.mean(sv**2))
    k = z.shape[1]
    n = y.size
    best: tuple[float, BankFit] | None = None
    for lam in BIAS_LAMBDAS:
        f = sv**2 / (sv**2 + lam * scale)
        coef = vt.T @ (sv / (sv**2 + lam * scale) * uy)
        lin, quad, cube = head_terms(coef, k, curved)
        fit = BankFit(intercept=ym - float(mu @ coef), lin=lin, quad=quad, cube=cube,
                      lam=lam, dof=float(f.sum()) + 1.0)
        if n - fit.dof <= 0:
            continue
        r = y - fit.predict(z)
        score = n * float(r @ r) / (n - fit.dof) ** 2
        if best is None or score < best[0]:
            best = (score, fit)
    return best[1] if best is not None else fit_bank(z, y, curved=curved)
