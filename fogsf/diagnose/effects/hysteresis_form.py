"""The `hysteresis` catalogue form: the play (backlash) operator of a coil temperature.

Column (C, per window): the window mean of play(N, w) - N, N a node lagging the driver (the
housing) by tau (a coil: 150-3000 s, as the temp_rate coil), the play primed at N's first
value. Its coefficient is the simulator's `hysteresis` strength in ppm/C; the grid value is
(width_c, tau_s): the width is reported, the coil's time constant profiled out. The play runs
on the node sampled every PLAY_STEP_S (it moves a few hundredths of a C between those
samples), every width of the grid at once.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fogsf.diagnose import design
from fogsf.diagnose.design import RunContext
from fogsf.logs.read.columns import derived
from fogsf.models.structures.hysteresis import plays_batch
from fogsf.sim.lag import STREAM_BLOCK, lag_blocks

WIDTHS_C = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 14.0)
COIL_TAUS_S = (150.0, 300.0, 600.0, 1200.0, 2400.0)
GRID = tuple((w, t) for t in COIL_TAUS_S for w in WIDTHS_C)
PLAY_STEP_S = 5.0
# a minor loop: the driver turns back (by more than TURN_C) at a temperature more than
# INNER_C inside the run's range; without one a play is a direction-dependent offset, the
# same function as the base's misfit on a full cycle or an up-and-back log
TURN_C = 3.0
INNER_C = 3.0
SEPARATING_RUN = ("a partial cycle: the temperature turning back inside its range, with "
                  "soaks at the turns (e.g. fogsf simulate --scenario partial)")


def _plays(ctx: RunContext, tau_s: float, widths: tuple[float, ...] = WIDTHS_C
           ) -> np.ndarray:
    """(windows, widths) window means of play(node, w) - node for every width."""
    def make() -> np.ndarray:
        d = ctx.driver.temp_c
        k = max(1, int(round(PLAY_STEP_S / ctx.run.dt_s)))
        # the node every k-th sample, made a block at a time
        coarse = np.concatenate([y[(-a) % k::k] for a, y in lag_blocks(
            d, tau_s, ctx.run.dt_s, float(d[0]), STREAM_BLOCK)])
        off = plays_batch(np.repeat(coarse[:, None], len(widths), axis=1),
                          np.asarray(widths))
        def held(j: int) -> Callable[[slice], np.ndarray]:
            return lambda s: off[np.arange(s.start, s.stop) // k, j]

        # each play value held for its k samples, summed over the windows a block at a time
        return np.column_stack([ctx.run.window_mean(derived(len(d), np.dtype(np.float64),
                                                            held(j)))
                                for j in range(len(widths))])
    return design._cached(ctx, ("play", float(tau_s), widths), make)


def has_minor_loop(ctx: RunContext) -> bool:
    """True when the run's driving temperature turns back inside its range (a minor loop)."""
    d = ctx.driver.temp_c
    x = np.asarray(d[::max(1, int(round(PLAY_STEP_S / ctx.run.dt_s)))], dtype=np.float64)
    if x.size < 3:
        return False
    p = plays_batch(x[:, None], np.array([TURN_C]))[:, 0] + x  # the play of x itself
    dp = np.diff(p)
    moving = np.flatnonzero(dp != 0)
    turns = [i for a, i in zip(moving[:-1], moving[1:], strict=True)
             if np.sign(dp[a]) != np.sign(dp[i])]
    lo, hi = float(x.min()), float(x.max())
    return any(lo + INNER_C < p[i] < hi - INNER_C for i in turns)


def column(ctx: RunContext, b: tuple[float, float], g: object) -> np.ndarray:
    assert isinstance(g, tuple)
    width, tau = float(g[0]), float(g[1])
    if width in WIDTHS_C:
        return _plays(ctx, tau)[:, WIDTHS_C.index(width)]
    return _plays(ctx, tau, (width,))[:, 0]  # a refined width
