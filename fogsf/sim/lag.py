"""The first-order lag, exact for a piecewise-linear input: the simulator's thermal nodes, its
effects and diagnose's design columns all use this one."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from fogsf.logs.read.columns import Column

STREAM_BLOCK = 1 << 20  # a bounded lag_blocks: samples made at a time (arrays of 8 MB)


def first_order_lag(u: np.ndarray, tau_s: float, dt_s: float, y0: float) -> np.ndarray:
    """Response of tau*dy/dt = u - y to u sampled every dt_s (linear in between), y(0)=y0.

    Exact for piecewise-linear u: y[k+1] = a*y[k] + b0*u[k] + b1*u[k+1], a = exp(-dt/tau).
    The recursion is evaluated in closed form over chunks short enough that a**-m stays
    far from overflow, so it is vectorised and has the rounding error of a few ulps of |u|.
    """
    u = np.asarray(u, dtype=np.float64)
    n = u.shape[0]
    y = np.empty(n, dtype=np.float64)
    for a, block in lag_blocks(u, tau_s, dt_s, y0):
        y[a:a + block.shape[0]] = block
    return y


def lag_blocks(u: Column, tau_s: float, dt_s: float, y0: float,
               max_block: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """`first_order_lag(u, ...)` a block at a time: (start, y[start:start + len]) in order.
    u is anything sliced as u[a:b] (an array, or a column on disk read a block at a time).
    With max_block None the blocks are first_order_lag's own chunks (the same bits); a
    max_block bounds the memory (a few arrays of that many samples) and moves the chunk
    boundaries, so the result may differ from first_order_lag in the last bits."""
    n = len(u)
    if n == 0:
        return
    if tau_s <= 0:
        size = max_block or n
        for a in range(0, n, size):
            yield a, np.array(u[a:a + size], dtype=np.float64)
        return
    r = dt_s / tau_s
    a_ = math.exp(-r)
    g = -math.expm1(-r) / r  # (1 - a) / r
    b1 = 1.0 - g
    b0 = g - a_
    yield 0, np.array([y0], dtype=np.float64)
    m = max(1, min(n - 1, int(30.0 / r)))  # a**-m <= e**30
    if max_block is not None:
        m = max(1, min(m, max_block))
    steps = np.arange(1, m + 1, dtype=np.float64)
    up = np.exp(steps * r)  # a**-(i+1)
    down = np.exp(-steps * r)  # a**j
    s = 0
    state = float(y0)
    while s < n - 1:
        k = min(m, n - 1 - s)
        uu = np.asarray(u[s:s + k + 1], dtype=np.float64)
        x = b0 * uu[:-1] + b1 * uu[1:]  # y[j+1] = a*y[j] + x[j]
        c = np.cumsum(x * up[:k])
        y = down[:k] * (state + c)
        state = float(y[-1])
        yield s + 1, y
        s += k
