"""Chamber programs of calibration rigs (docs/simulate.md, "Rig protocols"): a `Chamber` is
(time_s, temp_c) points, linear between them, with the intervals where the table is stopped
while the heater settles; `bang_bang` holds set points with a bang-bang heater, `ramp` soaks,
ramps and soaks, `loop` goes up and back down; `sim.rigs.protocols` plays them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fogsf.errors import UserError


@dataclass
class Chamber:
    """A chamber program: (time_s, temp_c) points, linear between them, and the intervals
    [start_s, stop_s) where the table is stopped (the heater settling)."""

    points: list[list[float]]
    stopped: list[tuple[float, float]] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return float(self.points[-1][0])


def _triangle(t0: float, length_s: float, centre_c: float, swing_c: float, period_s: float,
              heat_share: float) -> list[list[float]]:
    """Points of a bang-bang hold from t0 for length_s: from the centre up to centre+swing
    with the heater on (heat_share of the period), down to centre-swing with it off, and so
    on; the last leg cut at the end of the hold."""
    pts = [[t0, centre_c]]
    up, down = heat_share * period_s, (1.0 - heat_share) * period_s
    t, level = t0 + up / 2.0, centre_c + swing_c
    while t < t0 + length_s:
        pts.append([t, level])
        t += down if level > centre_c else up
        level = 2.0 * centre_c - level
    end = t0 + length_s
    prev_t, prev_c = pts[-1]
    # the last leg runs toward `level` at its slope: cut it at the end of the hold
    frac = (end - prev_t) / (t - prev_t)
    pts.append([end, prev_c + frac * (level - prev_c)])
    return pts


def bang_bang(set_points_c: Sequence[float] = (-20.0, 0.0, 20.0, 40.0, 60.0),
              hold_s: float = 1800.0, settle_s: float = 300.0, ramp_c_per_min: float = 2.0,
              swing_c: float = 0.75, period_s: float = 240.0, heat_share: float = 0.4
              ) -> Chamber:
    """Set points held by a bang-bang heater: the air oscillates +/- swing_c (a triangle of
    period_s, rising heat_share of it) about each set point for settle_s + hold_s; between
    set points a ramp at ramp_c_per_min. The table is stopped during each ramp and settle."""
    _require(bool(set_points_c), "bang_bang: give at least one set point")
    _require(period_s > 0 and 0 < heat_share < 1 and swing_c >= 0,
             "bang_bang: period_s must be > 0, heat_share in 0..1, swing_c >= 0")
    _require(ramp_c_per_min > 0 and hold_s > 0 and settle_s >= 0,
             "bang_bang: ramp_c_per_min and hold_s must be > 0, settle_s >= 0")
    pts: list[list[float]] = []
    stopped: list[tuple[float, float]] = []
    t = 0.0
    for i, sp in enumerate(set_points_c):
        if i:
            ramp = abs(sp - set_points_c[i - 1]) / ramp_c_per_min * 60.0
            stopped.append((t, t + ramp + settle_s))
            t += ramp
        else:
            stopped.append((0.0, settle_s))
        tri = _triangle(t, settle_s + hold_s, sp, swing_c, period_s, heat_share)
        pts += tri
        t += settle_s + hold_s
    return Chamber(_strictly_increasing(pts), [(a, b) for a, b in stopped if b > a])


def ramp(start_c: float = -20.0, stop_c: float = 50.0, rate_c_per_min: float = 1.0,
         soak_s: float = 600.0, stopped_s: float = 0.0) -> Chamber:
    """Soak at start_c, ramp to stop_c, soak there; the table stopped for the first
    stopped_s."""
    _require(rate_c_per_min > 0 and soak_s >= 0 and stopped_s >= 0,
             "ramp: rate_c_per_min must be > 0, soak_s and stopped_s >= 0")
    ramp_s = abs(stop_c - start_c) / rate_c_per_min * 60.0
    pts = [[0.0, start_c], [soak_s, start_c], [soak_s + ramp_s, stop_c],
           [2 * soak_s + ramp_s, stop_c]]
    return Chamber(_strictly_increasing(pts), [(0.0, stopped_s)] if stopped_s > 0 else [])


def loop(lo_c: float = -20.0, hi_c: float = 50.0, up_c_per_min: float = 1.0,
         down_c_per_min: float = 0.7, soak_s: float = 1200.0) -> Chamber:
    """Soak at lo_c, ramp up to hi_c, soak, ramp down to lo_c, soak: both directions, as a
    training run needs them (a model trained on one direction extrapolates the other)."""
    _require(up_c_per_min > 0 and down_c_per_min > 0 and soak_s >= 0,
             "loop: ramp rates must be > 0, soak_s >= 0")
    up = abs(hi_c - lo_c) / up_c_per_min * 60.0
    down = abs(hi_c - lo_c) / down_c_per_min * 60.0
    t = np.cumsum([0.0, soak_s, up, soak_s, down, soak_s])
    pts = [[float(a), c] for a, c in zip(t, (lo_c, lo_c, hi_c, hi_c, lo_c, lo_c), strict=True)]
    return Chamber(_strictly_increasing(pts))


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise UserError(message)


def _strictly_increasing(pts: list[list[float]]) -> list[list[float]]:
    """Points with repeated times dropped (the profile reader wants increasing times)."""
    out = [pts[0]]
    for p in pts[1:]:
        if p[0] > out[-1][0] + 1e-9:
            out.append([float(p[0]), float(p[1])])
    return out
