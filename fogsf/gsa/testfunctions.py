"""Test functions for the optimizers (in the package so that worker processes and Dask
workers can import them).

- Rashedi et al. (2009) Table 1 unimodal functions F1..F7, vectorised over agents: each takes
  an (N, n) array of positions and returns (N,) values; F7 adds uniform [0, 1) noise drawn
  from a caller-given generator, so runs stay reproducible.
- `shifted_sphere`: a dict-in, float-out fitness over named parameters, the form
  `fogsf.gsa.optimizer.minimize` calls by default; used to test executors and mixed spaces.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def f1_sphere(x: np.ndarray) -> np.ndarray:
    return np.sum(x * x, axis=1)


def f2_schwefel_2_22(x: np.ndarray) -> np.ndarray:
    a = np.abs(x)
    return np.sum(a, axis=1) + np.prod(a, axis=1)


def f3_schwefel_1_2(x: np.ndarray) -> np.ndarray:
    return np.sum(np.cumsum(x, axis=1) ** 2, axis=1)


def f4_schwefel_2_21(x: np.ndarray) -> np.ndarray:
    return np.max(np.abs(x), axis=1)


def f5_rosenbrock(x: np.ndarray) -> np.ndarray:
    return np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (x[:, :-1] - 1.0) ** 2, axis=1)


def f6_step(x: np.ndarray) -> np.ndarray:
    return np.sum(np.floor(x + 0.5) ** 2, axis=1)


def f7_quartic_noise(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    i = np.arange(1, x.shape[1] + 1)
    return np.sum(i * x ** 4, axis=1) + rng.random(x.shape[0])


@dataclass(frozen=True)
class TestFunction:
    key: str
    name: str
    fn: Callable
    low: float
    high: float
    paper_mean: float          # Rashedi 2009 Table 4, GSA, mean best-so-far
    noisy: bool = False


FUNCTIONS: dict[str, TestFunction] = {f.key: f for f in (
    TestFunction("F1", "sphere", f1_sphere, -100.0, 100.0, 7.3e-11),
    TestFunction("F2", "Schwefel 2.22", f2_schwefel_2_22, -10.0, 10.0, 4.03e-5),
    TestFunction("F3", "Schwefel 1.2", f3_schwefel_1_2, -100.0, 100.0, 0.16e3),
    TestFunction("F4", "Schwefel 2.21", f4_schwefel_2_21, -100.0, 100.0, 3.7e-6),
    TestFunction("F5", "Rosenbrock", f5_rosenbrock, -30.0, 30.0, 25.16),
    TestFunction("F6", "step", f6_step, -100.0, 100.0, 8.3e-11),
    TestFunction("F7", "quartic with noise", f7_quartic_noise, -1.28, 1.28, 0.018, noisy=True),
)}


def shifted_sphere(params: dict[str, float], target: dict[str, float] | None = None) -> float:
    """sum over names of (value - target)^2 (target 0 where not given); minimum 0."""
    target = target or {}
    return float(sum((float(v) - target.get(k, 0.0)) ** 2 for k, v in params.items()))
