"""Statistics for residuals that are few (tens of windows) and not independent.

- Ljung-Box whiteness test (chi-square tail from the regularised incomplete gamma).
- Paired sign-flip test on per-block sums (exact up to 2^16 sign patterns): does model B
  predict held-out data better than model A, block by block.
- Pearson correlation with a p-value on the effective sample size (lag-1 autocorrelation
  of both series), so slow structure is not mistaken for many independent points.
"""

from __future__ import annotations

import itertools
import math

import numpy as np


def _gammainc_upper(a: float, x: float) -> float:
    """Regularised upper incomplete gamma Q(a, x) (series / continued fraction)."""
    if x <= 0:
        return 1.0
    gln = math.lgamma(a)
    if x < a + 1:
        term = 1.0 / a
        s = term
        ap = a
        for _ in range(1000):
            ap += 1
            term *= x / ap
            s += term
            if abs(term) < abs(s) * 1e-15:
                break
        return max(0.0, 1.0 - s * math.exp(-x + a * math.log(x) - gln))
    b = x + 1 - a
    c = 1e300
    d = 1 / b
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2
        d = an * d + b
        d = 1e-300 if abs(d) < 1e-300 else d
        c = b + an / c
        c = 1e-300 if abs(c) < 1e-300 else c
        d = 1 / d
        delta = d * c
        h *= delta
        if abs(delta - 1) < 1e-15:
            break
    return math.exp(-x + a * math.log(x) - gln) * h


def chi2_sf(x: float, dof: int) -> float:
    return _gammainc_upper(dof / 2.0, x / 2.0)


def trimmed_chi2_1_mean(q: float) -> float:
    """E[X | X below its q-quantile] for X ~ chi-square(1): E[X 1(X<c)] = P(chi2_3 < c)."""
    lo, hi = 0.0, 50.0
    for _ in range(200):  # the q-quantile c of chi2(1), by bisection
        c = 0.5 * (lo + hi)
        lo, hi = (c, hi) if 1.0 - chi2_sf(c, 1) < q else (lo, c)
    c = 0.5 * (lo + hi)
    return (1.0 - chi2_sf(c, 3)) / q


def ljung_box_p(segments: list[np.ndarray], lags: int | None = None) -> float:
    """Whiteness p-value of residual series (one per run, in time order), pooled: the
    Q statistics and their degrees of freedom add over runs."""
    q = 0.0
    dof = 0
    for e in segments:
        e = np.asarray(e, dtype=np.float64) - np.mean(e)
        n = e.shape[0]
        h = lags or max(1, min(10, n // 5))
        denom = float(np.sum(e * e))
        if n < 8 or denom == 0:
            continue
        for k in range(1, h + 1):
            r = float(np.sum(e[k:] * e[:-k])) / denom
            q += n * (n + 2) * r * r / (n - k)
        dof += h
    return chi2_sf(q, dof) if dof else 1.0


SMOOTH_WINDOWS = 5  # the structure's moving mean, in windows


def structure_ms(segments: list[np.ndarray], span: int = SMOOTH_WINDOWS
                 ) -> tuple[float, float]:
    """(mean square of the residual's structure, mean square of the residual), pooled over
    runs. A residual e = s + n, s slow (it keeps its value over `span` windows) and n
    white: its moving mean over `span` windows keeps s and n / span, so the structure's
    mean square is (span * ms(smoothed) - ms(e)) / (span - 1), at least 0; 0 (within
    noise) for a white residual, whatever its variance, so no noise estimate is needed."""
    sm_sum = e_sum = 0.0
    n_sm = n_e = 0
    k = np.ones(span) / span
    for e in segments:
        e = np.asarray(e, dtype=np.float64)
        if e.shape[0] < 2 * span:
            continue
        sm = np.convolve(e, k, mode="valid")
        sm_sum += float(np.sum(sm * sm))
        n_sm += sm.shape[0]
        e_sum += float(np.sum(e * e))
        n_e += e.shape[0]
    if not n_e:
        return 0.0, 0.0
    ms_e = e_sum / n_e
    return max(0.0, (span * sm_sum / n_sm - ms_e) / (span - 1)), ms_e


def structured_share(segments: list[np.ndarray]) -> float:
    """The share of a residual's mean square that is slow structure (structure_ms)."""
    s, total = structure_ms(segments)
    return s / total if total > 0 else 0.0


def smoothed_rms(segments: list[np.ndarray]) -> float:
    """The RMS of a residual's slow structure, in the residual's unit (structure_ms)."""
    return float(np.sqrt(structure_ms(segments)[0]))


SIGN_ROWS_SAMPLES = 1 << 20  # sign draws made at a time (8 MB)


def sign_flip_p(d: np.ndarray, rng_seed: int = 0, draws: int = 20000) -> float:
    """One-sided p-value that the mean of per-block differences d is > 0 by chance."""
    d = np.asarray(d, dtype=np.float64)
    n = d.shape[0]
    obs = float(np.sum(d))
    if n == 0:
        return 1.0
    if n <= 16:
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=n)))
        return int(np.sum(signs @ np.abs(d) >= obs - 1e-12 * (1 + abs(obs)))) / signs.shape[0]
    rng = np.random.default_rng(rng_seed)
    hits = 0
    rows = max(1, SIGN_ROWS_SAMPLES // n)  # draws made a few MB at a time (long logs)
    for a in range(0, draws, rows):
        signs = rng.choice((1.0, -1.0), size=(min(rows, draws - a), n))
        hits += int(np.sum(signs @ np.abs(d) >= obs - 1e-12 * (1 + abs(obs))))
    return (hits + 1) / (draws + 1)  # Monte Carlo: never an impossible p = 0


def lag1(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=np.float64) - np.mean(x)
    d = float(np.sum(x * x))
    return float(np.sum(x[1:] * x[:-1]) / d) if d > 0 and x.shape[0] > 2 else 0.0


def correlation_ratio(e: np.ndarray, x: np.ndarray, bins: int = 8) -> tuple[float, float]:
    """(eta^2, p): share of the residual's variance explained by its mean in quantile bins
    of x (catches structure a straight line misses, e.g. residuals of a model that has x
    as a regressor), p from n_eff * eta^2 ~ chi-square(bins - 1)."""
    e = np.asarray(e, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    if edges.shape[0] < 3 or np.ptp(e) == 0:
        return 0.0, 1.0
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.shape[0] - 2)
    k = int(np.unique(idx).shape[0])
    means = np.bincount(idx, weights=e) / np.maximum(np.bincount(idx), 1)
    dev = e - e.mean()
    eta2 = float(np.sum((means[idx] - e.mean()) ** 2) / np.sum(dev * dev))
    rho = max(-0.9, min(0.95, lag1(e)))
    n_eff = max(float(k + 1), e.shape[0] * (1 - rho) / (1 + rho))
    return eta2, chi2_sf(n_eff * eta2, k - 1) if k > 1 else 1.0


def correlation(e: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """(Pearson r, two-sided p) with n_eff = n (1 - r1 s1) / (1 + r1 s1)."""
    e = np.asarray(e, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if np.ptp(x) == 0 or np.ptp(e) == 0:
        return 0.0, 1.0
    r = float(np.corrcoef(e, x)[0, 1])
    rho = max(-0.9, min(0.95, lag1(e) * lag1(x)))
    n_eff = max(3.0, e.shape[0] * (1 - rho) / (1 + rho))
    z = math.atanh(max(-0.999999, min(0.999999, r))) * math.sqrt(max(n_eff - 3.0, 1.0))
    return r, math.erfc(abs(z) / math.sqrt(2.0))
