"""The front end's configuration, shared by the artifact (`models.stream`) and the trainer:
the lag filters' coefficients, the samples per model step, the play (backlash) operators'
widths and source weights as the kernel holds them."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from fogsf.errors import UserError


def play_half_c(widths_c: tuple[float, ...] | list[float]) -> np.ndarray:
    """float32(width / 2) per play: what the header prints and the reference uses."""
    return (np.asarray(widths_c, dtype=np.float64).reshape(-1) * 0.5).astype(np.float32)


def play_source_w(weights: tuple | list, n_filters: int) -> np.ndarray:
    """The plays' source weights as float32 [P, 1+K] (what the header prints)."""
    return np.asarray(weights, dtype=np.float64).reshape(-1, 1 + n_filters).astype(np.float32)


def filter_alpha(filter_tau_s: list[float], decimation: int, sample_dt_s: float = 0.1
                 ) -> np.ndarray:
    """alpha_k = 1 - exp(-D*dt/tau_k), computed in float64, stored as float32."""
    return np.array([1.0 - math.exp(-decimation * sample_dt_s / tau) for tau in filter_tau_s],
                    dtype=np.float32)


# A model step may differ from D * dt by this fraction at most (D an integer of samples)
STEP_TOLERANCE = 0.01


def decimation_for(step_s: float, sample_dt_s: float, where: str | None = None) -> int:
    """Samples per model step: step_s / sample_dt_s, which must be (within STEP_TOLERANCE)
    a whole number >= 1; `where` (a log's path) starts the refusal."""
    d = max(1, int(round(step_s / sample_dt_s)))
    if abs(d * sample_dt_s - step_s) > STEP_TOLERANCE * step_s:
        raise UserError(f"{where + ': ' if where else ''}a model step of {step_s:g} s is "
                        f"{step_s / sample_dt_s:.4g} samples at {1.0 / sample_dt_s:.6g} Hz, "
                        "not a whole number: the step must be a multiple of "
                        f"{sample_dt_s:.6g} s at this rate (`fogsf train --model-step-s`)")
    return d


@dataclass(frozen=True)
class FrontEnd:
    """What the front end needs (a subset of the artifact; the trainer can build one alone)."""

    t_ref_c: float
    t_min_c: float
    t_max_c: float
    decimation: int
    stuck_samples: int
    filter_alpha: np.ndarray  # [K] float32
    sample_dt_s: float = 0.1
    filter_tau_s: tuple[float, ...] = ()  # () : unknown (the alphas are then rescaled)
    # play (backlash) operators after the lag filters: width (C) and source weights over
    # [Tm, y_1..y_K] (the play's input x = w . [Tm, y]); rate-independent, so the same at any
    # sample rate
    play_width_c: tuple[float, ...] = ()
    play_source_w: tuple[tuple[float, ...], ...] = ()

    @property
    def n_plays(self) -> int:
        return len(self.play_width_c)

    def play_half_c(self) -> np.ndarray:
        """The plays' half widths as the kernel holds them (float32 of width / 2)."""
        return play_half_c(self.play_width_c)

    @property
    def step_s(self) -> float:
        """The model step in seconds: D samples."""
        return self.decimation * self.sample_dt_s

    def at_rate(self, sample_dt_s: float) -> FrontEnd:
        """The same front end for samples every `sample_dt_s`: the model step (s), the lag
        filters' time constants (s) and the stuck-thermometer time (s) kept, in samples."""
        d = decimation_for(self.step_s, sample_dt_s)
        if d == self.decimation:  # the same samples per step, a step within 1 %: the same
            return self
        return replace(self, decimation=d, sample_dt_s=sample_dt_s,
                       stuck_samples=int(round(self.stuck_samples * self.sample_dt_s
                                               / sample_dt_s)),
                       filter_alpha=self._alpha_at(d, sample_dt_s))

    def _alpha_at(self, decimation: int, sample_dt_s: float) -> np.ndarray:
        """Filter coefficients for D samples of sample_dt_s: the same bits when the step is
        the same (to 1e-9), else `filter_alpha` afresh (rescaled when tau is unknown)."""
        new_step_s = decimation * sample_dt_s
        if abs(new_step_s - self.step_s) <= 1e-9 * self.step_s:
            return np.asarray(self.filter_alpha, dtype=np.float32)
        if len(self.filter_tau_s):
            return filter_alpha(list(self.filter_tau_s), decimation, sample_dt_s)
        keep = 1.0 - np.asarray(self.filter_alpha, dtype=np.float64)
        return (1.0 - keep ** (new_step_s / self.step_s)).astype(np.float32)
