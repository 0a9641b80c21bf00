"""Calibration rigs as people build them, with the truth behind every sample (docs/simulate.md,
"Rig protocols").

A `RigProtocol` is a chamber program (`Chamber`, `sim.rigs.chambers`: bang-bang set points or a
ramp, with the intervals where the table is stopped while the heater settles) and a commanded
table schedule (`Step`s, `sim.rigs.schedules`: IEEE 952 +/- reversals, a rate staircase in
both directions), played on a table with a finite acceleration (`slew`) and occasional stalls
(the stepper skipped: the table turned slower than commanded, flagged). `run_rig` /
`run_imu3` run one gyro, or three skew-mounted ones, through it with the simulator
(`gyro.simulate` with the actual rate the axis sees: the physics is the simulator's own) and
return a `RigRun` with the per-axis `Truth`; `sim.rigs.rig_logs` writes it as rigs write
their logs. The same protocol, gyro seeds and seed give the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import EARTH_RATE_DPS, RATE_RANGE_HZ
from fogsf.sim.config import BiasConfig, ProfileConfig, SimConfig, TableConfig
from fogsf.sim.effects import EffectConfig
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.population import gyro_for_seed, with_gyro
from fogsf.sim.profiles import chamber_series
from fogsf.sim.rigs.chambers import Chamber, bang_bang, loop, ramp
from fogsf.sim.rigs.schedules import (
    Step,
    command_series,
    reversals,
    schedule_s,
    slew,
    staircase,
    stall_target,
)

SKEW_COSINE = 1.0 / math.sqrt(3.0)  # an axis at 54.7356 deg to the table axis
AXES = ("x", "y", "z")
LATITUDE_DEG = 34.26


# --- protocols and runs --------------------------------------------------------------------

@dataclass
class RigProtocol:
    """What a rig does: the chamber program, the commanded table schedule and how the
    table and the thermometer behave.

    accel_dps2: the table's acceleration (0: at each command at once); stalls_per_h:
    stalls an hour, each stall_s long, the table at stall_share of the command;
    temp_lsb_c: the thermometer's step (1, 0.25 or 0.0625 C); bias: the gyros' bias law
    (None: each gyro's own, from the population); thermal_bias: with bias None, each gyro's
    own thermal bias from the population (its coil, a Shupe term, a quadratic and a cubic:
    `population.with_thermal_bias`); arw_deg_per_sqrt_h: the gyros' angle
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
    thermal_bias: bool = False
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
                     self.command_dps, self.table_dps * ax.cosine, r.log.earth(),
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
    cfg = with_gyro(run, gyro_for_seed(gyro_seed, thermal_bias=p.thermal_bias))
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
        (p.bias is None or not p.thermal_bias,
         "thermal_bias draws each gyro's own bias: give bias=None with it"),
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
