"""Linear least-squares models: the industry's polynomials and the lag-temperature profile.

- `poly`: SF error as a polynomial in the board temperature.
- `polyrate`: polynomial in T plus a filtered dT/dt and its products with T (the industry
  standard for hysteresis).
- `profile_lag_taus`: picks the time constants of two first-order lags of the board
  temperature (the physics: each internal node lags the board) by profiling a log-spaced
  grid, with linear least squares inside, scored on the held-out part.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from trainer.features import SeqData, prepare
from trainer.fit import validation_rms
from trainer.stream import FrontEnd, filter_alpha


def poly_design(z: np.ndarray, degree: int, with_rate: bool) -> np.ndarray:
    """Columns T^0..T^degree (z[:, 0] = normalised T); with a rate (z[:, 1]): R, R T, R T^2."""
    t = z[:, 0].astype(np.float64)
    cols = [t**k for k in range(degree + 1)]
    if with_rate:
        r = z[:, 1].astype(np.float64)
        cols += [r, r * t, r * t * t]
    return np.column_stack(cols)


@dataclass
class LinearFit:
    coef: np.ndarray
    degree: int
    with_rate: bool

    def predict(self, z: np.ndarray) -> np.ndarray:
        return poly_design(z, self.degree, self.with_rate) @ self.coef

    @property
    def params(self) -> int:
        return int(self.coef.size)


def fit_linear(data: list[SeqData], z: list[np.ndarray], degree: int,
               with_rate: bool) -> LinearFit:
    x = np.concatenate([poly_design(a[d.train_mask], degree, with_rate)
                        for a, d in zip(z, data, strict=True)])
    y = np.concatenate([d.target_ppm[d.train_mask] for d in data])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return LinearFit(coef, degree, with_rate)


TAU_GRID_S = tuple(float(t) for t in np.geomspace(60.0, 7200.0, 11).round(0))


def _lag_design(s: np.ndarray, i: int, j: int) -> np.ndarray:
    t, a, b = (s[:, k].astype(np.float64) / 50.0 for k in (0, i, j))
    return np.column_stack([np.ones_like(t), t, t * t, a, a * a, b, b * b])


def profile_lag_taus(logs: list, fe: FrontEnd, val_chunk: tuple[float, float],
                     latitude_deg: float | None = None,
                     grid: tuple[float, ...] = TAU_GRID_S) -> tuple[tuple[float, float], float]:
    """(tau_1, tau_2) minimising the held-out windowed RMS of a quadratic least-squares model
    on T and two lag-filtered temperatures; returns the pair and its score (ppm)."""
    full = FrontEnd(fe.t_ref_c, fe.t_min_c, fe.t_max_c, fe.decimation, fe.stuck_samples,
                    filter_alpha(list(grid), fe.decimation))
    data = [prepare(lg, full, val_chunk, latitude_deg) for lg in logs]
    best, best_score = (grid[0], grid[-1]), math.inf
    for i, j in itertools.combinations(range(1, len(grid) + 1), 2):
        x = np.concatenate([_lag_design(d.s[d.train_mask], i, j) for d in data])
        y = np.concatenate([d.target_ppm[d.train_mask] for d in data])
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        preds = [_lag_design(d.s, i, j) @ coef for d in data]
        score = validation_rms(preds, data)
        if score < best_score:
            best, best_score = (grid[i - 1], grid[j - 1]), score
    return best, best_score

