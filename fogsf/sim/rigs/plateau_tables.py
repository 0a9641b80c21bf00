"""Plateau tables, as a rate-table rig's DAQ software writes them (docs/simulate.md, "Plateau
tables"): one row per rate plateau with the mean gyro output, the commanded rate, the mean
board temperature, the plateau's start time and its duration; no samples.

The rig: a heated box holding set points (default 36, 43, 50, 57 C, a bang-bang heater
swinging +/- `swing_c`), the table stopped while the box ramps and soaks at each; then at
each set point `passes` rate staircases 0, +dw ... +max, 0, -dw ... -max (dw = max /
rate_steps), `plateau_s` a plateau. The gyro is simulated sample by sample (`gyro.simulate`
with the table's actual rate: it follows each command from rest at `accel_dps2`), and each
row is the mean of the simulated samples over its plateau after `settle_s`, so the noise
averages down as it does on a real rig. The same configuration and plan give the same bytes.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.read.dialect import MAPPING_FILES
from fogsf.sim.config import ProfileConfig, SimConfig, TableConfig
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.profiles import chamber_series
from fogsf.sim.rigs.chambers import Chamber, bang_bang
from fogsf.sim.rigs.rig_logs import write_csv
from fogsf.sim.rigs.schedules import Step, schedule_s, slew

SET_POINTS_C = (36.0, 43.0, 50.0, 57.0)  # the heated-box range of the real FOG
PLATEAU_S = (16.0, 20.0)  # what rigs of this kind dwell on a rate
COLUMNS = ("time_s", "duration_s", "table_rate_dps", "gyro_dps", "temp_c")
FORMATS = ("%.3f", "%.3f", "%.10g", "%.12g", "%.6f")
TRUTH_COLUMNS = ("time_s", "true_sf_ppm", "true_bias_dph", "ideal_dps", "true_board_c")


@dataclass(frozen=True)
class PlateauPlan:
    """The rig's program. set_points_c: the box's set points, in order; max_rate_dps and
    rate_steps: the staircase's top and its number of steps each way; plateau_s: a plateau's
    length; passes: staircases at each set point; soak_s: the table stopped while the box
    settles at a set point (after a ramp at ramp_c_per_min); settle_s: the start of each
    plateau the mean leaves out (the table accelerating: 0.5 s to 150 deg/s at 300 deg/s^2);
    swing_c: the heater's swing about a set point."""

    set_points_c: tuple[float, ...] = SET_POINTS_C
    max_rate_dps: float = 150.0
    rate_steps: int = 5
    plateau_s: float = 18.0
    passes: int = 2
    soak_s: float = 1200.0
    ramp_c_per_min: float = 1.0
    settle_s: float = 2.0
    accel_dps2: float = 300.0
    swing_c: float = 0.5


def plan_from(**given: float | int | list[float] | None) -> PlateauPlan:
    """A plan from the fields given, None (an option not given) leaving the default."""
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in given.items()
          if v is not None}
    try:
        return PlateauPlan(**kw)  # type: ignore[arg-type]
    except TypeError as e:
        raise UserError(f"plateau plan: {e}") from None


def check_plan(p: PlateauPlan, dt_s: float) -> None:
    """Refuse a plan that cannot be played (UserError naming the field and the rule)."""
    rules = [
        (len(p.set_points_c) >= 1 and all(math.isfinite(c) for c in p.set_points_c),
         "set_points_c: give at least one temperature"),
        (math.isfinite(p.max_rate_dps) and p.max_rate_dps > 0,
         f"max_rate_dps must be > 0, got {p.max_rate_dps!r}"),
        (1 <= p.rate_steps <= 100, f"rate_steps must lie in 1..100, got {p.rate_steps!r}"),
        (p.passes >= 1, f"passes must be >= 1, got {p.passes!r}"),
        # a plateau shorter than a few samples after its settle has no mean worth a row
        (p.plateau_s >= p.settle_s + 5 * dt_s,
         f"plateau_s ({p.plateau_s:g}) must exceed settle_s ({p.settle_s:g}) by 5 samples"),
        (p.settle_s >= 0 and p.soak_s >= 0 and p.accel_dps2 >= 0 and p.swing_c >= 0,
         "settle_s, soak_s, accel_dps2 and swing_c must be >= 0"),
        (p.ramp_c_per_min > 0, f"ramp_c_per_min must be > 0, got {p.ramp_c_per_min!r}"),
    ]
    for ok, message in rules:
        if not ok:
            raise UserError(f"plateau plan: {message}")


def rate_schedule(p: PlateauPlan) -> list[Step]:
    """One staircase: 0, +dw ... +max, 0, -dw ... -max, plateau_s each."""
    dw = p.max_rate_dps / p.rate_steps
    up = [Step(k * dw, p.plateau_s) for k in range(1, p.rate_steps + 1)]
    down = [Step(-s.rate_dps, p.plateau_s) for s in up]
    return [Step(0.0, p.plateau_s), *up, Step(0.0, p.plateau_s), *down]


def chamber(p: PlateauPlan) -> Chamber:
    """The box: each set point soaked soak_s (table stopped), then held for the staircases."""
    hold = p.passes * schedule_s(rate_schedule(p))
    return bang_bang(p.set_points_c, hold_s=hold, settle_s=p.soak_s,
                     ramp_c_per_min=p.ramp_c_per_min, swing_c=p.swing_c)


def plateau_config(cfg: SimConfig, p: PlateauPlan) -> SimConfig:
    """`cfg`'s gyro, noise, effects and seed on the plan's chamber program (a new config; its
    table schedule is unused: the plan's actual rate is given to `simulate`)."""
    out = copy.deepcopy(cfg)
    out.profile = ProfileConfig(kind="program", points=chamber(p).points)
    out.table = TableConfig(kind="constant", rate_dps=1.0)
    return out


@dataclass
class PlateauRun:
    """A plan played: the simulated samples, the commanded and actual rate per sample, and
    each plateau's samples [start, stop) and the first sample of its mean (start + settle)."""

    plan: PlateauPlan
    result: SimResult
    command_dps: np.ndarray
    table_dps: np.ndarray
    start: np.ndarray
    mean_from: np.ndarray
    stop: np.ndarray


def _plateaus(p: PlateauPlan, box: Chamber, t_s: np.ndarray, dt_s: float
              ) -> tuple[np.ndarray, list[tuple[int, int, float]]]:
    """(commanded rate per sample, [(start, stop, rate)] of every whole plateau)."""
    steps = rate_schedule(p)
    n = max(1, int(round(p.plateau_s / dt_s)))  # whole samples: plateaus are exact
    enabled = np.ones(t_s.shape[0], dtype=bool)
    for a, b in box.stopped:
        enabled &= ~((t_s >= a - 1e-9) & (t_s < b - 1e-9))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], enabled.astype(np.int8), [0]])))
    command = np.zeros(t_s.shape[0])
    plats: list[tuple[int, int, float]] = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        # each running stretch starts the staircase from its first step; a cut one is no row
        for k in range((b - a) // n):
            rate = steps[k % len(steps)].rate_dps
            command[a + k * n:a + (k + 1) * n] = rate
            plats.append((int(a + k * n), int(a + (k + 1) * n), rate))
    return command, plats


def run_plateaus(cfg: SimConfig, p: PlateauPlan = PlateauPlan()) -> PlateauRun:
    """Simulate `cfg`'s gyro through the plan, sample by sample."""
    check_plan(p, cfg.dt_s)
    run = plateau_config(cfg, p)
    box = chamber(p)
    t, _ = chamber_series(run.profile, run.dt_s)
    command, plats = _plateaus(p, box, t, run.dt_s)
    if not plats:
        raise UserError("plateau plan: no whole plateau fits the program")
    actual = slew(command, run.dt_s, p.accel_dps2)
    result = simulate(run, table_dps=actual)
    skip = int(round(p.settle_s / run.dt_s))
    start = np.array([a for a, _, _ in plats])
    stop = np.array([b for _, b, _ in plats])
    return PlateauRun(p, result, command, actual, start, start + skip, stop)


@dataclass
class PlateauTable:
    """One row per plateau: COLUMNS, the earth rate on the axis (one number, the column map
    gives it), and the truth per plateau (TRUTH_COLUMNS: the means over the same samples)."""

    columns: dict[str, np.ndarray]
    earth_rate_dps: float
    truth: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.columns["time_s"].shape[0])


def _means(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean of x over each [a_i, b_i) (cumulative sums would round differently per row)."""
    return np.array([float(np.mean(x[i:j])) for i, j in zip(a, b, strict=True)])


def plateau_table(run: PlateauRun) -> PlateauTable:
    """The run as its DAQ writes it: time_s the plateau's start (its commanded change),
    duration_s its length, table_rate_dps the command, gyro_dps and temp_c the means of the
    samples from mean_from to the plateau's end."""
    r, a, b = run.result, run.mean_from, run.stop
    log = r.log
    cols = {"time_s": log.time_s[run.start], "duration_s": (run.stop - run.start) * r.config.dt_s,
            "table_rate_dps": run.command_dps[run.start], "gyro_dps": _means(log.gyro_dps, a, b),
            "temp_c": _means(log.temp_c, a, b)}
    truth = {"time_s": cols["time_s"], "true_sf_ppm": _means(r.sf_ppm, a, b),
             "true_bias_dph": _means(r.bias_dps * 3600.0, a, b),
             "ideal_dps": _means(r.ideal_dps, a, b),
             "true_board_c": _means(r.nodes[r.config.thermal.board_node], a, b)}
    earth = np.asarray(log.earth_rate_dps, dtype=np.float64)
    return PlateauTable(cols, float(earth.flat[0]), truth)


def mapping_text(table: PlateauTable) -> str:
    """fogsf-columns.toml for the table: the layout, which instant time_s gives (a plateau's
    start), the earth rate (the table's columns have the format's names: no rename)."""
    return ("# a plateau table written by fogsf simulate --plateaus: one row per rate "
            "plateau\n# time_s: the plateau's start (s); duration_s: its length; gyro_dps, "
            "temp_c: means over it\n"
            f"layout = {json.dumps('plateaus')}\n"
            f"time_is = {json.dumps('start')}\n"
            f"earth_rate_dps = {json.dumps(table.earth_rate_dps)}\n")


def write_plateau_table(path: str | Path, table: PlateauTable) -> tuple[Path, Path]:
    """The table as CSV (COLUMNS) and fogsf-columns.toml beside it: (table, map)."""
    out = write_csv(Path(path), table.columns, list(FORMATS))
    toml = Path(out.parent) / next(n for n in MAPPING_FILES if n.endswith(".toml"))
    toml.write_text(mapping_text(table), encoding="utf-8")
    return out, toml


def write_plateau_truth(path: str | Path, table: PlateauTable) -> Path:
    """The truth per plateau (TRUTH_COLUMNS) as CSV; keep it out of the table's folder."""
    return write_csv(Path(path), table.truth, ["%.3f", "%.10g", "%.10g", "%.12g", "%.6f"])
