"""The lag bank: the default model's structure, chosen over the gyro population.

A real gyro's SF error is a sum of polynomials of several internal temperatures, each
lagging the board thermometer differently (and with either sign), so no one or two
effective nodes hold it. The bank holds them all at once: the board temperature T and its
first-order lag filters at every time constant of `TAU_GRID_S` (60 s .. 2 h), each entering
on its own: T and the lags up to CURVED_MAX_TAU_S (2000 s) as cubics, the slower lags
linearly, all fitted together by ridge regression with a penalty that is a physics prior
chosen on development gyros (BANK_LAMBDA). Logs with many held-out parts may lower it and
add the cross terms of the curved features (`bankx`: a part's quadratic law is a
quadratic form in the lags; `training.structure.choice`: where the data decides, the prior
gives way). No structure is selected, so there is no selection to get wrong; the penalty shrinks
what the data does not determine.

Chosen over the alternatives on development gyros (docs/decisions.md has the figures):
one effective node with a cubic (`--structure node`), the best of one and two nodes, the
mean and the median of every lag model consistent with the training data, the lag model of
least node sensitivity, a quadratic bank with cross terms at the prior on every log (it is
now a step of the choice on logs of many held-out parts), varying-coefficient forms in
T - lag(T) with block cross-validation.

In the firmware contract the bank is the polynomial head over 1 + K features (T and the K
filters, normalised: a diagonal feature map, `feat_diag`): the linear terms in skip_w, the
squares in quad_w (its diagonal form, `quad_diag`, or the full [F, F] with the cross
terms), the cubes in cube_w; the LSTM, reading the first
BANK_LSTM_INPUTS features, then learns what the bank leaves, with the bank held fixed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.models.features import FeatureSpec
from fogsf.models.structures.least_squares import TAU_GRID_S

# The ridge penalty, as a multiple of the centred design's mean diagonal (so it does not
# depend on the logs' length): a fixed physics prior, the same for every gyro. Penalties
# chosen from the training data lose in the tail: collinear lags let them go small, and the
# cubes then extrapolate (docs/decisions.md; benchmarks/probes/README.md, "The bank's prior").
BANK_LAMBDA = 1e-3
# The prior of logs that ramp both up and down (a loop; fewer held-out parts than the
# penalty rule needs, `training.structure.penalty.bank_prior`): ramps in both directions
# decide the lags' fine structure better than ramps one way, and a chain of parts' delay
# is a difference of lags that BANK_LAMBDA shrinks; ramps one way keep BANK_LAMBDA
# (docs/decisions.md; benchmarks/probes/README.md, "The loop's prior").
LOOP_LAMBDA = 1e-4
# Lags slower than this enter linearly only: the SF's curvature is carried by T and the
# faster lags, the slow lags carry the hysteresis as a first-order correction. Cubics of slow
# lags extrapolate worst where a run takes them beyond the training range
# (docs/decisions.md; benchmarks/probes/README.md, "Bank time constants").
CURVED_MAX_TAU_S = 2000.0
# The LSTM that learns what the bank leaves reads the first this many bank features (T, then
# the fastest lags): its input weights are most of a model's flash (4H per input), and three
# models must fit one Cortex-M4F image in 24 KB (docs/firmware.md). Set from a comparison on
# development gyros (docs/decisions.md).
BANK_LSTM_INPUTS = 1


def bank_name(lam: float = BANK_LAMBDA, cross: bool = False) -> str:
    """The structure name of the bank fitted with penalty `lam`: "bank" at the prior
    BANK_LAMBDA, else "bank:LAM" (a penalty the training logs chose,
    `training.structure.choice`); "bankx", "bankx:LAM" with the cross terms of the curved
    features in its quadratic (`bank_design`)."""
    stem = "bankx" if cross else "bank"
    return stem if lam == BANK_LAMBDA else f"{stem}:{lam!r}"


def bank_penalty(name: str) -> float | None:
    """The ridge penalty of a bank structure name (`bank_name`); None for any other."""
    stem, _, lam = name.partition(":")
    if stem not in ("bank", "bankx"):
        return None
    return float(lam) if lam else BANK_LAMBDA


def bank_cross(name: str) -> bool:
    """Whether the bank structure `name` (`bank_name`) has the cross terms."""
    return name.partition(":")[0] == "bankx"


def bank_spec(grid: tuple[float, ...] = TAU_GRID_S) -> FeatureSpec:
    """Features T and lag(T, tau) for every tau of `grid`: the rows of an identity."""
    k = len(grid)
    rows = tuple(tuple(1.0 if j == i else 0.0 for j in range(k + 1)) for i in range(k + 1))
    names = ("T",) + tuple(f"lag(T,{t:.0f}s)" for t in grid)
    return FeatureSpec(tuple(float(t) for t in grid), rows, names)


def n_curved(grid: tuple[float, ...] = TAU_GRID_S) -> int:
    """How many bank features (T first, then the lags in grid order) carry squares and cubes:
    T and every lag of at most CURVED_MAX_TAU_S."""
    return 1 + sum(1 for t in grid if t <= CURVED_MAX_TAU_S)


def bank_design(z: np.ndarray, curved: int | None = None, cross: bool = False) -> np.ndarray:
    """Columns z of every feature, then z^2 and z^3 of the first `curved` (default: all);
    with `cross`, then z_i z_j of every pair i < j of them (`cross_pairs`' order)."""
    x = np.asarray(z, dtype=np.float64)
    c = x[:, :x.shape[1] if curved is None else curved]
    cols = [x, c * c, c * c * c]
    if cross:
        i, j = cross_pairs(c.shape[1])
        cols.append(c[:, i] * c[:, j])
    return np.column_stack(cols)


def cross_pairs(curved: int) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (i, j), i < j, of the first `curved` features, row by row."""
    i, j = np.triu_indices(curved, 1)
    return i, j


def head_terms(coef: np.ndarray, k: int, curved: int, cross: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lin, quad, cube) of the coefficients of `bank_design(z, curved, cross)` over k
    features (extra columns after them, e.g. a free term's, ignored): quad the diagonal [k],
    or with `cross` the upper-triangular [k, k] (z^T quad z, the firmware's full quad_w)."""
    quad: np.ndarray
    quad, cube = np.zeros(k), np.zeros(k)
    quad[:curved], cube[:curved] = coef[k:k + curved], coef[k + curved:k + 2 * curved]
    if cross:
        i, j = cross_pairs(curved)
        full = np.diag(quad)
        full[i, j] = coef[k + 2 * curved:k + 2 * curved + i.size]
        quad = full
    return coef[:k], quad, cube


@dataclass
class BankFit:
    """A ridge fit of the bank in normalised units: y = intercept + lin.z + quad.z^2 +
    cube.z^3 (y the normalised target)."""

    intercept: float
    lin: np.ndarray
    quad: np.ndarray
    cube: np.ndarray
    lam: float  # the penalty, as a multiple of the design's mean diagonal
    dof: float  # effective degrees of freedom of the fit

    def predict(self, z: np.ndarray) -> np.ndarray:
        x = np.asarray(z, dtype=np.float64)
        sq = (x * x) @ self.quad if self.quad.ndim == 1 else np.sum((x @ self.quad) * x, 1)
        return self.intercept + x @ self.lin + sq + (x * x * x) @ self.cube


def fit_bank(z: np.ndarray, y: np.ndarray, lam: float = BANK_LAMBDA,
             curved: int | None = None, cross: bool = False) -> BankFit:
    """Ridge regression of y on bank_design(z, curved, cross), the intercept unpenalised,
    with penalty `lam` times the centred design's mean diagonal."""
    x = bank_design(z, curved, cross)
    y = np.asarray(y, dtype=np.float64)
    mu, ym = x.mean(axis=0), float(np.mean(y))
    xc = x - mu
    u, sv, vt = np.linalg.svd(xc, full_matrices=False)
    uy = u.T @ (y - ym)
    scale = float(np.mean(sv**2))
    f = sv**2 / (sv**2 + lam * scale)
    coef = vt.T @ (sv / (sv**2 + lam * scale) * uy)
    k = z.shape[1]
    lin, quad, cube = head_terms(coef, k, k if curved is None else curved, cross)
    return BankFit(intercept=ym - float(mu @ coef), lin=lin, quad=quad, cube=cube,
                   lam=lam, dof=float(f.sum()) + 1.0)
