"""A rate table's commanded schedules as calibration rigs run them (docs/simulate.md, "Rig
protocols"): `Step`s (IEEE 952 +/- `reversals`, a rate `staircase` in both directions), the
commanded rate per sample (`command_series`), the table's actual rate when it follows the
command with a finite acceleration (`slew`), and the command with occasional stalls (the
stepper skipped: `stall_target`); `sim.rigs.protocols` plays them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Step:
    """One commanded table rate held for dwell_s."""

    rate_dps: float
    dwell_s: float


def reversals(rate_dps: float = 100.0, dwell_s: float = 60.0) -> list[Step]:
    """IEEE 952 style: +rate then -rate, each for dwell_s (repeated, a +/- pair each)."""
    return [Step(rate_dps, dwell_s), Step(-rate_dps, dwell_s)]


def staircase(step_dps: float = 4.0, max_dps: float = 100.0, dwell_s: float = 16.0,
              zero: bool = True) -> list[Step]:
    """0, +step, -step, +2 step, -2 step ... +max, -max, each for dwell_s (+ and - of a rate
    adjacent, so they form a pair); `zero`: start with a step at rest."""
    n = int(round(max_dps / step_dps))
    steps = [Step(0.0, dwell_s)] if zero else []
    for k in range(1, n + 1):
        steps += [Step(k * step_dps, dwell_s), Step(-k * step_dps, dwell_s)]
    return steps


def schedule_s(schedule: Sequence[Step]) -> float:
    """One pass of a schedule, s."""
    return float(sum(s.dwell_s for s in schedule))


def command_series(schedule: Sequence[Step], running: np.ndarray, dt_s: float) -> np.ndarray:
    """The commanded rate per sample: zero where the table is stopped (`running` False), the
    schedule from its first step (and repeated) in each run of running samples. Steps are
    counted in whole samples, so plateaus are exact."""
    counts = [max(1, int(round(s.dwell_s / dt_s))) for s in schedule]
    cycle = np.repeat([s.rate_dps for s in schedule], counts).astype(np.float64)
    out = np.zeros(running.shape[0])
    for a, b in _runs(running):
        out[a:b] = np.resize(cycle, b - a)
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in mask."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def slew(target_dps: np.ndarray, dt_s: float, accel_dps2: float) -> np.ndarray:
    """The table's actual rate at each sample when it follows `target_dps` (a step function)
    from rest with at most accel_dps2: a change commanded at sample i is still r0 there and
    moves by accel * dt a sample after it. accel_dps2 <= 0: the table is there at once."""
    target = np.asarray(target_dps, dtype=np.float64)
    if accel_dps2 <= 0 or target.shape[0] == 0:
        return target.copy()
    out = np.empty_like(target)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(target)) + 1, [target.shape[0]]])
    r0 = 0.0
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        dist = float(target[a]) - r0
        moved = np.minimum(accel_dps2 * dt_s * np.arange(b - a + 1), abs(dist))
        path = r0 + math.copysign(1.0, dist) * moved
        out[a:b] = path[:-1]
        r0 = float(path[-1])
    return out


def stall_target(command_dps: np.ndarray, dt_s: float, per_h: float,
                 length_s: tuple[float, float], share: tuple[float, float],
                 rng: np.random.Generator) -> np.ndarray:
    """The command with stalls: about per_h an hour, at random samples where the table
    turns, the rate drops to `share` of the command for `length_s` (uniform ranges)."""
    out = np.array(command_dps, dtype=np.float64)
    turning = np.flatnonzero(out != 0.0)
    if turning.size == 0 or per_h <= 0:
        return out
    n = int(rng.poisson(per_h * out.shape[0] * dt_s / 3600.0))
    for i in np.sort(rng.choice(turning, size=n, replace=True)):
        stop = min(out.shape[0], int(i) + max(1, int(round(rng.uniform(*length_s) / dt_s))))
        out[i:stop] = command_dps[i:stop] * rng.uniform(*share)
    return out
