"""The physics fit: nonlinear in a few time constants, linear in the coefficients.

A gyro's internal temperatures are first-order lags of what drives them, and its SF error
a polynomial of some of them: the model is linear in its coefficients once the time
constants are fixed. Both `diagnose` (its base model and catalogue columns, profiled over
grids of time constants) and the trainer's physics-node model (`models.structures.physics_nodes`)
identify their nodes through this module:

- `profile_solve`: weighted ridge least squares of many design matrices stacked (G, n, p),
  one per grid combination of time constants, solved at once; the combination with the
  least weighted squared error wins (the profile likelihood over the grid).
- `ridge_fit`: one design, the intercept unpenalised, the penalty a multiple of the
  centred design's mean diagonal (so it does not depend on the logs' length).
- `varpro`: variable projection: Levenberg-Marquardt on the log time constants of the
  residual left by `ridge_fit` (the coefficients projected out), from a grid start.
- `discrete_lag`: the firmware's lag filter at the model rate, in float64.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

PROFILE_RIDGE = 1e-5  # diagnose: a whisker of ridge on scaled columns for collinear nodes
PROFILE_CHUNK = 1 << 21  # numbers of the design profile_solve works on at a time (16 MB)


# --- the profile over a grid (diagnose's base model and catalogue) ---------------------------

@dataclass
class ProfileFit:
    index: int  # best combination
    beta: np.ndarray  # (p,) coefficients of the best combination
    sse: np.ndarray  # (G,) weighted SSE of every combination on the fitting rows
    cov: np.ndarray  # (p, p) coefficient covariance (unit weights = 1/sigma^2)


def profile_solve(x: np.ndarray, y: np.ndarray, w: np.ndarray, rows: np.ndarray,
                  ridge: float = PROFILE_RIDGE) -> ProfileFit:
    """Every stacked design x (G, n, p) fitted on `rows` with weights w (1/sigma^2): batched
    normal equations on scaled columns with `ridge` times the row count on the diagonal,
    a few combinations at a time (PROFILE_CHUNK numbers: long logs have many rows)."""
    sw = np.sqrt(w[rows])
    yw = y[rows] * sw
    g_all, p = x.shape[0], x.shape[2]
    per = max(1, PROFILE_CHUNK // max(1, rows.shape[0] * p))
    sse = np.empty(g_all)
    bs_all, scale_all, a_all = np.empty((g_all, p)), np.empty((g_all, p)), np.empty((g_all, p, p))
    for g0 in range(0, g_all, per):
        g1 = min(g_all, g0 + per)
        xw = x[g0:g1][:, rows, :] * sw[None, :, None]
        scale = np.sqrt(np.mean(xw * xw, axis=1))  # (G, p)
        scale = np.where(scale > 0, scale, 1.0)  # an all-zero column (e.g. warmup, no power-on)
        xs = xw / scale[:, None, :]
        del xw
        a = np.einsum("gnp,gnq->gpq", xs, xs)
        a = a + ridge * rows.shape[0] * np.eye(p)[None]
        rhs = np.einsum("gnp,n->gp", xs, yw)
        bs = np.linalg.solve(a, rhs[..., None])[..., 0]
        resid = yw[None, :] - np.einsum("gnp,gp->gn", xs, bs)
        sse[g0:g1] = np.sum(resid * resid, axis=1)
        bs_all[g0:g1], scale_all[g0:g1], a_all[g0:g1] = bs, scale, a
    k = int(np.argmin(sse))
    beta = bs_all[k] / scale_all[k]
    cov = np.linalg.inv(a_all[k]) / np.outer(scale_all[k], scale_all[k])
    return ProfileFit(k, beta, sse, cov)


# --- one design: ridge with an unpenalised intercept -------------------------------------------

@dataclass
class RidgeFit:
    intercept: float
    coef: np.ndarray
    sse: float  # over the fitted rows
    dof: float  # effective degrees of freedom (intercept included)

    def predict(self, x: np.ndarray) -> np.ndarray:
        return self.intercept + x @ self.coef


def ridge_fit(x: np.ndarray, y: np.ndarray, lam: float) -> RidgeFit:
    """Ridge regression of y on the columns of x with an unpenalised intercept, penalty
    `lam` times the centred design's mean diagonal."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    mu, ym = x.mean(axis=0), float(np.mean(y))
    xc = x - mu
    yc = y - ym
    ev, vec = np.linalg.eigh(xc.T @ xc)  # the normal equations: p x p, fast for long logs
    ev = np.maximum(ev, 0.0)
    pen = lam * float(np.mean(ev))  # the mean diagonal of xc^T xc (its trace / p)
    coef = vec @ ((vec.T @ (xc.T @ yc)) / (ev + pen))
    resid = yc - xc @ coef
    return RidgeFit(ym - float(mu @ coef), coef, float(resid @ resid),
                    float(np.sum(ev / (ev + pen))) + 1.0)


# --- the firmware's lag at the model rate --------------------------------------------------------

def lag_alpha(tau_s: float, step_s: float) -> float:
    """alpha of y += alpha (x - y) for time constant tau at one update per step_s."""
    return -math.expm1(-step_s / tau_s)


def discrete_lag(x: np.ndarray, alpha: float) -> np.ndarray:
    """y primed with x[0], then y += alpha (x - y) per step (the contract's filter, float64):
    evaluated in closed form over chunks short enough that (1 - alpha)^-m stays finite."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    y = np.empty(n)
    if n == 0:
        return y
    b = 1.0 - alpha
    if b <= 0.0:
        y[:] = x
        return y
    lb = -math.log(b)
    m = max(1, min(n, int(30.0 / max(lb, 1e-12))))
    steps = np.arange(1, m + 1, dtype=np.float64)
    up, down = np.exp(steps * lb), np.exp(-steps * lb)
    state = float(x[0])
    y[0] = state
    s = 1
    while s < n:
        k = min(m, n - s)
        c = np.cumsum(alpha * x[s:s + k] * up[:k])
        y[s:s + k] = down[:k] * (state + c)
        state = float(y[s + k - 1])
        s += k
    return y


# --- variable projection --------------------------------------------------------------------

@dataclass
class VarProFit:
    theta: np.ndarray  # the nonlinear parameters (e.g. log time constants)
    fit: RidgeFit  # the coefficients projected out at theta
    iters: int


VARPRO_STEP = 1e-3  # forward-difference step of the Jacobian in theta


def varpro(design: Callable[[np.ndarray], np.ndarray], y: np.ndarray, theta0: np.ndarray,
           lo: np.ndarray, hi: np.ndarray, lam: float, max_iter: int = 30,
           rtol: float = 1e-6) -> VarProFit:
    """Minimise ||y - ridge projection of y on design(theta)||^2 over theta in [lo, hi] by
    Levenberg-Marquardt, the Jacobian of the projected residual by forward differences
    (Kaufman's variable projection with numerical derivatives)."""
    y = np.asarray(y, dtype=np.float64)

    def resid(th: np.ndarray) -> tuple[np.ndarray, RidgeFit]:
        x = design(th)
        f = ridge_fit(x, y, lam)
        return y - f.predict(x), f

    theta = np.clip(np.asarray(theta0, dtype=np.float64), lo, hi)
    r, fit = resid(theta)
    sse = float(r @ r)
    mu = 1e-2
    iters = 0
    while iters < max_iter:
        iters += 1
        jac = np.empty((r.size, theta.size))
        for j in range(theta.size):
            t = theta.copy()
            h = VARPRO_STEP if t[j] + VARPRO_STEP <= hi[j] else -VARPRO_STEP
            t[j] += h
            jac[:, j] = (resid(t)[0] - r) / h
        jtj, jtr = jac.T @ jac, jac.T @ r
        improved = False
        for _ in range(8):
            a = jtj + mu * np.diag(np.diag(jtj) + 1e-12)
            step = -np.linalg.solve(a, jtr)
            cand = np.clip(theta + step, lo, hi)
            r2, f2 = resid(cand)
            s2 = float(r2 @ r2)
            if s2 < sse:
                improved = True
                gain = (sse - s2) / max(sse, 1e-300)
                theta, r, fit, sse = cand, r2, f2, s2
                mu = max(mu / 3.0, 1e-9)
                break
            mu *= 4.0
        if not improved or gain < rtol:
            break
    return VarProFit(theta, fit, iters)
