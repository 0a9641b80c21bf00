"""How sure the bias model is on another log: the bias's rate-transfer interval.

In the form of the SF's (`transfer_interval.rate_transfer`), from the training targets and
the target log's board temperature alone (its gyro output is not used):

1. every bias structure (`bias_structure.CANDIDATES`) fitted to every training target;
   those whose sum of squares is within a chi-square allowance of the best (the noise
   variance from the best fit, widened by its residual's long-run variance ratio) are
   "consistent with the training data";
2. their predictions on the target log's bias windows, against the chosen model's: the
   largest windowed RMS difference is the structural spread;
3. the chosen structure's own parameter uncertainty there: the RMS over the windows of the
   standard deviation of its window mean (least-squares covariance, the same noise variance);
4. the interval for the RMS of measured - predicted over the target's bias windows: from
   INTERVAL_LO times the lower of two noise figures (the target's window noise floor, the
   fit's windowed residual on the training log) to the higher one and BIAS_INTERVAL_K times
   the spread and the parameter term (in quadrature) added in quadrature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from fogsf.trainer.logs.bias import bias_windows
from fogsf.trainer.logs.chamber_log import ChamberLog
from fogsf.trainer.logs.columns import Column
from fogsf.trainer.logs.plateaus import SETTLE_S
from fogsf.trainer.models.reference import expand
from fogsf.trainer.training.bias_structure import CandidateFit, Columns, fit_candidate
from fogsf.trainer.training.transfer import CHI2_ALLOWANCE, INTERVAL_LO, long_run_ratio

# The multiple of the model's spread and parameter uncertainty in the interval's top:
# the 90th percentile of what each case needed on development gyros 1-16, four protocols
# (64 cases; docs/decisions.md).
BIAS_INTERVAL_K = 1.9
LONG_RUN_WINDOWS = 5  # targets per long-run window (pairs; stationary logs: 100 s of steps)


@dataclass
class Family:
    """The candidates fitted to every training target, the consistent ones, and what the
    interval needs on another log."""

    fits: dict[str, CandidateFit]
    consistent: list[str]
    chosen: str
    sigma2: float  # one target's noise variance (deg/h^2), long-run inflated
    window_noise_dph: float  # the chosen fit's residual, RMS over its training windows
    inflation: float
    gram_inv: np.ndarray  # (X^T X)^-1 of the chosen design with its intercept column
    columns_of: Callable[[ChamberLog], Columns]  # a log's columns at every model step
    decimation_of: Callable[[ChamberLog], int]


def family(cols: Columns, y: np.ndarray, order: list[str] | tuple[str, ...], chosen: str,
           group: np.ndarray, columns_of: Callable[[ChamberLog], Columns],
           decimation_of: Callable[[ChamberLog], int]) -> Family:
    rows = np.arange(y.size)
    fits = {c: fit_candidate(c, cols, rows, y) for c in order}
    sse = {c: float(np.sum((y - f.predict(cols)) ** 2)) for c, f in fits.items()}
    best = min(sse, key=lambda c: sse[c])
    p_best = fits[best].columns(cols).shape[1] + 1
    resid = y - fits[best].predict(cols)
    per = max(1, int(round(y.size / max(1, np.unique(group).size))))
    inflation = long_run_ratio(resid, [y.size], max(LONG_RUN_WINDOWS, per))
    noise = sse[best] / max(1, y.size - p_best)
    ok = [c for c in order if sse[c] <= sse[best] + CHI2_ALLOWANCE * noise * inflation]
    x = np.column_stack([np.ones(y.size), fits[chosen].columns(cols)])
    gram_inv = np.linalg.pinv(x.T @ x, rcond=1e-12)
    g = np.unique(group, return_inverse=True)[1]
    r = y - fits[chosen].predict(cols)
    window_noise = float(np.sqrt(np.mean((np.bincount(g, r) / np.bincount(g)) ** 2)))
    return Family(fits, ok, chosen, noise * inflation, window_noise, inflation, gram_inv,
                  columns_of, decimation_of)


def _window_means(per_sample: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    c = np.concatenate([np.zeros((1,) + per_sample.shape[1:]), np.cumsum(per_sample, axis=0)])
    n = (stop - start).reshape((-1,) + (1,) * (per_sample.ndim - 1))
    return (c[stop] - c[start]) / n


def bias_interval(fam: Family, log: ChamberLog, model_pred_dph: np.ndarray,
                  window_s: float = 100.0, latitude_deg: float | None = None,
                  settle_s: float = SETTLE_S, sf_ppm: Column | None = None
                  ) -> dict | None:
    """The interval on `log` for the model whose per-sample prediction is `model_pred_dph`
    (`sf_ppm`: the SF model's, taken off the pairs' plateaus); None for a log that measures
    no bias."""
    w = bias_windows(log, window_s, latitude_deg, settle_s, sf_ppm=sf_ppm)
    if w is None:
        return None
    cols = fam.columns_of(log)
    dec = fam.decimation_of(log)
    n = len(log)
    ref = _window_means(np.asarray(model_pred_dph, dtype=np.float64), w.start, w.stop)
    spread = {c: float(np.sqrt(np.mean((_window_means(expand(fam.fits[c].predict(cols), n,
                                                                   dec), w.start, w.stop)
                                          - ref) ** 2))) for c in fam.consistent}
    x = fam.fits[fam.chosen].columns(cols)
    xw = _window_means(expand(np.column_stack([np.ones(x.shape[0]), x]), n, dec), w.start,
                       w.stop)
    var = np.einsum("wi,ij,wj->w", xw, fam.gram_inv, xw) * fam.sigma2
    param = float(np.sqrt(np.mean(np.maximum(var, 0.0))))
    floor = float(w.noise_floor_dph) if np.isfinite(w.noise_floor_dph) else 0.0
    # the training windows' residual bounds the noise too (a pair's floor, from second
    # differences, assumes white noise on the plateaus)
    lo_floor, hi_floor = sorted((floor, fam.window_noise_dph))
    top = BIAS_INTERVAL_K * float(np.hypot(max(spread.values(), default=0.0), param))
    return asdict(BiasInterval(fam.consistent, len(fam.fits), spread, param, floor,
                               fam.window_noise_dph, fam.inflation,
                               (INTERVAL_LO * lo_floor, float(np.hypot(hi_floor, top)))))


@dataclass
class BiasInterval:
    consistent: list[str]  # structures consistent with the training targets
    candidates: int
    spread_dph: dict[str, float]  # each consistent structure's windowed RMS from the model
    parameter_dph: float  # the chosen structure's parameter uncertainty (RMS over windows)
    noise_floor_dph: float  # the target's bias windows'
    train_window_noise_dph: float  # the fit's residual over its training windows (RMS)
    residual_long_run_ratio: float
    rms_interval_dph: tuple[float, float]


def interval_message(d: dict) -> str:
    lo, hi = d["rms_interval_dph"]
    spread = max(d["spread_dph"].values(), default=0.0)
    text = (f"bias rate transfer: {len(d['consistent'])} of {d['candidates']} bias structures "
            f"fit the training targets as well as the best ({', '.join(d['consistent'])}); on "
            f"the target they differ from the model by up to {spread:.3f} deg/h RMS, its "
            f"parameters are uncertain by {d['parameter_dph']:.3f}. Expected RMS bias error "
            f"on the target: {lo:.3f}-{hi:.3f} deg/h (noise floor {d['noise_floor_dph']:.3f})")
    rr = d.get("ramp_rates") or {}
    if rr.get("rate_term_extrapolated"):
        than = (f"faster than any training ramp ({rr['train_fastest_c_per_min']:.2f})"
                if rr["train_fastest_c_per_min"] > 0 else "and the training logs hold no ramp")
        text += (f". The test ramps at {rr['test_fastest_c_per_min']:.2f} C/min, {than}: the "
                 "bias's rate term (a Shupe term) is extrapolated there; a training ramp as "
                 "fast as the fastest the gyro will see pins it (docs/train.md, \"Bias\")")
    return text
