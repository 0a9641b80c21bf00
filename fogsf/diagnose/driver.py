"""The housing temperature that drives the internal thermal nodes.

The simulator's (and a real gyro's) internal nodes lag the housing, which lags the chamber
air; the board thermometer is one more lag behind the housing. With the chamber air logged
(`chamber_c`), the two lags chamber -> housing -> board are identified by profiling their
time constants over a grid with linear least squares inside (board = gain * lag2(chamber) +
offset + self-heating step); the housing is then the chamber air lagged by the faster of
the two (a chain of two first-order lags is symmetric in its time constants, so which is
the housing's is a convention: the faster one, as in a gyro whose housing follows the air
within a few minutes). Without `chamber_c`, the board thermometer itself is the driver.

A power-on start shows as a self-heating rise of the board at constant chamber air, or,
from the board thermometer alone (board_power_on), as a rise at the log's start that
flattens; its amplitude (above POWER_ON_MIN_C) decides whether the internal nodes' own (unseen)
self-heating transients belong in the base model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.logs.measure.exact_stats import median_step
from fogsf.logs.read.columns import Column, Spill, blocks, derived, is_lazy
from fogsf.sim.lag import STREAM_BLOCK, first_order_lag, lag_blocks

TAU_GRID_S = (0.0, 15.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0, 300.0, 360.0, 480.0,
              600.0, 800.0, 1000.0, 1300.0, 1800.0)
DECIMATE_S = 2.0  # the fits take a sample every 2 s, whatever the log's sample rate
POWER_ON_MIN_C = 0.5  # a self-heating rise above this (C) marks a power-on start


def every(time_s: np.ndarray) -> int:
    """The decimation that takes a sample every DECIMATE_S (20 at 10 Hz, 200 at 100 Hz)."""
    if len(time_s) < 2:
        return 1
    return max(1, int(round(DECIMATE_S / median_step(time_s))))


def onset_samples(time_s: Column) -> int:
    """How many samples from the log's start lie within ONSET_FIT_S of it (time increases)."""
    t0 = float(time_s[0])
    n = 0
    for _, x in blocks(time_s):
        inside = int(np.count_nonzero(np.asarray(x, dtype=np.float64) - t0 <= ONSET_FIT_S))
        n += inside
        if inside < x.shape[0]:
            break
    return n


@dataclass
class Driver:
    """The driving (housing) temperature at 10 Hz and how it was found."""

    temp_c: Column  # per sample: the board thermometer's column, or the housing made here
    source: str  # "chamber" or "board"
    tau_housing_s: float
    tau_board_s: float
    self_heat_housing_c: float  # rises after power-on (0 for a warm start)
    self_heat_board_c: float
    board_offset_c: float  # board minus lagged chamber (g * lag2 + c: the c)
    power_on: bool
    rms_c: float  # RMS of the board-thermometer fit


def _lag(u: np.ndarray, tau: float, dt: float) -> np.ndarray:
    return first_order_lag(u, tau, dt, float(u[0]))


MAX_SELF_HEAT_C = 15.0  # the population's boards heat by 2-8 C (+ housing 0.3-2 C)
ONSET_FIT_S = 2400.0  # the first 40 min of the board thermometer
ONSET_TAU_S = (60.0, 120.0, 240.0, 480.0, 900.0)


def board_power_on(time_s: np.ndarray, board_c: np.ndarray) -> float:
    """The self-heating rise (C) of the board at the log's start, from the board thermometer
    alone; 0 when there is none. Over the first ONSET_FIT_S, board = a + b t + q (1 -
    exp(-t/tau)) (tau profiled on ONSET_TAU_S): a power-on shows as q > 0 with the board
    actually rising at the start (b + q/tau > 0; a ramp that begins with the log gives the
    same curvature with the opposite initial slope, or a negative q). Returns the rise the
    fit shows over the first 3 tau."""
    n = onset_samples(time_s)
    t = np.asarray(time_s[:n], dtype=np.float64)
    t = t - float(time_s[0])
    k = every(t)
    if n < 10 * k:
        return 0.0
    tt = t[::k]
    bb = np.asarray(board_c[:n], dtype=np.float64)[::k]
    best: tuple[float, float, np.ndarray] | None = None
    for tau in ONSET_TAU_S:
        xm = np.column_stack([np.ones_like(tt), tt, 1.0 - np.exp(-tt / tau)])
        coef, *_ = np.linalg.lstsq(xm, bb, rcond=None)
        sse = float(np.sum((bb - xm @ coef) ** 2))
        if best is None or sse < best[0]:
            best = (sse, tau, coef)
    assert best is not None
    _, tau, (_, b, q) = best
    if q <= 0.0 or b + q / tau <= 0.0:
        return 0.0
    rise = float(b * 3.0 * tau + q * (1.0 - np.exp(-3.0)))
    # a rise bigger than a board's self-heating is the chamber moving (a ramp into a soak)
    return rise if 0.0 < rise <= MAX_SELF_HEAT_C else 0.0


def identify(time_s: np.ndarray, board_c: np.ndarray, chamber_c: np.ndarray | None,
             start: str = "auto") -> Driver:
    """Find the driver of one run. start: "auto", "warm" or "power-on".

    Model of the board thermometer: board = g * lag(lag(chamber, tau_h), tau_b) + c
    [+ q_h * (lag(lag(step, tau_h), tau_b) - 1) + q_b * (lag(step, tau_b) - 1)], the
    bracket being the self-heating of housing and board after power-on (a unit step at t=0).
    The chamber path is symmetric in (tau_h, tau_b), the self-heating path is not, so after
    a power-on both are identified; after a warm start the faster is taken as the housing's.
    """
    onset = board_power_on(time_s, board_c) if start == "auto" else 0.0
    if chamber_c is None:
        power_on = start == "power-on" or onset > POWER_ON_MIN_C
        return Driver(board_c, "board", 0.0, 0.0, 0.0, 0.0, 0.0, power_on, 0.0)
    dt10 = median_step(time_s)  # the log's sample period
    k = every(time_s)
    dt = dt10 * k
    c = np.asarray(chamber_c[::k], dtype=np.float64)
    b = np.asarray(board_c[::k], dtype=np.float64)
    step = np.ones_like(c)
    step[0] = 0.0
    with_steps = start != "warm"
    lag_c = {t: _lag(c, t, dt) for t in TAU_GRID_S}
    lag_s = {t: _lag(step, t, dt) for t in TAU_GRID_S}
    best: tuple[float, float, float, np.ndarray] | None = None
    for ta in TAU_GRID_S:
        for tb in TAU_GRID_S:
            if not with_steps and tb < ta:
                continue
            x = _lag(lag_c[ta], tb, dt)
            cols = [x, np.ones_like(x)]
            if with_steps:
                cols += [_lag(lag_s[ta], tb, dt) - 1.0, lag_s[tb] - 1.0]
            xm = np.column_stack(cols)
            coef, *_ = np.linalg.lstsq(xm, b, rcond=None)
            sse = float(np.sum((b - xm @ coef) ** 2))
            if best is None or sse < best[0]:
                best = (sse, ta, tb, coef)
    assert best is not None
    sse, ta, tb, coef = best
    q_h, q_b = (float(coef[2]), float(coef[3])) if with_steps else (0.0, 0.0)
    early = np.asarray(chamber_c[:onset_samples(time_s)], dtype=np.float64)
    air_still = float(np.ptp(early)) < 1.0  # then a rise of the board is its own heating
    power_on = start == "power-on" or (start == "auto" and (
        q_h + q_b > POWER_ON_MIN_C or (air_still and onset > POWER_ON_MIN_C)))
    if not power_on:
        q_h = q_b = 0.0
        ta, tb = min(ta, tb), max(ta, tb)
    return Driver(_housing(chamber_c, q_h, ta, dt10), "chamber", ta, tb, q_h, q_b,
                  float(coef[1]), power_on, float(np.sqrt(sse / b.shape[0])))


def _housing(chamber_c: Column, q_h: float, tau_s: float, dt_s: float) -> Column:
    """lag(chamber + q_h * power, tau_s), power the unit step at the first sample, made a
    block at a time: an array for a log in memory, a column on disk for a log on disk."""
    def heated(s: slice) -> np.ndarray:
        power = np.ones(s.stop - s.start)
        if s.start == 0 and power.shape[0]:
            power[0] = 0.0
        return np.asarray(chamber_c[s], dtype=np.float64) + q_h * power

    u = derived(len(chamber_c), np.dtype(np.float64), heated)
    parts = lag_blocks(u, tau_s, dt_s, float(chamber_c[0]), STREAM_BLOCK)
    if not is_lazy(chamber_c):
        out = np.empty(len(chamber_c))
        for a, y in parts:
            out[a:a + y.shape[0]] = y
        return out
    f = Spill().file("housing", np.dtype(np.float64))
    for _, y in parts:
        f.append(y)
    return f.column()
