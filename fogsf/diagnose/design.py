"""Model columns per window: the base physics model and the features residuals are read
against.

Base model of the apparent SF error (ppm vs nominal), per window:

    y = c0 + a_b*B + q_b*B^2 + a_1*N1 + q_1*N1^2 + a_2*N2 + q_2*N2^2      (thermal SF)
        [+ s_1*exp(-t/tau1) + s_2*exp(-t/tau2)]   (unseen self-heating after power-on)
        [+ b0 * 1e6 / (3600 * rate)]             (constant bias in deg/h, when rates differ)

B: board thermometer; N1, N2: internal nodes, first-order lags (tau1 < tau2) of the driver
(the housing, see `driver`); temperatures as offsets from 20 C. Each node's SF law is a
quadratic, as each factor of K = 2*pi*L*D/(Km*K_DA*lambda*c) is in the simulator. A
constant bias is separable from the SF only when the table rate takes more than one value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.diagnose.driver import Driver
from fogsf.diagnose.runs import Run, per_sample

T_REF_C = 20.0
BASE_TAU_GRID_S = tuple(float(x) for x in np.round(np.geomspace(600.0, 4000.0, 7), -1))
MIN_TAU_RATIO = 1.4  # tau2 >= MIN_TAU_RATIO * tau1
PPM_PER_DPH = 1e6 / 3600.0  # bias of 1 deg/h at 1 deg/s, in ppm of the rate


@dataclass
class RunContext:
    """Per-run facts the columns need."""

    run: Run
    driver: Driver
    power_on: bool
    bias_on: bool  # the set of logs has more than one table rate


def _cached(ctx: RunContext, key: tuple, make) -> np.ndarray:
    c = ctx.run.cache
    if key not in c:
        c[key] = make()
    return c[key]


def node(ctx: RunContext, tau_s: float) -> np.ndarray:
    """Window mean of lag(driver, tau) - 20 C."""
    return _cached(ctx, ("node", float(tau_s)),
                   lambda: ctx.run.lagged_window_mean(ctx.driver.temp_c, tau_s) - T_REF_C)


def drive(ctx: RunContext) -> np.ndarray:
    return _cached(ctx, ("drive",), lambda: ctx.run.window_mean(ctx.driver.temp_c) - T_REF_C)


def board(ctx: RunContext) -> np.ndarray:
    return _cached(ctx, ("board",), lambda: ctx.run.window_mean(ctx.run.log.temp_c) - T_REF_C)


def decay(ctx: RunContext, tau_s: float) -> np.ndarray:
    """Window mean of exp(-t/tau), t since power-on (the log's time_s)."""
    return _cached(ctx, ("decay", float(tau_s)),
                   lambda: ctx.run.window_mean(per_sample(
                       ctx.run.log.time_s, lambda t: np.exp(-t / tau_s))))


def settle(ctx: RunContext, tau_s: float) -> np.ndarray:
    """Window mean of 1 - exp(-t/tau), t since the log's start."""
    def make() -> np.ndarray:
        t0 = float(ctx.run.log.time_s[0])
        return ctx.run.window_mean(per_sample(ctx.run.log.time_s,
                                              lambda t: 1.0 - np.exp(-(t - t0) / tau_s)))
    return _cached(ctx, ("settle", float(tau_s)), make)


def board_rate_c_per_min(ctx: RunContext, smooth_s: float = 60.0) -> np.ndarray:
    """Window mean of the board temperature's rate of change (C/min), smoothed by a lag."""
    tb = ctx.run.log.temp_c

    def rate(a: int, lagged: np.ndarray) -> np.ndarray:
        return (np.asarray(tb[a:a + lagged.shape[0]], dtype=np.float64) - lagged) \
            / smooth_s * 60.0
    return _cached(ctx, ("board_rate", smooth_s),
                   lambda: ctx.run.lagged_window_mean(tb, smooth_s, rate))


def base_grid() -> list[tuple[float, float]]:
    g = BASE_TAU_GRID_S
    return [(a, b) for a in g for b in g if b >= MIN_TAU_RATIO * a]


def base_names(power_on: bool, bias_on: bool) -> list[str]:
    names = ["offset_ppm", "board_ppm_per_c", "board_ppm_per_c2", "node1_ppm_per_c",
             "node1_ppm_per_c2", "node2_ppm_per_c", "node2_ppm_per_c2"]
    if power_on:
        names += ["selfheat1_ppm", "selfheat2_ppm"]
    if bias_on:
        names += ["bias_dph"]
    return names


def base_columns(ctx: RunContext, theta: tuple[float, float], any_power_on: bool
                 ) -> np.ndarray:
    """(windows, p) base columns of one run; the self-heating columns exist when any run
    starts at power-on (zero for the runs that do not)."""
    tau1, tau2 = theta
    b = board(ctx)
    n1 = node(ctx, tau1)
    n2 = node(ctx, tau2)
    cols = [np.ones_like(b), b, b * b, n1, n1 * n1, n2, n2 * n2]
    if any_power_on:
        on = 1.0 if ctx.power_on else 0.0
        cols += [on * decay(ctx, tau1), on * decay(ctx, tau2)]
    if ctx.bias_on:
        cols.append(PPM_PER_DPH / ctx.run.rate)
    return np.column_stack(cols)
