"""The rate-transfer check of `fogsf train --test`, and its interval for the error left.

`transfer` says what the training logs hold (ramp rates, segments) and how far the lag
models consistent with them spread on the target log. This module adds the structure
candidates of `training.structure.choice` (physics nodes with 1-3 nodes, the lag bank),
each fitted by least squares to the same training logs and run on the target's board
temperatures: the windowed RMS distance from the judged model to the farthest of them is
how much equally reasonable structures disagree where the judged model is used.

The interval for the RMS error (SF windows) the judged model leaves on the target runs from
INTERVAL_LO times the noise floor to hypot(floor, K x D), D and K by what the training logs
hold, both calibrated on development gyros for 90 % coverage (docs/decisions.md):
- several ramps (rates or directions): D the farthest structure candidate, K_SEVERAL;
- one ramp: D the farthest lag model consistent with the training logs
  (`transfer.target_spreads`), K_ONE_SEGMENT. On one ramp every structure is fitted to the
  same temperature history, so they agree more than their errors at another rate do; the
  lag family spans the rate dependences one ramp leaves open.
The predictors compared: benchmarks/probes/README.md, "Rate-transfer interval".
"""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import noise_floor_ppm
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.measure.windows import sf_windows
from fogsf.training.interval.transfer import (
    INTERVAL_LO,
    RATE_TOLERANCE,
    STEP_S,
    RateTransfer,
    TargetSpreads,
    ramp_rates,
    target_spreads,
    training_ramp_rates,
)
from fogsf.training.structure.choice import CANDIDATES
from fogsf.training.structure.heldout import candidate_compensations

# the 90th percentile of the multiple of D each case needs to fall inside, development gyros
# (`python -m benchmarks.probes.interval_predictors`, docs/decisions.md)
K_ONE_SEGMENT = 0.45  # D: the farthest consistent lag model; 148 cases (protocol a)
K_SEVERAL = 1.45  # D: the farthest structure candidate; 192 cases (protocols b-e)


def structure_spread(train_logs: list[ChamberLog], target: ChamberLog, ts: TargetSpreads,
                     step_s: float = STEP_S, latitude_deg: float | None = None
                     ) -> tuple[dict[str, float], bool]:
    """Per structure candidate, the windowed RMS distance (ppm) on `target` from the judged
    model (`ts.judged`) to the candidate fitted to `train_logs`; and whether those logs hold
    one ramp."""
    sd, comp = candidate_compensations(CANDIDATES, train_logs, step_s, latitude_deg)
    return {n: float(ts.distance(f(target))) for n, f in comp.items()}, sd.one_segment


def rms_interval(floor_ppm: float, lag_spread_ppm: float, structure_spread_ppm: float,
                 one_segment: bool) -> tuple[float, float]:
    """From INTERVAL_LO x the floor (noise alone scatters that far below it) to the floor and
    K x D in quadrature: D the farthest consistent lag model with one ramp, the farthest
    structure candidate with several (module docstring)."""
    top = (K_ONE_SEGMENT * lag_spread_ppm if one_segment
           else K_SEVERAL * structure_spread_ppm)
    return (INTERVAL_LO * floor_ppm, float(np.hypot(floor_ppm, top)))


def rate_transfer(train_logs: list[ChamberLog], target: ChamberLog,
                  latitude_deg: float | None = None,
                  prediction_ppm: np.ndarray | None = None, step_s: float = STEP_S,
                  window_s: float = 100.0, settle_s: float = SETTLE_S) -> RateTransfer:
    """How well the training logs determine the compensation on `target`; `prediction_ppm`
    (per sample of the target) is the trained model's prediction there, the model the
    interval is for (without it, the best-fitting lag model's: `transfer.target_spreads`).
    Spreads and the noise floor are over the target's SF windows (`window_s`, `settle_s`)."""
    ts = target_spreads(train_logs, target, latitude_deg, prediction_ppm, step_s, window_s,
                        settle_s)
    spreads, one = structure_spread(train_logs, target, ts, step_s, latitude_deg)
    train_rates = training_ramp_rates(train_logs)
    target_rates = ramp_rates(target) or [0.0]
    lo, hi = (min(train_rates), max(train_rates)) if train_rates else (0.0, 0.0)
    outside = [r for r in target_rates
               if not lo * (1 - RATE_TOLERANCE) <= r <= hi * (1 + RATE_TOLERANCE)]
    target_rate = outside[0] if outside else max(target_rates)
    floor = noise_floor_ppm(sf_windows(target, window_s, latitude_deg, settle_s=settle_s))
    m_max = float(np.max(ts.model_spread))
    interval = rms_interval(floor, m_max, max(spreads.values()), one)
    return RateTransfer(train_rates, target_rate, not outside, ts.candidates,
                        int(ts.spread.size), float(np.median(ts.spread)),
                        float(np.max(ts.spread)), ts.inflation, floor, m_max, ts.excursion_c,
                        interval, spreads, one)
