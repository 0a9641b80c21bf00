"""Calibration rigs as people build them: their table schedules, chamber programs and log
conventions, with the truth behind every sample (docs/simulate.md, "Rig protocols").

A `RigProtocol` is a chamber program (`Chamber`: bang-bang set points or a ramp, with the
intervals where the table is stopped while the heater settles) and a commanded table
schedule (`Step`s: IEEE 952 +/- reversals, a rate staircase in both directions), played on
a table with a finite acceleration (`slew`) and occasional stalls (the stepper skipped: the
table turned slower than commanded, flagged). `run_rig` / `run_imu3` run one gyro, or three
skew-mounted ones, through it with the simulator (`gyro.simulate` with the actual rate the
axis sees: the physics is the simulator's own); `write_ros`, `write_plain` and `write_imu3`
write the log the way such a rig writes it and return a `RigLog`: the column map a user
would write for it (our name -> the log's column, an expression over columns, or a number)
and the per-axis `Truth`. The same protocol, gyro seeds and seed give the same bytes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.trainer.errors import UserError
from fogsf.trainer.logs.chamber_log import EARTH_RATE_DPS, RATE_RANGE_HZ
from fogsf.trainer.logs.dialect import MAPPING_FILES
from fogsf.trainer.logs.logio import write_rows
from fogsf.trainer.sim.config import BiasConfig, ProfileConfig, SimConfig, TableConfig
from fogsf.trainer.sim.effects import EffectConfig
from fogsf.trainer.sim.gyro import SimResult, simulate
from fogsf.trainer.sim.population import gyro_for_seed, with_gyro
from fogsf.trainer.sim.profiles import chamber_series

STEPS_PER_REV = 577803.965671  # the ROS rig's stepper steps per table revolution
EPOCH_S = 1_700_000_000.0  # where absolute time stamps start (2023-11-14)
DEG_PER_RAD = 57.29577951308232
SKEW_COSINE = 1.0 / math.sqrt(3.0)  # an axis at 54.7356 deg to the table axis
AXES = ("x", "y", "z")
LATITUDE_DEG = 34.26


# --- table schedules ---------------------------------------------------------------------

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


# --- chamber programs ----------------------------------------------------------------------

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


# --- protocols and runs --------------------------------------------------------------------

@dataclass
class RigProtocol:
    """What a rig does: the chamber program, the commanded table schedule and how the
    table and the thermometer behave.

    accel_dps2: the table's acceleration (0: at each command at once); stalls_per_h:
    stalls an hour, each stall_s long, the table at stall_share of the command;
    temp_lsb_c: the thermometer's step (1, 0.25 or 0.0625 C); bias: the gyros' bias law
    (None: each gyro's own, from the population); arw_deg_per_sqrt_h: the gyros' angle
    random walk (None: each gyro's own; 0.05 deg/sqrt(h) is 0.27 deg/h on the mean of a
    +/- pair of 60 s plateaus); effects: the simulator's optional effects on every gyro
    (e.g. rate_nonlinearity, asymmetry: they see the rate the axis actually turns at);
    rotating_earth: a tilted axis also sees the horizontal earth rate turning with the table
    (off: each axis sees the vertical earth rate x its cosine, what a column map can say);
    stamp_jitter_s: the logger's time stamps off the sample times by up to this (uniform;
    below 5 % of a sample so that steps stay within the reader's 20 %).
    """

    chamber: Chamber
    schedule: list[Step]
    rate_hz: float = 10.0
    accel_dps2: float = 300.0
    stalls_per_h: float = 0.0
    stall_s: tuple[float, float] = (0.3, 2.0)
    stall_share: tuple[float, float] = (0.3, 0.9)
    temp_lsb_c: float = 0.0625
    latitude_deg: float = LATITUDE_DEG
    bias: BiasConfig | None = None
    arw_deg_per_sqrt_h: float | None = None
    effects: list[EffectConfig] = field(default_factory=list)
    rotating_earth: bool = False
    stamp_jitter_s: float = 0.0

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz


def reversal_protocol(rate_dps: float = 100.0, dwell_s: float = 60.0,
                      chamber: Chamber | None = None, **kw: Any) -> RigProtocol:
    """IEEE 952 +/- reversals through a chamber program (default: a ramp -20 -> 50 C at
    1 C/min with 10 min soaks), bias 1 deg/h drifting 0.05 deg/h/C unless `bias` is given."""
    kw.setdefault("bias", BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05))
    return RigProtocol(chamber or ramp(), reversals(rate_dps, dwell_s), **kw)


def staircase_protocol(step_dps: float = 4.0, max_dps: float = 100.0, dwell_s: float = 16.0,
                       chamber: Chamber | None = None, **kw: Any) -> RigProtocol:
    """A rate staircase in both directions at each bang-bang set point (default: 5 set
    points, -20..60 C, two staircases each), the table stopped while the heater settles."""
    steps = staircase(step_dps, max_dps, dwell_s)
    chamber = chamber or bang_bang(hold_s=2 * schedule_s(steps))
    kw.setdefault("bias", BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05))
    return RigProtocol(chamber, steps, **kw)


def stationary_protocol(chamber: Chamber | None = None, **kw: Any) -> RigProtocol:
    """The table stopped throughout (the autopilots' cold soak and warm-up): a chamber
    program (default: a loop -20 -> 50 -> -20 C) with the gyro at rest, so the output is
    bias + earth rate; bias 1 deg/h drifting 0.05 deg/h/C unless `bias` is given."""
    kw.setdefault("bias", BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05))
    return RigProtocol(chamber or loop(), [Step(0.0, 60.0)], **kw)


@dataclass
class Truth:
    """The truth behind one axis of a rig log, per sample (time_s as the log writes it)."""

    time_s: np.ndarray
    sf_ppm: np.ndarray  # true SF error vs nominal
    bias_dph: np.ndarray  # true bias
    table_dps: np.ndarray  # the table's actual rate
    command_dps: np.ndarray  # the commanded rate (what the log's table column says)
    axis_rate_dps: np.ndarray  # the rate on this axis: table_dps * cosine
    earth_dps: np.ndarray  # earth rate on this axis
    ideal_dps: np.ndarray  # noiseless, unquantised gyro output
    cosine: float  # the axis' direction cosine to the table axis
    measures: np.ndarray  # the rows the log marks as measuring (enabled, not stalled)

    def columns(self) -> dict[str, np.ndarray]:
        return {"time_s": self.time_s, "true_sf_ppm": self.sf_ppm,
                "true_bias_dph": self.bias_dph, "true_table_dps": self.table_dps,
                "command_dps": self.command_dps, "true_axis_rate_dps": self.axis_rate_dps,
                "true_earth_dps": self.earth_dps, "ideal_dps": self.ideal_dps,
                "measures": self.measures.astype(np.float64)}


@dataclass
class AxisRun:
    """One gyro on the rig: its simulated run and the direction cosine it sees."""

    gyro_seed: int
    cosine: float
    result: SimResult

    @property
    def gyro_dps(self) -> np.ndarray:
        return self.result.log.gyro_dps

    @property
    def temp_c(self) -> np.ndarray:
        return self.result.log.temp_c


@dataclass
class RigRun:
    """A protocol played on the rig: the table and flags per sample, one AxisRun per axis."""

    protocol: RigProtocol
    time_s: np.ndarray  # from 0
    command_dps: np.ndarray
    table_dps: np.ndarray  # actual
    stalled: np.ndarray  # bool: the table slower than commanded (a stall or its recovery)
    enabled: np.ndarray  # bool: the table running (not stopped for the heater)
    heating: np.ndarray  # bool: the chamber's heater on (the air warming)
    axes: dict[str, AxisRun]
    stamp_s: np.ndarray  # the logger's time stamps, from 0: time_s + its jitter

    @property
    def measures(self) -> np.ndarray:
        return self.enabled & ~self.stalled

    def truth(self, axis: str, epoch_s: float = 0.0) -> Truth:
        ax = self.axes[axis]
        r = ax.result
        return Truth(self.stamp_s + epoch_s, r.sf_ppm, r.bias_dps * 3600.0, self.table_dps,
                     self.command_dps, self.table_dps * ax.cosine, r.log.earth_rate_dps,
                     r.ideal_dps, ax.cosine, self.measures)


def _table(p: RigProtocol, t_s: np.ndarray, seed: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(command, actual, stalled, enabled) per sample."""
    enabled = np.ones(t_s.shape[0], dtype=bool)
    for a, b in p.chamber.stopped:
        enabled &= ~((t_s >= a - 1e-9) & (t_s < b - 1e-9))
    command = command_series(p.schedule, enabled, p.dt_s)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x516]))
    target = stall_target(command, p.dt_s, p.stalls_per_h, p.stall_s, p.stall_share, rng)
    actual = slew(target, p.dt_s, p.accel_dps2)
    clean = slew(command, p.dt_s, p.accel_dps2)
    stalled = (target != command) | (np.abs(actual - clean) > 1e-9)
    return command, actual, stalled, enabled


def _axis_config(p: RigProtocol, gyro_seed: int, noise_seed: int) -> SimConfig:
    run = SimConfig(scenario=f"rig:gyro{gyro_seed}", seed=noise_seed, dt_s=p.dt_s,
                    latitude_deg=p.latitude_deg)
    run.profile = ProfileConfig(kind="program", points=p.chamber.points)
    run.table = TableConfig(kind="constant", rate_dps=1.0)  # unused: the actual rate is given
    cfg = with_gyro(run, gyro_for_seed(gyro_seed))
    cfg.noise.temp_lsb_c = p.temp_lsb_c
    if p.bias is not None:
        cfg.bias = replace(p.bias)
    if p.arw_deg_per_sqrt_h is not None:
        cfg.noise.arw_deg_per_sqrt_h = p.arw_deg_per_sqrt_h
    cfg.effects = [replace(e, params=dict(e.params)) for e in p.effects]
    return cfg


def _noise_seed(seed: int, axis: int) -> int:
    return seed if axis == 0 else int(np.random.SeedSequence([seed, axis]).generate_state(1)[0])


MAX_STALLS_PER_H = 3600.0


def check_protocol(p: RigProtocol) -> None:
    """Refuse a protocol that cannot be played (UserError naming the field and the rule)."""
    lo, hi = RATE_RANGE_HZ
    rules = [
        (lo <= p.rate_hz <= hi, f"rate_hz must lie in {lo:g}..{hi:g}, got {p.rate_hz!r}"),
        (math.isfinite(p.accel_dps2) and p.accel_dps2 >= 0,
         f"accel_dps2 must be >= 0, got {p.accel_dps2!r}"),
        (0 <= p.stalls_per_h <= MAX_STALLS_PER_H,
         f"stalls_per_h must lie in 0..{MAX_STALLS_PER_H:g}, got {p.stalls_per_h!r}"),
        (0 < p.stall_s[0] <= p.stall_s[1] < math.inf,
         f"stall_s must be (shortest, longest) > 0, got {p.stall_s!r}"),
        (0 <= p.stall_share[0] <= p.stall_share[1] < 1,
         f"stall_share must be (lowest, highest) in 0..1, got {p.stall_share!r}"),
        (math.isfinite(p.temp_lsb_c) and p.temp_lsb_c >= 0,
         f"temp_lsb_c must be >= 0, got {p.temp_lsb_c!r}"),
        (0 <= p.stamp_jitter_s <= 0.05 / p.rate_hz,
         f"stamp_jitter_s must lie in 0..{0.05 / p.rate_hz:g} (5 % of a sample), got "
         f"{p.stamp_jitter_s!r}"),
        (abs(p.latitude_deg) <= 90, f"latitude_deg must lie in -90..90, got {p.latitude_deg!r}"),
        (bool(p.schedule), "schedule: give at least one Step"),
        (all(math.isfinite(s.rate_dps) and math.isfinite(s.dwell_s) and s.dwell_s > 0
             for s in p.schedule), "schedule: every rate must be finite, every dwell_s > 0"),
        (len(p.chamber.points) >= 2, "chamber: at least two (time_s, temp_c) points"),
    ]
    for ok, message in rules:
        if not ok:
            raise UserError(f"rig protocol: {message}")


def run_rig(p: RigProtocol, gyro_seed: int = 0, seed: int = 0) -> RigRun:
    """One gyro (population member gyro_seed) on the table axis, noise seed `seed`."""
    return run_imu3(p, (gyro_seed,), seed, cosines=(1.0,), axes=("",))


def run_imu3(p: RigProtocol, gyro_seeds: Sequence[int] = (1, 2, 3), seed: int = 0,
             cosines: Sequence[float] = (SKEW_COSINE,) * 3,
             azimuths_deg: Sequence[float] = (0.0, 120.0, 240.0),
             axes: Sequence[str] = AXES) -> RigRun:
    """Gyros on one table, axis i at cosine cosines[i] to the table axis (vertical) and
    azimuth azimuths_deg[i]: each sees table * cosine and the earth's vertical rate *
    cosine; the protocol's `rotating_earth` adds the horizontal earth rate turning with the
    table (zero on average over whole turns, up to 0.0034 deg/s on a skew axis)."""
    check_protocol(p)
    t, chamber = chamber_series(ProfileConfig(kind="program", points=p.chamber.points),
                                p.dt_s)
    command, actual, stalled, enabled = _table(p, t, seed)
    heating = np.diff(chamber, append=chamber[-1]) > 0.0
    angle_deg = np.concatenate([[0.0], np.cumsum(actual[:-1]) * p.dt_s])
    runs: dict[str, AxisRun] = {}
    for i, (name, gseed, cos) in enumerate(zip(axes, gyro_seeds, cosines, strict=True)):
        earth = _earth_on_axis(p.latitude_deg, cos, azimuths_deg[i % len(azimuths_deg)],
                               angle_deg if p.rotating_earth else None)
        cfg = _axis_config(p, gseed, _noise_seed(seed, i))
        runs[name] = AxisRun(gseed, cos, simulate(cfg, table_dps=actual * cos,
                                                  earth_dps=earth))
    return RigRun(p, t, command, actual, stalled, enabled, heating, runs, _stamps(p, t, seed))


def _stamps(p: RigProtocol, t_s: np.ndarray, seed: int) -> np.ndarray:
    """The logger's time stamps: each sample's time plus uniform jitter of +/- stamp_jitter_s
    (a ROS node stamps a message when it handles it, not when the gyro sampled)."""
    if p.stamp_jitter_s <= 0:
        return t_s
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7173]))
    return t_s + rng.uniform(-p.stamp_jitter_s, p.stamp_jitter_s, t_s.shape[0])


def _earth_on_axis(latitude_deg: float, cosine: float, azimuth_deg: float,
                   table_angle_deg: np.ndarray | None) -> np.ndarray | float:
    lat = math.radians(latitude_deg)
    vertical = EARTH_RATE_DPS * math.sin(lat) * cosine
    if table_angle_deg is None:
        return vertical
    sine = math.sqrt(max(0.0, 1.0 - cosine * cosine))
    turn = np.radians(table_angle_deg + azimuth_deg)
    return vertical + EARTH_RATE_DPS * math.cos(lat) * sine * np.cos(turn)


def earth_map_dps(latitude_deg: float, cosine: float = 1.0) -> float:
    """The earth rate a user writes in the column map for an axis at `cosine` to the
    vertical table axis."""
    return EARTH_RATE_DPS * math.sin(math.radians(latitude_deg)) * cosine


# --- writers -------------------------------------------------------------------------------

ColumnMap = dict[str, str | float]


@dataclass
class RigLog:
    """A written rig log: where, the column map a user writes for it, the truth per axis
    ("" for a one-axis rig)."""

    path: Path
    columns: ColumnMap
    truth: dict[str, Truth]
    mapping_path: Path | None = None


def _write_csv(path: str | Path, cols: dict[str, np.ndarray], fmts: list[str]) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    data = np.column_stack([np.asarray(v, dtype=np.float64) for v in cols.values()])
    with open(out, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(cols) + "\n")
        write_rows(f, data, fmts)
    return out


def write_mapping(folder: str | Path, columns: ColumnMap, kind: str = "toml") -> Path:
    """The column map as fogsf-columns.toml (or .json) in `folder`: our names as keys."""
    name = next(n for n in MAPPING_FILES if n.endswith("." + kind))
    path = Path(folder) / name
    if kind == "json":
        text = json.dumps(columns, indent=2) + "\n"
    else:  # JSON strings and numbers are TOML ones
        text = "".join(f"{k} = {json.dumps(v)}\n" for k, v in columns.items())
    path.write_text(text, encoding="utf-8")
    return path


def write_ros(path: str | Path, run: RigRun, steps_per_rev: float = STEPS_PER_REV,
              epoch_s: float = EPOCH_S, mapping: bool = True) -> RigLog:
    """The ROS rig's log: sec,nanosec (the epoch time split in two integers), gyro_raw
    (rad/s), gyro_temp (C), rig_rate (the COMMANDED table rate in stepper steps/s),
    rig_heating, rig_enabled, rig_stalled (0/1); with `mapping`, fogsf-columns.toml
    beside it."""
    ax = run.axes[_one_axis(run)]
    ns = np.int64(round(epoch_s * 1e9)) + np.round(run.stamp_s * 1e9).astype(np.int64)
    cols = {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000,
            "gyro_raw": ax.gyro_dps / DEG_PER_RAD, "gyro_temp": ax.temp_c,
            "rig_rate": run.command_dps * steps_per_rev / 360.0,
            "rig_heating": run.heating, "rig_enabled": run.enabled, "rig_stalled": run.stalled}
    out = _write_csv(path, cols, ["%d", "%d", "%.12g", "%.10g", "%.12g", "%d", "%d", "%d"])
    cmap: ColumnMap = {
        "time_s": "sec + nanosec * 1e-9",
        "temp_c": "gyro_temp",
        "table_rate_dps": f"rig_rate * 360 / {steps_per_rev!r}",
        "gyro_dps": f"gyro_raw * {DEG_PER_RAD!r}",
        "earth_rate_dps": earth_map_dps(run.protocol.latitude_deg, ax.cosine),
        "valid": "rig_enabled == 1 and rig_stalled == 0",
    }
    return RigLog(out, cmap, {"": run.truth(_one_axis(run), epoch_s)},
                  write_mapping(out.parent, cmap) if mapping else None)


def write_plain(path: str | Path, run: RigRun, gyro_unit: str = "rad/s",
                epoch_s: float = EPOCH_S, mapping: bool = False) -> RigLog:
    """A plain CSV: time_s (epoch s), temp_c, table_rate_dps (commanded), the gyro in rad/s
    (gyro_rad_s) or deg/s (gyro_dps), earth_rate_dps and valid (0 where the table is stopped
    or stalled). In deg/s every column has the format's name (no map needed)."""
    ax = run.axes[_one_axis(run)]
    if gyro_unit not in ("rad/s", "deg/s"):
        raise ValueError(f"gyro_unit must be 'rad/s' or 'deg/s', got {gyro_unit!r}")
    rad = gyro_unit == "rad/s"
    cols = {"time_s": run.stamp_s + epoch_s, "temp_c": ax.temp_c,
            "table_rate_dps": run.command_dps,
            "gyro_rad_s" if rad else "gyro_dps": ax.gyro_dps / DEG_PER_RAD if rad
            else ax.gyro_dps,
            "earth_rate_dps": ax.result.log.earth_rate_dps, "valid": run.measures}
    out = _write_csv(path, cols, ["%.6f", "%.10g", "%.12g", "%.12g", "%.10g", "%d"])
    cmap: ColumnMap = {"gyro_dps": f"gyro_rad_s * {DEG_PER_RAD!r}"} if rad else {}
    return RigLog(out, cmap, {"": run.truth(_one_axis(run), epoch_s)},
                  write_mapping(out.parent, cmap) if mapping and cmap else None)


def write_imu3(path: str | Path, run: RigRun, epoch_s: float = EPOCH_S,
               mapping: bool = True) -> RigLog:
    """A 3-axis IMU on a one-axis table: time_s (epoch s), temp_c (the IMU's thermometer:
    the first axis' board), table_rate_dps (commanded, the table's own axis), gyro_<a>_dps
    per axis, temp_<a>_c (each gyro's own board thermometer), valid. The map gives each
    axis its table share (table_rate_<a>_dps = table_rate_dps * cosine) and earth rate."""
    names = list(run.axes)
    first = run.axes[names[0]]
    cols: dict[str, np.ndarray] = {"time_s": run.stamp_s + epoch_s, "temp_c": first.temp_c,
                                   "table_rate_dps": run.command_dps}
    cols.update({f"gyro_{a}_dps": run.axes[a].gyro_dps for a in names})
    cols.update({f"temp_{a}_c": run.axes[a].temp_c for a in names})
    cols["valid"] = run.measures
    fmts = ["%.6f", "%.10g", "%.12g", *["%.12g"] * len(names), *["%.10g"] * len(names), "%d"]
    out = _write_csv(path, cols, fmts)
    cmap: ColumnMap = {}
    for a in names:
        cmap[f"table_rate_{a}_dps"] = f"table_rate_dps * {run.axes[a].cosine!r}"
    for a in names:
        cmap[f"earth_rate_{a}_dps"] = earth_map_dps(run.protocol.latitude_deg,
                                                    run.axes[a].cosine)
    truth = {a: run.truth(a, epoch_s) for a in names}
    return RigLog(out, cmap, truth, write_mapping(out.parent, cmap) if mapping else None)


def write_truth(path: str | Path, truth: Truth) -> Path:
    """One axis' truth as CSV (for benches; keep it out of a folder of logs)."""
    cols = truth.columns()
    fmts = ["%.6f", *["%.12g"] * (len(cols) - 2), "%d"]
    return _write_csv(path, cols, fmts)


def _one_axis(run: RigRun) -> str:
    if len(run.axes) != 1:
        raise ValueError(f"this writer takes a one-axis run, got axes {', '.join(run.axes)}")
    return next(iter(run.axes))


# --- truth per plateau and per +/- pair (for benches) ------------------------------------

@dataclass(frozen=True)
class Plateau:
    """Samples [start, stop) at one commanded rate, after the settle margin, and the
    truth's means over them."""

    start: int
    stop: int
    rate_dps: float  # commanded
    sf_ppm: float
    bias_dph: float
    temp_c: float  # the log's thermometer


def plateaus(run: RigRun, axis: str = "", settle_s: float = 2.0, min_s: float = 5.0
             ) -> list[Plateau]:
    """The log's plateaus of non-zero commanded rate that measure (enabled, no stall) for
    at least min_s after settle_s; a stall ends a plateau."""
    ax, dt = run.axes[axis], run.protocol.dt_s
    key = np.where(run.measures, run.command_dps, 0.0)
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [key.shape[0]]])
    skip, need = int(round(settle_s / dt)), int(round(min_s / dt))
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        rate = float(key[a])
        # a stall's recovery rows are flagged: settle only after a commanded change
        start = a + (skip if a == 0 or run.command_dps[a - 1] != rate else 0)
        if rate == 0.0 or b - start < need:
            continue
        out.append(Plateau(int(start), int(b), rate, float(ax.result.sf_ppm[start:b].mean()),
                           float(ax.result.bias_dps[start:b].mean() * 3600.0),
                           float(ax.temp_c[start:b].mean())))
    return out


@dataclass(frozen=True)
class PairTruth:
    """A +/- pair of adjacent plateaus of equal |rate| and the truth's means over both."""

    plus: Plateau
    minus: Plateau
    rate_dps: float  # |rate|
    sf_ppm: float
    bias_dph: float
    temp_c: float


def pairs(plats: Sequence[Plateau]) -> list[PairTruth]:
    """Adjacent plateaus of equal |rate| and opposite sign, each used once, in order."""
    out, i = [], 0
    while i + 1 < len(plats):
        p, q = plats[i], plats[i + 1]
        if p.rate_dps == -q.rate_dps and q.start - p.stop <= p.stop - p.start:
            plus, minus = (p, q) if p.rate_dps > 0 else (q, p)
            n1, n2 = p.stop - p.start, q.stop - q.start
            w = (n1, n2)
            out.append(PairTruth(plus, minus, abs(p.rate_dps),
                                 float(np.average([p.sf_ppm, q.sf_ppm], weights=w)),
                                 float(np.average([p.bias_dph, q.bias_dph], weights=w)),
                                 float(np.average([p.temp_c, q.temp_c], weights=w))))
            i += 2
        else:
            i += 1
    return out


# --- one call: a protocol's log in a rig's convention ------------------------------------

PROTOCOLS = {"reversals": reversal_protocol, "staircase": staircase_protocol,
             "stationary": stationary_protocol}
RIG_KINDS = ("ros", "plain", "imu3")


def rig_log(kind: str, path: str | Path, protocol: RigProtocol | str = "reversals",
            gyro_seeds: Sequence[int] = (0,), seed: int = 0, **kw: Any) -> RigLog:
    """Run `protocol` (a RigProtocol or a name in PROTOCOLS, built with `kw`) on the
    population's gyro(s) and write the log the way rig `kind` writes it: "ros" and "plain"
    take one gyro seed, "imu3" three (x, y, z, skew-mounted at SKEW_COSINE)."""
    if kind not in RIG_KINDS:
        raise UserError(f"rig kind must be one of {', '.join(RIG_KINDS)}, got {kind!r}")
    if isinstance(protocol, str):
        if protocol not in PROTOCOLS:
            raise UserError(f"protocol must be one of {', '.join(PROTOCOLS)}, got "
                            f"{protocol!r}")
        protocol = PROTOCOLS[protocol](**kw)
    want = 3 if kind == "imu3" else 1
    if len(gyro_seeds) != want:
        raise UserError(f"rig {kind!r} takes {want} gyro seed(s), got {len(gyro_seeds)}")
    if kind == "imu3":
        return write_imu3(path, run_imu3(protocol, gyro_seeds, seed))
    run = run_rig(protocol, gyro_seeds[0], seed)
    return write_ros(path, run) if kind == "ros" else write_plain(path, run, mapping=True)


# --- bench cases: a training and a held-out test log per rig --------------------------------

@dataclass(frozen=True)
class BenchCase:
    """A rig convention with a training protocol and a held-out test protocol (another
    chamber path, another noise seed), as `make bench-rigs` runs them."""

    kind: str  # one of RIG_KINDS
    train: RigProtocol
    test: RigProtocol
    note: str


QUIET_ARW = 0.01  # deg/sqrt(h): 0.055 deg/h (1 sigma) on the mean of a 60 s + 60 s pair


def bench_cases(rate_hz: float = 10.0) -> dict[str, BenchCase]:
    """The issue-18 conventions, each trained on one protocol and tested on another:

    ros-staircase: ROS log, staircase at 5 set points with stalls and time stamps jittered
    by 2 % of a sample; test at 4 other set points.
    plain-reversals: plain rad/s log, +/-100 deg/s 60 s over a -20 -> 50 -> -20 C loop at
    1 C/min up, 0.7 C/min down (20 min soaks); test the loop at 0.8 up, 0.9 down (rates
    inside the training range: the rig is scored, not the rate transfer of docs/train.md).
    imu3-reversals: the same on a skew IMU; imu3-earth: with the horizontal earth rate
    turning with the table. ros-bias: the
    reversals in the ROS convention with stalls and a quiet gyro (QUIET_ARW: the population's
    0.03-0.08 deg/sqrt(h) alone puts 0.16-0.44 deg/h (1 sigma) on a 60 s + 60 s pair).
    thermometer-1c / -0.25c: the plain reversals with a thermometer of 1 C / 0.25 C steps.
    """
    up = loop(-20.0, 50.0, 1.0, 0.7)
    down = loop(-20.0, 50.0, 0.8, 0.9)
    steps = staircase()
    hold = 2 * schedule_s(steps)
    stairs = staircase_protocol(chamber=bang_bang(hold_s=hold), rate_hz=rate_hz,
                                stalls_per_h=6.0, stamp_jitter_s=0.02 / rate_hz)
    stairs_test = replace(stairs, chamber=bang_bang((-10.0, 10.0, 30.0, 50.0), hold_s=hold))
    rev, rev_test = (reversal_protocol(chamber=c, rate_hz=rate_hz) for c in (up, down))
    ros_quiet: dict[str, Any] = {"arw_deg_per_sqrt_h": QUIET_ARW, "stalls_per_h": 6.0,
                                 "stamp_jitter_s": 0.02 / rate_hz}
    cases = {
        "ros-staircase": BenchCase("ros", stairs, stairs_test,
                                   "staircase 0..100 deg/s both ways, 5 -> 4 set points"),
        "plain-reversals": BenchCase("plain", rev, rev_test,
                                     "+/-100 deg/s 60 s, loop 1/0.7 C/min -> 0.8/0.9 C/min"),
        "imu3-reversals": BenchCase("imu3", rev, rev_test,
                                    "skew 3-axis IMU, reversals, loop -> another loop"),
        "ros-bias": BenchCase("ros", replace(rev, **ros_quiet), replace(rev_test, **ros_quiet),
                              f"ROS log, reversals, ARW {QUIET_ARW:g} deg/sqrt(h): bias per "
                              "pair to 0.1 deg/h is above the noise"),
        "imu3-earth": BenchCase("imu3", replace(rev, rotating_earth=True),
                                replace(rev_test, rotating_earth=True),
                                "the same with the horizontal earth rate turning with the "
                                "table"),
    }
    for lsb, name in ((1.0, "1c"), (0.25, "0.25c")):
        cases[f"thermometer-{name}"] = BenchCase(
            "plain", replace(rev, temp_lsb_c=lsb), replace(rev_test, temp_lsb_c=lsb),
            f"reversals with a thermometer of {lsb:g} C steps")
    return cases


def write_case(folder: str | Path, case: BenchCase, gyro_seeds: Sequence[int], seed: int
               ) -> tuple[RigLog, RigLog]:
    """The case's training log in folder/train and its test log in folder/test (each with
    its column map), noise seeds `seed` and `seed + 1`."""
    folder = Path(folder)
    name = {"ros": "ros.csv", "plain": "plain.csv", "imu3": "imu.csv"}[case.kind]
    train = rig_log(case.kind, folder / "train" / name, case.train, gyro_seeds, seed)
    test = rig_log(case.kind, folder / "test" / name, case.test, gyro_seeds, seed + 1)
    return train, test
