"""The housing temperature that drives the internal thermal nodes.

The simulator's (and a real gyro's) internal nodes lag the housing, which lags the chamber
air; the board thermometer is one more lag behind the housing. With the chamber air logged
(`chamber_c`), the two lags chamber -> housing -> board are identified by profiling their
time constants over a grid with linear least squares inside (board = gain * lag2(chamber) +
offset + self-heating step); the housing is then the chamber air lagged by the faster of
the two (a chain of two first-order lags is symmetric in its time constants, so which is
the housing's is a convention: the faster one, as in a gyro whose housing follows the air
within a few minutes). Without `chamber_c`, the board thermometer itself is the driver.

A power-on start shows as a self-heating rise of the board at constant chamber air; its
amplitude decides whether the internal nodes' own (unseen) self-heating transients belong
in the base model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trainer.sim.thermal import first_order_lag

TAU_GRID_S = (0.0, 15.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0, 300.0, 360.0, 480.0,
              600.0, 800.0, 1000.0, 1300.0, 1800.0)
DECIMATE = 10  # fit on 1 Hz samples
POWER_ON_MIN_C = 0.5  # a self-heating rise above this (C) marks a power-on start


@dataclass
class Driver:
    """The driving (housing) temperature at 10 Hz and how it was found."""

    temp_c: np.ndarray
    source: str  # "chamber" or "board"
    tau_housing_s: float
    tau_board_s: float
    self_heat_c: float  # board's rise after power-on (0 for a warm start)
    board_offset_c: float  # board minus lagged chamber at equilibrium
    power_on: bool
    rms_c: float  # RMS of the board-thermometer fit


def _two_lag(u: np.ndarray, a: float, b: float, dt: float) -> np.ndarray:
    y = first_order_lag(u, a, dt, float(u[0]))
    return first_order_lag(y, b, dt, float(y[0]))


def identify(time_s: np.ndarray, board_c: np.ndarray, chamber_c: np.ndarray | None,
             start: str = "auto") -> Driver:
    """Find the driver of one run. start: "auto", "warm" or "power-on"."""
    if chamber_c is None:
        return Driver(np.asarray(board_c, dtype=np.float64), "board", 0.0, 0.0, 0.0, 0.0,
                      start == "power-on", 0.0)
    dt = float(np.median(np.diff(time_s))) * DECIMATE
    c = np.asarray(chamber_c, dtype=np.float64)[::DECIMATE]
    b = np.asarray(board_c, dtype=np.float64)[::DECIMATE]
    t = np.asarray(time_s, dtype=np.float64)[::DECIMATE] - float(time_s[0])
    step = np.ones_like(c)
    step[0] = 0.0
    best: tuple[float, float, float, np.ndarray] | None = None
    for i, ta in enumerate(TAU_GRID_S):
        for tb in TAU_GRID_S[i:]:
            x = _two_lag(c, ta, tb, dt)
            s = _two_lag(step, ta, tb, dt) - 1.0  # -1 at power-on, 0 once settled
            cols = [x, np.ones_like(x)]
            if start != "warm":
                cols.append(s)
            xm = np.column_stack(cols)
            coef, *_ = np.linalg.lstsq(xm, b, rcond=None)
            sse = float(np.sum((b - xm @ coef) ** 2))
            if best is None or sse < best[0]:
                best = (sse, ta, tb, coef)
    assert best is not None
    sse, ta, tb, coef = best
    rise = float(coef[2]) if start != "warm" else 0.0  # coefficient of (step response - 1)
    power_on = start == "power-on" or (start == "auto" and rise > POWER_ON_MIN_C)
    housing = first_order_lag(np.asarray(chamber_c, dtype=np.float64), ta,
                              float(np.median(np.diff(time_s))), float(chamber_c[0]))
    return Driver(housing, "chamber", ta, tb, rise if power_on else 0.0, float(coef[1]),
                  power_on, float(np.sqrt(sse / b.shape[0])))
