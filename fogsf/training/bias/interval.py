"""How sure the bias model is on another log: the bias's rate-transfer interval.

In the form of the SF's (`interval.rate_transfer.rate_transfer`), from the training targets and
the target log's board temperature alone (its gyro output is not used):

1. every bias structure (`bias.structure.CANDIDATES`) fitted to every training target;
   those whose held-out score (the structure choice's: RMS over held-out blocks) is within
   CONSISTENT_TOLERANCE of the best, and the chosen one, are "consistent with the training
   data" (an in-sample sum of squares lets the most flexible structure, the bank, stand for
   the data: it fits the training targets best and extrapolates worst);
2. their predictions on the target log's bias windows, against the chosen model's: the
   largest windowed RMS difference is the structural spread; when the chosen structure is
   `lead`, also `lead` at every grid point of its time constants that the training
   targets cannot tell from the best (`bias.structure.lead_set`): the rate term's spread
   where the training ramps leave the coil's time constants open;
3. the chosen structure's own parameter uncertainty there: the RMS over the windows of the
   standard deviation of its window mean (least-squares covariance, the noise variance of
   its own residual, widened by the residual's long-run variance ratio);
4. the interval for the RMS of measured - predicted over the target's bias windows: from
   INTERVAL_LO times the lower of two noise figures (the target's window noise floor, the
   fit's windowed residual on the training log) to BIAS_NOISE_K times the higher one and
   BIAS_INTERVAL_K times the spread and the parameter term (in quadrature) added in
   quadrature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.bias import bias_windows
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.read.columns import Column, span_means
from fogsf.models.reference import expand
from fogsf.training.bias.structure import CandidateFit, Columns, fit_candidate, lead_set
from fogsf.training.interval.transfer import INTERVAL_LO, long_run_ratio
from fogsf.training.results import RampRateCheck

# The multiples of the noise figure and of the model's spread and parameter uncertainty in
# the interval's top: the pairs' floor from second differences reads low, and the model's
# own error adds to the noise (docs/decisions.md, "The bias interval")
BIAS_NOISE_K = 1.2
BIAS_INTERVAL_K = 1.5
# A structure whose held-out score is within this fraction of the best is consistent with
# the training data (about two standard errors of an RMS over ~100 held-out windows).
CONSISTENT_TOLERANCE = 0.2
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
    lead_set: list[CandidateFit]  # lead at the time constants the targets cannot tell apart


def family(cols: Columns, y: np.ndarray, scores: dict[str, float], chosen: str,
           group: np.ndarray, columns_of: Callable[[ChamberLog], Columns],
           decimation_of: Callable[[ChamberLog], int]) -> Family:
    """`scores`: each candidate's held-out RMS (`training.bias.choice.choose`), in its order."""
    rows = np.arange(y.size)
    fits = {c: fit_candidate(c, cols, rows, y) for c in scores}
    best = min(scores.values())
    ok = [c for c, s in scores.items()
          if c == chosen or s <= (1.0 + CONSISTENT_TOLERANCE) * best]
    r = y - fits[chosen].predict(cols)
    x = np.column_stack([np.ones(y.size), fits[chosen].columns(cols)])
    per = max(1, int(round(y.size / max(1, np.unique(group).size))))
    inflation = long_run_ratio(r, [y.size], max(LONG_RUN_WINDOWS, per))
    noise = float(np.sum(r * r)) / max(1, y.size - x.shape[1])
    gram_inv = np.linalg.pinv(x.T @ x, rcond=1e-12)
    g = np.unique(group, return_inverse=True)[1]
    window_noise = float(np.sqrt(np.mean((np.bincount(g, r) / np.bincount(g)) ** 2)))
    sigma2 = noise * inflation
    near = lead_set(cols, y, sigma2) if chosen == "lead" else []
    return Family(fits, ok, chosen, sigma2, window_noise, inflation, gram_inv, columns_of,
                  decimation_of, near)


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
    ref = span_means(np.asarray(model_pred_dph, dtype=np.float64), w.start, w.stop)

    def rms_from_model(fit: CandidateFit) -> float:
        pred = span_means(expand(fit.predict(cols), n, dec), w.start, w.stop)
        return float(np.sqrt(np.mean((pred - ref) ** 2)))

    spread = {c: rms_from_model(fam.fits[c]) for c in fam.consistent}
    lead_spread = max((rms_from_model(f) for f in fam.lead_set), default=0.0)
    x = fam.fits[fam.chosen].columns(cols)
    xw = span_means(expand(np.column_stack([np.ones(x.shape[0]), x]), n, dec), w.start,
                       w.stop)
    var = np.einsum("wi,ij,wj->w", xw, fam.gram_inv, xw) * fam.sigma2
    param = float(np.sqrt(np.mean(np.maximum(var, 0.0))))
    floor = float(w.noise_floor_dph) if np.isfinite(w.noise_floor_dph) else 0.0
    # the training windows' residual bounds the noise too (a pair's floor, from second
    # differences, assumes white noise on the plateaus)
    lo_floor, hi_floor = sorted((floor, fam.window_noise_dph))
    widest = max(max(spread.values(), default=0.0), lead_spread)
    top = BIAS_INTERVAL_K * float(np.hypot(widest, param))
    taus = [f.taus_s[1] for f in fam.lead_set]
    region = ({"points": len(fam.lead_set), "tau_s": [min(taus), max(taus)],
               "spread_dph": lead_spread} if fam.lead_set else None)
    return asdict(BiasInterval(fam.consistent, len(fam.fits), spread, region, param, floor,
                               fam.window_noise_dph, fam.inflation,
                               (INTERVAL_LO * lo_floor,
                                float(np.hypot(BIAS_NOISE_K * hi_floor, top)))))


@dataclass
class BiasInterval:
    consistent: list[str]  # structures consistent with the training targets
    candidates: int
    spread_dph: dict[str, float]  # each consistent structure's windowed RMS from the model
    # lead's time constants the training targets cannot tell apart: how many refitted, their
    # range (s) and their largest windowed RMS from the model (None unless lead is chosen)
    lead_region: dict[str, Any] | None
    parameter_dph: float  # the chosen structure's parameter uncertainty (RMS over windows)
    noise_floor_dph: float  # the target's bias windows'
    train_window_noise_dph: float  # the fit's residual over its training windows (RMS)
    residual_long_run_ratio: float
    rms_interval_dph: tuple[float, float]


def _lead_clause(lead: dict | None) -> str:
    if not lead:
        return ""
    lo, hi = lead["tau_s"]
    return (f", lead at the coil time constants the training targets allow ({lo:.0f}-{hi:.0f} "
            f"s) by up to {lead['spread_dph']:.3f}")


def interval_message(d: dict, rr: RampRateCheck | None = None) -> str:
    """`fogsf train`'s lines on the interval `d` (`bias_interval`'s) and the ramp check."""
    lo, hi = d["rms_interval_dph"]
    spread = max(d["spread_dph"].values(), default=0.0)
    text = (f"bias rate transfer: {len(d['consistent'])} of {d['candidates']} bias structures "
            "predict held-out blocks of the training targets about as well as the best "
            f"({', '.join(d['consistent'])}); on "
            f"the target they differ from the model by up to {spread:.3f} deg/h RMS"
            f"{_lead_clause(d.get('lead_region'))}, the model's "
            f"parameters are uncertain by {d['parameter_dph']:.3f}. Expected RMS bias error "
            f"on the target: {lo:.3f}-{hi:.3f} deg/h (noise floor {d['noise_floor_dph']:.3f})")
    if rr is not None and rr.rate_term_extrapolated:
        than = (f"faster than any training ramp ({rr.train_fastest_c_per_min:.2f})"
                if rr.train_fastest_c_per_min > 0 else "and the training logs hold no ramp")
        text += (f". The test ramps at {rr.test_fastest_c_per_min:.2f} C/min, {than}: the "
                 "bias's rate term (a Shupe term) is extrapolated there; a training ramp as "
                 "fast as the fastest the gyro will see pins it (docs/train.md, \"Bias\")")
    return text
