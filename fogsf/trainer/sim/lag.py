"""The first-order lag, exact for a piecewise-linear input: the simulator's thermal nodes, its
effects and diagnose's design columns all use this one."""

from __future__ import annotations

import math

import numpy as np


def first_order_lag(u: np.ndarray, tau_s: float, dt_s: float, y0: float) -> np.ndarray:
    """Response of tau*dy/dt = u - y to u sampled every dt_s (linear in between), y(0)=y0.

    Exact for piecewise-linear u: y[k+1] = a*y[k] + b0*u[k] + b1*u[k+1], a = exp(-dt/tau).
    The recursion is evaluated in closed form over chunks short enough that a**-m stays
    far from overflow, so it is vectorised and has the rounding error of a few ulps of |u|.
    """
    u = np.asarray(u, dtype=np.float64)
    n = u.shape[0]
    y = np.empty(n, dtype=np.float64)
    if n == 0:
        return y
    if tau_s <= 0:
        y[:] = u
        return y
    r = dt_s / tau_s
    a = math.exp(-r)
    g = -math.expm1(-r) / r  # (1 - a) / r
    b1 = 1.0 - g
    b0 = g - a
    x = b0 * u[:-1] + b1 * u[1:]  # y[k+1] = a*y[k] + x[k]
    y[0] = y0
    m = max(1, min(n - 1, int(30.0 / r)))  # a**-m <= e**30
    steps = np.arange(1, m + 1, dtype=np.float64)
    up = np.exp(steps * r)  # a**-(i+1)
    down = np.exp(-steps * r)  # a**j
    s = 0
    state = float(y0)
    while s < n - 1:
        k = min(m, n - 1 - s)
        c = np.cumsum(x[s:s + k] * up[:k])
        y[s + 1:s + 1 + k] = down[:k] * (state + c)
        state = float(y[s + k])
        s += k
    return y
