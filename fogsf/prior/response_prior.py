"""A new unit under its design's prior, in the space of responses: what `fogsf train --prior`
fits and `fogsf plan --prior` plans with.

Each unit of the fleet, fitted on its full program at the design's structure
(`DesignPrior.unit_thetas`), is a function f_i from a temperature history to the SF error.
The new unit's function is drawn around theirs:
    f = m + D a + J b,   a ~ N(0, LAM_UNITS I),   b ~ N(0, LAM_PARAMS I),
m the units' mean response, D their deviations from it over sqrt(N - 1) (the fleet's own
spread of responses, rank N - 1: what real units of the design do, whatever form the
physics has), J the response's Jacobian at the design's parameters times a square root of
their spread (`DesignPrior.sigma`: the directions a few units did not happen to span).
The short run's steps y = f + e, e ~ N(0, NOISE_SCALE s^2), s^2 the unit's own residual
variance with its correlation (`unit_fit.correlation_factor`), NOISE_SCALE > 1
(`map_estimate`: the design's responses also miss a run the fleet never ran); the posterior
of (a, b) is a ridge in closed form, its mean the unit's response on any history
(`predict`), its covariance the spread of that response (`variance`, the interval's).

The units' fits and J carry the design's play when it has one (`DesignPrior.play`). The
exported model is an ordinary physics-node model (with the play
in its front end when the design has one): `law` fits the design's structure (as
`unit_fit.fit_unit` fits a unit) to the posterior mean response on the fleet's reference
program and the unit's own runs, the law the model's head carries.

The weights LAM_UNITS and LAM_PARAMS: benchmarks/probes/README.md, "Fleet prior: where it
stops" ("The response prior against the MAP of the parameters").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.prior.design_prior import DesignPrior
from fogsf.prior.map_estimate import NOISE_SCALE
from fogsf.prior.unit_fit import (
    StepSeries,
    all_steps,
    fit_unit,
    jacobian,
    predict,
    window_means,
)

LAM_UNITS = 1.0
LAM_PARAMS = 0.3


def _root(sigma: np.ndarray) -> np.ndarray:
    """R with R R^T = sigma (sigma symmetric, eigenvalues floored at zero)."""
    ev, vec = np.linalg.eigh(0.5 * (sigma + sigma.T))
    return vec * np.sqrt(np.maximum(ev, 0.0))


@dataclass
class FunctionFit:
    """A new unit's posterior under the prior: the basis coefficients' mean and covariance
    (`function_fit`), read on any temperature history through `basis`."""

    prior: DesignPrior
    a: np.ndarray  # posterior mean of the basis coefficients [a, b]
    a_cov: np.ndarray  # their posterior covariance
    s2: float  # the data's noise variance used
    own: StepSeries  # the unit's training runs
    lam: tuple[float, float] = (LAM_UNITS, LAM_PARAMS)
    # (m, B) on `own`, as the fit computed it: each unit of the fleet is read on a series
    # for it, so with a fleet of hundreds it is computed once, not again for the misfit
    own_basis: tuple[np.ndarray, np.ndarray] | None = None

    def basis(self, series: StepSeries) -> tuple[np.ndarray, np.ndarray]:
        """(m, B) on `series`' rows (`response_basis` at this fit's weights)."""
        if series is self.own and self.own_basis is not None:
            return self.own_basis
        return response_basis(self.prior, series, *self.lam)

    def predict(self, series: StepSeries) -> np.ndarray:
        """The posterior mean response (ppm) on `series`' rows."""
        m, b = self.basis(series)
        return m + b @ self.a

    def variance(self, series: StepSeries) -> np.ndarray:
        """The posterior variance (ppm^2) of the response on `series`' rows."""
        _, b = self.basis(series)
        return np.sum((b @ self.a_cov) * b, axis=1)  # diag(B C B^T), by BLAS

    def misfit_ppm2(self) -> float:
        """The slow part of the posterior mean's residual on the unit's own runs (ppm^2): the
        mean square of its WINDOW_S means less what white noise of its variance leaves there
        (>= 0): what the design's responses could not explain in the run itself."""
        r = self.own.y - self.predict(self.own)
        means, w = window_means(r, self.own.step_s)
        if means.size < 2:
            return 0.0
        return max(0.0, float(np.mean(means**2)) - float(np.var(r)) / w)

    def law(self) -> np.ndarray:
        """The design's structure fitted to the posterior mean response on the fleet's
        reference program and the unit's own runs: theta = [log taus, coefficients]."""
        p = self.prior
        # the fleet's program joins the unit's runs when both are at the same model step
        same = p.reference is not None and abs(p.reference.step_s - self.own.step_s) < 1e-9
        runs = (list(p.reference.t_rel) if same and p.reference is not None else []) \
            + list(self.own.t_rel)
        ref = all_steps(StepSeries(runs, np.zeros(0), np.zeros(0, dtype=np.int64),
                                   self.own.step_s))
        ref.y = self.predict(ref)
        return fit_unit(ref, p.k, np.exp(p.mu[:p.k]), p.play).theta


def response_basis(prior: DesignPrior, series: StepSeries, lam_units: float = LAM_UNITS,
                   lam_params: float = LAM_PARAMS) -> tuple[np.ndarray, np.ndarray]:
    """(m, B) on `series`' rows: the units' mean response and the basis [sqrt(lam_units) D,
    sqrt(lam_params) J R] (R R^T = Sigma)."""
    k = prior.k
    assert prior.unit_thetas is not None  # function_fit refuses a prior without them
    f = np.stack([predict(series, th, k, prior.play) for th in prior.unit_thetas], axis=1)
    m = f.mean(axis=1)
    n = f.shape[1]
    d = (f - m[:, None]) / np.sqrt(max(n - 1, 1))
    j = jacobian(series, prior.mu, k, play=prior.play) @ _root(prior.sigma)
    return m, np.hstack([np.sqrt(lam_units) * d, np.sqrt(lam_params) * j])


def function_fit(series: StepSeries, prior: DesignPrior, s2: float,
                 lam: tuple[float, float] = (LAM_UNITS, LAM_PARAMS),
                 noise_scale: float = NOISE_SCALE) -> FunctionFit:
    """The new unit's posterior under the prior from its runs `series` (s2: the unit's own
    noise variance estimate, taken `noise_scale` times larger; `lam`: the weights on the
    fleet's responses and on the parametric spread)."""
    if prior.unit_thetas is None or len(prior.unit_thetas) == 0:
        raise ValueError("the design's prior holds no units' fits")
    s2 = s2 * noise_scale
    m, b = response_basis(prior, series, *lam)
    prec = b.T @ b / s2 + np.eye(b.shape[1])
    cov = np.linalg.inv(prec)
    a = cov @ (b.T @ (series.y - m) / s2)
    return FunctionFit(prior, a, 0.5 * (cov + cov.T), s2, series, lam, (m, b))
