"""The chamber programs and table schedules that the planted-effect cases draw
(`diagnose.cases.planted`): each from a seeded generator over the ranges in its code."""

from __future__ import annotations

import numpy as np

from fogsf.sim.config import ProfileConfig, TableConfig

MIXED_RATES_DPS = (10.0, 50.0, 100.0, 200.0)  # the mixed-rate null's |rate| levels


def steps(rng: np.random.Generator, back: bool, minutes: float) -> ProfileConfig:
    t0 = float(rng.uniform(-10.0, 30.0))
    delta = float(rng.uniform(25.0, 40.0)) * float(rng.choice([-1.0, 1.0]))
    rate = float(rng.uniform(1.0, 2.0))
    levels = [t0, t0 + delta] + ([t0] if back else [])
    ramps = (len(levels) - 1) * abs(delta) / rate * 60.0
    soak = max(900.0, (minutes * 60.0 - ramps) / len(levels))
    return ProfileConfig(kind="steps", levels_c=[round(x, 1) for x in levels],
                         rate_c_per_min=rate, soak_s=round(soak))


def long_soaks(rng: np.random.Generator) -> ProfileConfig:
    """Up and back with 70-80 min soaks (4.5 h): a lag keeps settling in the soaks, a dT/dt
    term dies with the coil's rate; shorter soaks leave the two ambiguous."""
    t0 = float(rng.uniform(-10.0, 30.0))
    delta = float(rng.uniform(25.0, 40.0)) * float(rng.choice([-1.0, 1.0]))
    return ProfileConfig(kind="steps", levels_c=[round(t0, 1), round(t0 + delta, 1),
                                                 round(t0, 1)],
                         rate_c_per_min=float(rng.uniform(1.0, 2.0)),
                         soak_s=float(rng.uniform(4200.0, 4800.0)))


def partial(rng: np.random.Generator) -> ProfileConfig:
    """Partial cycles: up 25-40 C, back 10-20 C, up 10-20 C, back 15-25 C, up 10-20 C, back
    to the start (either direction first), 1-2 C/min, 15-25 min soaks at each turn."""
    t0 = float(rng.uniform(-20.0, 10.0))
    sign = float(rng.choice([-1.0, 1.0]))
    steps = [float(rng.uniform(*r)) for r in ((25.0, 40.0), (-20.0, -10.0), (10.0, 20.0),
                                                (-25.0, -15.0), (10.0, 20.0))]
    rate = float(rng.uniform(1.0, 2.0))
    soak = float(rng.uniform(900.0, 1500.0))
    levels = [t0] + [t0 + sign * float(np.sum(steps[:i + 1])) for i in range(len(steps))] + [t0]
    if min(levels) < -50.0 or max(levels) > 60.0:  # the other direction stays in the chamber
        levels = [2.0 * t0 - v for v in levels]
    pts = [[0.0, t0], [soak, t0]]
    for lv in levels[1:]:
        t = pts[-1][0] + abs(lv - pts[-1][1]) / rate * 60.0
        pts += [[t, lv], [t + soak, lv]]
    return ProfileConfig(kind="program", points=[[round(t, 1), round(v, 2)] for t, v in pts],
                         rate_c_per_min=rate, levels_c=[round(x, 2) for x in levels])


def cycle(rng: np.random.Generator) -> ProfileConfig:
    t0 = float(rng.uniform(-20.0, 10.0))
    span = float(rng.uniform(30.0, 45.0))
    return ProfileConfig(kind="cycle", start_c=round(t0, 1), stop_c=round(t0 + span, 1),
                         rate_c_per_min=float(rng.uniform(1.0, 2.0)),
                         soak_s=float(rng.uniform(900.0, 1500.0)), cycles=1)


def table(rng: np.random.Generator, kind: str) -> TableConfig:
    dwell = float(rng.choice([120.0, 180.0, 240.0]))
    if kind == "mixed":  # the mixed-rate null's table: +/- at every MIXED_RATES_DPS
        return TableConfig(kind="levels", rates_dps=[s * r for r in MIXED_RATES_DPS
                                                     for s in (1.0, -1.0)], dwell_s=dwell)
    if kind == "multi_pm":  # +/- at three |rate|
        lv = [float(rng.uniform(5.0, 15.0)), float(rng.uniform(20.0, 35.0)),
              float(rng.uniform(40.0, 100.0))]
        return TableConfig(kind="levels", rates_dps=[s * r for r in lv for s in (1.0, -1.0)],
                           dwell_s=dwell)
    if kind == "constant":
        return TableConfig(kind="constant", rate_dps=float(rng.choice([10.0, 20.0])))
    if kind == "alternating":
        return TableConfig(kind="alternating", rate_dps=float(rng.uniform(5.0, 20.0)),
                           dwell_s=dwell)
    if kind == "multi":  # several |rate|, one sign
        lo = float(rng.uniform(5.0, 15.0))
        return TableConfig(kind="levels", rates_dps=[lo, float(rng.uniform(40.0, 100.0)),
                                                     float(rng.uniform(20.0, 35.0))],
                           dwell_s=dwell)
    lo = float(rng.uniform(5.0, 15.0))  # +/- at two |rate|
    hi = float(rng.uniform(40.0, 100.0))
    return TableConfig(kind="levels", rates_dps=[lo, -lo, hi, -hi], dwell_s=dwell)
