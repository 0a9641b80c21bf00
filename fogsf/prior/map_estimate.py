"""A new unit's parameters under the design's prior: their MAP, what the check against the
design and the prior's share per parameter group read (the unit's law `train --prior`
exports is fitted in the space of responses, `response_prior`).

theta = [log taus, coefficients] minimises
    J(theta) = |y - f(theta)|^2 / s^2 + (theta - mu)^T Sigma^-1 (theta - mu),
s^2 the unit's own residual variance (its data-only fit's, times the residuals'
correlation, `unit_fit.correlation_factor`). For fixed time constants the coefficients are
a generalised ridge toward the prior's conditional mean (closed form); the time constants
by Levenberg-Marquardt on the stacked residual [(y - f) / s, L (theta - mu)], L^T L =
Sigma^-1: a penalised variable projection. The posterior covariance, at the noise the
unit's law is fitted with (NOISE_SCALE s^2, `response_prior`), is (J^T J / (NOISE_SCALE s^2)
+ Sigma^-1)^-1: the prior's share per group reads it.

The unit's data disagree with the design when its data-only fit lies outside the prior
predictive: (theta_alone - mu)^T (Sigma_check + C)^-1 (theta_alone - mu) over the
chi-square(p) quantile at DISAGREE_LEVEL (C the fit's estimation covariance at NOISE_SCALE
times s^2, the noise `response_prior` fits with; Sigma_check the spread shrunk toward its
diagonal, `prior.DesignPrior.sigma_check`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fogsf.models.structures.physics_nodes import TAU_MAX_S, TAU_MIN_S
from fogsf.prior.design_prior import DesignPrior
from fogsf.prior.unit_fit import StepSeries, UnitFit, design_matrix, fit_unit, jacobian

DISAGREE_LEVEL = 1e-3
# the unit's own data weighed at this multiple of its estimated precision: 1 is the
# white-noise-with-correlation estimate (`unit_fit.correlation_factor`)
DATA_WEIGHT = 1.0
# a short run's noise in the unit's fit under the prior and in the check: this many times
# the unit's own estimate, because the design's responses also miss a run the fleet never
# ran (their common misfit, which the unit's own fit absorbs, counted as noise rather than
# bent into the unit's coefficients or read as the unit's difference from the design).
# Figures, for the fit and the check: benchmarks/probes/README.md, "Fleet prior: where it
# stops" ("The short run's noise").
NOISE_SCALE = 3.0
GROUPS = ("time constants", "intercept and linear", "quadratic and cross", "cubes")


@dataclass
class MapFit:
    k: int
    theta: np.ndarray
    cov: np.ndarray  # the posterior covariance at NOISE_SCALE s2 (the prior's share's)
    s2: float  # the data's noise variance used
    objective: float
    alone_objective: float
    chi2: float  # the data-only fit against the prior predictive (`check_chi2`)
    chi2_limit: float
    prior_share: dict[str, float]  # per group: the prior's share of the posterior precision
    alone_theta: np.ndarray

    @property
    def disagrees(self) -> bool:
        return self.chi2 > self.chi2_limit

    @property
    def taus_s(self) -> np.ndarray:
        return np.exp(self.theta[:self.k])

    def as_dict(self) -> dict:
        return {"k": self.k, "taus_s": self.taus_s.tolist(),
                "theta": self.theta.tolist(), "s2": self.s2,
                "chi2": self.chi2, "chi2_limit": self.chi2_limit,
                "disagrees": self.disagrees, "prior_share": self.prior_share,
                "alone_taus_s": np.exp(self.alone_theta[:self.k]).tolist()}


def chi2_quantile(p: int, level: float) -> float:
    """The upper `level` quantile of chi-square(p) (Wilson-Hilferty)."""
    z = _normal_upper(level)
    return p * (1.0 - 2.0 / (9.0 * p) + z * math.sqrt(2.0 / (9.0 * p))) ** 3


def _normal_upper(level: float) -> float:
    lo, hi = 0.0, 10.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(mid / math.sqrt(2.0)) > level:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _chol_inv(sigma: np.ndarray) -> np.ndarray:
    """L with L^T L = Sigma^-1."""
    prec = np.linalg.inv(sigma)
    prec = 0.5 * (prec + prec.T)
    return np.linalg.cholesky(prec).T


class _Problem:
    def __init__(self, series: StepSeries, prior: DesignPrior, s2: float) -> None:
        self.series, self.prior, self.k = series, prior, prior.k
        self.s = math.sqrt(s2)
        self.lmat = _chol_inv(prior.sigma)

    def coef(self, log_tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(theta, stacked residual) with the coefficients at their conditional MAP."""
        k, mu, lm = self.k, self.prior.mu, self.lmat
        x = design_matrix(self.series, np.exp(log_tau), self.prior.play)
        a = np.vstack([x / self.s, lm[:, k:]])
        b = np.concatenate([self.series.y / self.s,
                            lm[:, k:] @ mu[k:] - lm[:, :k] @ (log_tau - mu[:k])])
        beta = np.linalg.lstsq(a, b, rcond=None)[0]
        theta = np.concatenate([log_tau, beta])
        r = np.concatenate([(self.series.y - x @ beta) / self.s, lm @ (theta - mu)])
        return theta, r


def map_fit(series: StepSeries, prior: DesignPrior, max_iter: int = 30,
            data_weight: float | None = None) -> MapFit:
    """The new unit's MAP under `prior`, its posterior, the prior's share, the check.
    `data_weight`: the unit's noise variance divided by this (default DATA_WEIGHT)."""
    k = prior.k
    alone = fit_unit(series, k, np.exp(prior.mu[:k]), prior.play)
    grid_alone = fit_unit(series, k, play=prior.play)
    if grid_alone.sse < alone.sse:
        alone = grid_alone
    s2 = alone.sigma2 / (DATA_WEIGHT if data_weight is None else data_weight)
    pb = _Problem(series, prior, s2)
    starts = [prior.mu[:k].copy(), np.sort(alone.theta[:k])]
    best: tuple[float, np.ndarray] | None = None
    for st in starts:
        theta = _lm(pb, st, max_iter)
        _, r = pb.coef(theta[:k])
        obj = float(r @ r)
        if best is None or obj < best[0]:
            best = (obj, theta)
    assert best is not None
    obj, theta = best
    jac = jacobian(series, theta, k, play=prior.play)
    # at the noise the unit's law is fitted with (response_prior)
    cov = np.linalg.inv(jac.T @ jac / (s2 * NOISE_SCALE) + np.linalg.inv(prior.sigma))
    alone_obj = alone.sse / s2
    p = theta.size
    return MapFit(k, theta, cov, s2, obj, alone_obj,
                  check_chi2(series, prior, alone.sigma2 * NOISE_SCALE, alone, max_iter),
                  chi2_quantile(p, DISAGREE_LEVEL),
                  _shares(cov, prior.sigma, k, prior.play is not None), alone.theta)


def check_problem(series: StepSeries, prior: DesignPrior, s2: float) -> _Problem:
    """The check's objective J_check: the prior's spread shrunk toward its diagonal
    (`DesignPrior.sigma_check`); `coef(log_tau)` its minimum over the law's coefficients."""
    return _Problem(series, DesignPrior(**{**prior.__dict__, "sigma": prior.sigma_check}), s2)


def check_chi2(series: StepSeries, prior: DesignPrior, s2: float, alone: UnitFit,
               max_iter: int) -> float:
    """min_theta J_check(theta) - |y - f(theta_alone)|^2 / s^2, J_check the objective with
    the spread shrunk toward its diagonal (`DesignPrior.sigma_check`), s^2 the noise the
    check reads (`map_fit`: NOISE_SCALE times the unit's own estimate): for a linear model
    (theta_alone - mu)^T (Sigma_check + C)^-1 (theta_alone - mu), the unit's data-only fit
    against the design's prior predictive, without inverting the short run's C."""
    pb = check_problem(series, prior, s2)
    best = min(float(r @ r) for r in (pb.coef(_lm(pb, st, max_iter)[:prior.k])[1]
                                       for st in (prior.mu[:prior.k].copy(),
                                                  np.sort(alone.theta[:prior.k]))))
    return best - alone.sse / s2


def _groups(k: int, play: bool = False) -> dict[str, list[int]]:
    """theta's indices per group (the play's, `unit_fit.play_index`, is linear)."""
    f = k + 1
    lin = list(range(k, k + 1 + f + int(play)))
    q0 = lin[-1] + 1
    quad = list(range(q0, q0 + f * (f + 1) // 2))
    return {GROUPS[0]: list(range(k)), GROUPS[1]: lin, GROUPS[2]: quad,
            GROUPS[3]: list(range(quad[-1] + 1, quad[-1] + 1 + f))}


def _shares(cov: np.ndarray, sigma: np.ndarray, k: int, play: bool = False
            ) -> dict[str, float]:
    """Per group, the mean over its parameters of posterior variance / prior variance:
    the prior's share of the posterior precision (1: the data added nothing)."""
    v = np.diag(cov) / np.diag(sigma)
    return {g: float(np.clip(np.mean(v[idx]), 0.0, 1.0))
            for g, idx in _groups(k, play).items()}


def _lm(pb: _Problem, log_tau0: np.ndarray, max_iter: int) -> np.ndarray:
    lo, hi = math.log(TAU_MIN_S), math.log(TAU_MAX_S)
    x = np.clip(log_tau0, lo, hi)
    theta, r = pb.coef(x)
    sse = float(r @ r)
    mu = 1e-2
    for _ in range(max_iter):
        jac = np.empty((r.size, x.size))
        for j in range(x.size):
            t = x.copy()
            h = 1e-3 if t[j] + 1e-3 <= hi else -1e-3
            t[j] += h
            jac[:, j] = (pb.coef(t)[1] - r) / h
        jtj, jtr = jac.T @ jac, jac.T @ r
        improved = False
        for _ in range(8):
            step = -np.linalg.solve(jtj + mu * np.diag(np.diag(jtj) + 1e-12), jtr)
            cand = np.clip(x + step, lo, hi)
            th2, r2 = pb.coef(cand)
            s2 = float(r2 @ r2)
            if s2 < sse:
                gain = (sse - s2) / max(sse, 1e-300)
                x, theta, r, sse = cand, th2, r2, s2
                mu = max(mu / 3.0, 1e-9)
                improved = True
                break
            mu *= 4.0
        if not improved or gain < 1e-7:
            break
    return theta

