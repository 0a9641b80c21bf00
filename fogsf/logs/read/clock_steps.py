"""A clock that steps back, told by the data (docs/logs.md, "Clocks").

Time cannot go back, so a step back is one of two things. A *clock step* (the logger's clock
re-synchronised, NTP or GPS, while it kept logging): no sample was missed, so the
temperature runs on across the step as its trend says. A *reboot* (the logger restarted its
clock): the temperature, which went on moving while the logger was down, jumps off its
trend. The verdict compares the lines fitted to the temperature on each side of the step,
both taken to the midpoint between its two rows. Two cases are reboots whatever the
temperature says: a clock that lands near 0 or before the log's first stamp (a restarted
clock), and a step in a soak (the temperature flat on both sides cannot tell).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fogsf.logs.read.columns import Column

SIDE_ROWS = 100  # rows each side of a step the temperature's trend is fitted to
MIN_SIDE_ROWS = 3  # fewer on either side: the temperature cannot tell
# the temperature "runs on" within this many sigmas of its noise about the trend, and never
# tighter than one quantum of the thermometer or JUMP_FLOOR_C (a thermometer's resolution)
JUMP_SIGMAS = 5.0
JUMP_FLOOR_C = 0.01
# a clock that lands within this of 0 (or before the log's first stamp) restarted: a reboot
RESTART_NEAR_ZERO_S = 10.0


@dataclass(frozen=True)
class StepBack:
    """One step back of a clock, judged by the temperature across it."""

    row: int  # the first row after the step (0-based, as read)
    step_s: float  # the clock's step (< 0)
    jump_c: float | None  # the temperature's jump off its trend, C; None: it cannot tell
    tolerance_c: float  # the jump that still counts as running on
    restarted: bool = False  # the clock landed near 0 or before the log's first stamp
    flat: bool = False  # the temperature is flat on both sides (a soak): it cannot tell

    @property
    def is_clock_step(self) -> bool:
        """The temperature runs on across it, off a soak, and the clock did not restart: a
        re-synchronised clock, no sample missed."""
        return (not self.restarted and not self.flat and self.jump_c is not None
                and abs(self.jump_c) <= self.tolerance_c)

    def text(self, line: int, reset_gap_s: float) -> str:
        """What it is and why, naming its line of the file (a reboot's segment starts
        `reset_gap_s` after the last row)."""
        what = ("a clock step (a re-synchronised clock, no sample missed): the later rows "
                "timed on from the row before, states carried" if self.is_clock_step else
                f"a reboot of the logger: a new segment {reset_gap_s:g} s after the last row, "
                "states restarted")
        return f"time steps {self.step_s:+.1f} s at line {line}: {self.why()}: {what}"

    def why(self) -> str:
        """What the clock and the temperature say across the step."""
        if self.jump_c is None:
            temp = "too few rows around it for the temperature to tell"
        elif self.flat:
            temp = (f"the temperature is flat on both sides (a soak, {self.jump_c:+.3f} C off "
                    "its trend across it) and cannot tell a clock step from a reboot")
        else:
            runs = abs(self.jump_c) <= self.tolerance_c
            temp = (f"the temperature {'runs on' if runs else 'jumps'} {self.jump_c:+.3f} C "
                    f"off its trend across it (within {self.tolerance_c:.3f} C runs on)")
        if self.restarted:
            return (f"the clock restarts (near 0 or before the log's first stamp), a reboot "
                    f"whatever the temperature: {temp}")
        return temp


def judge_step(t: Column, temp: Column, row: int, lo: int = 0, hi: int | None = None
               ) -> StepBack:
    """The verdict on the clock `t`'s step back before `row`, from the temperature `temp` of
    rows [lo, hi) (the segment the step lies in: other steps bound it)."""
    hi = temp.shape[0] if hi is None else hi
    step_s = float(t[row] - t[row - 1])
    landed = float(t[row])
    restarted = abs(landed) <= RESTART_NEAR_ZERO_S or landed <= float(t[0])
    before = np.asarray(temp[max(lo, row - SIDE_ROWS):row], dtype=np.float64)
    after = np.asarray(temp[row:min(hi, row + SIDE_ROWS)], dtype=np.float64)
    if before.size < MIN_SIDE_ROWS or after.size < MIN_SIDE_ROWS:
        return StepBack(row, step_s, None, math.inf, restarted)
    xb = np.arange(-before.size, 0, dtype=np.float64)  # row - 1 at -1, row at 0
    xa = np.arange(after.size, dtype=np.float64)
    fb = np.polyfit(xb, before, 1)
    fa = np.polyfit(xa, after, 1)
    jump = float(np.polyval(fa, -0.5) - np.polyval(fb, -0.5))
    resid = np.concatenate([before - np.polyval(fb, xb), after - np.polyval(fa, xa)])
    sigma = float(np.sqrt(np.mean(resid ** 2)))
    # the thermometer's quantum: its smallest change on either side, not across the step
    steps = np.abs(np.concatenate([np.diff(before), np.diff(after)]))
    quantum = float(steps[steps > 0].min()) if (steps > 0).any() else 0.0
    tol = max(JUMP_SIGMAS * sigma, quantum, JUMP_FLOOR_C)
    # flat: on each side the trend moves within the tolerance over the rows fitted
    flat = bool(abs(fb[0]) * before.size <= tol and abs(fa[0]) * after.size <= tol)
    return StepBack(row, step_s, jump, tol, restarted, flat)


def judge_steps(t: Column, temp: Column, rows: list[int]) -> list[StepBack]:
    """Each step back of `t` before `rows` judged within the rows between its neighbouring
    steps."""
    bounds = [0, *rows, int(temp.shape[0])]
    return [judge_step(t, temp, r, bounds[i], bounds[i + 2]) for i, r in enumerate(rows)]
