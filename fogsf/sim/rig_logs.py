"""Rig logs written the way rigs write them, and the cases the benches run on them
(docs/simulate.md, "Rig protocols"): `write_ros`, `write_plain` and `write_imu3` write a
`RigRun` (`sim.rigs`) as that rig's CSV with the column map a user would write beside it
(our name -> the log's column, an expression over columns, or a number) and return a
`RigLog` with the per-axis `Truth`; `plateaus` and `pairs` give the truth per plateau and
per +/- pair; `rig_log` runs and writes in one call; `bench_cases` and `write_case` are the
training and held-out test logs of `make bench-rigs`. The same inputs give the same bytes.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.dialect import MAPPING_FILES
from fogsf.logs.logio import write_rows
from fogsf.sim.rigs import (
    DEG_PER_RAD,
    EPOCH_S,
    STEPS_PER_REV,
    RigProtocol,
    RigRun,
    Truth,
    bang_bang,
    earth_map_dps,
    loop,
    reversal_protocol,
    run_imu3,
    run_rig,
    schedule_s,
    staircase,
    staircase_protocol,
    stationary_protocol,
)

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
    ros-stationary: the table stopped through the same loops (the autopilots' soak and
    warm-up), a 0.25 C thermometer: the bias alone.
    Every gyro has its own thermal bias from the population (`thermal_bias`: its coil, a
    Shupe term, a quadratic and a cubic).
    """
    up = loop(-20.0, 50.0, 1.0, 0.7)
    down = loop(-20.0, 50.0, 0.8, 0.9)
    steps = staircase()
    hold = 2 * schedule_s(steps)
    own: dict[str, Any] = {"bias": None, "thermal_bias": True}
    stairs = staircase_protocol(chamber=bang_bang(hold_s=hold), rate_hz=rate_hz,
                                stalls_per_h=6.0, stamp_jitter_s=0.02 / rate_hz, **own)
    stairs_test = replace(stairs, chamber=bang_bang((-10.0, 10.0, 30.0, 50.0), hold_s=hold))
    rev, rev_test = (reversal_protocol(chamber=c, rate_hz=rate_hz, **own) for c in (up, down))
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
    still, still_test = (stationary_protocol(chamber=c, rate_hz=rate_hz, temp_lsb_c=0.25,
                                             stamp_jitter_s=0.02 / rate_hz, **own)
                         for c in (up, down))
    cases["ros-stationary"] = BenchCase(
        "ros", still, still_test, "ROS log, the table stopped through the loop (soak and "
        "warm-up), 0.25 C thermometer: a bias-only model")
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


# --- raw logger output: several files on their own clocks ----------------------------------

WALL_EPOCH_S = 1_772_612_100.0  # 2026-03-04T08:15:00Z: the chamber logger's wall clock
WRAP_US = 2**32  # a 32-bit microsecond counter wraps every 4294.967296 s


def iso_stamps(epoch_s: np.ndarray) -> list[str]:
    """Epoch seconds as ISO-8601 text to the millisecond, UTC without an offset
    (`2026-03-04T09:15:02.123`), as chamber loggers write wall-clock time."""
    ms = np.round(np.asarray(epoch_s) * 1e3).astype(np.int64).astype("datetime64[ms]")
    return list(np.datetime_as_string(ms, unit="ms"))


def _write_text_csv(path: Path, names: list[str], cols: list[list[str]]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(",".join(names) + "\n")
        f.writelines(",".join(row) + "\n" for row in zip(*cols, strict=True))
    return path


def write_loggers(path: str | Path, run: RigRun, seed: int = 0, thermo_hz: float = 1.0,
                  dropout_s: float = 30.0, boot_s: float | None = None,
                  duplicates: int = 3, max_gap_s: float = 5.0) -> RigLog:
    """A run as two loggers and a table controller write it, each on its own clock:

    `path` (the IMU): t_us, a 32-bit microsecond counter since the IMU booted (`boot_s`
    before the run; by default so that it wraps in the run's first half), rate_z (rad/s),
    header.frame_id (text), with `duplicates` rows written twice; `{stem}.thermo.csv`:
    wall (ISO-8601, UTC), board_T, chamber_T at `thermo_hz`, with a dropout of `dropout_s`
    (no rows) at a seeded time; `{stem}.table.csv`: wall, cmd_dps, one row per command
    change. The map beside them joins both onto the IMU's clock (time_s = unwrap(t_us,
    2**32) * 1e-6 + the boot's wall time). The truth is on that clock (epoch seconds)."""
    ax = run.axes[_one_axis(run)]
    out = Path(path)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x10661]))
    n = run.stamp_s.shape[0]
    if boot_s is None:  # the counter's first wrap a third to two thirds into the run
        boot_s = WRAP_US * 1e-6 - (run.stamp_s[-1] * float(rng.uniform(0.3, 0.6))) % (
            WRAP_US * 1e-6)
    boot_wall = float(WALL_EPOCH_S - boot_s)  # the wall time of the IMU's boot
    t_us = np.round((run.stamp_s + boot_s) * 1e6).astype(np.int64) % WRAP_US
    rows = np.arange(n)
    if duplicates:
        dup = np.sort(rng.choice(np.arange(1, n), size=min(duplicates, n - 1), replace=False))
        rows = np.sort(np.concatenate([rows, dup]))
    rate = ax.gyro_dps / DEG_PER_RAD
    _write_text_csv(out, ["t_us", "rate_z", "header.frame_id"],
                    [[str(int(v)) for v in t_us[rows]], [f"{v:.12g}" for v in rate[rows]],
                     ["imu_link"] * rows.size])
    wall = WALL_EPOCH_S + run.stamp_s  # the run's samples on the wall clock
    step = max(1, int(round(run.protocol.rate_hz / thermo_hz)))
    th = np.arange(0, n, step)
    if dropout_s > 0:
        d0 = float(rng.uniform(0.2, 0.7)) * run.stamp_s[-1]
        th = th[(run.stamp_s[th] < d0) | (run.stamp_s[th] >= d0 + dropout_s)]
    chamber = ax.result.log.extra.get("chamber_c", ax.temp_c)
    _write_text_csv(out.with_name(f"{out.stem}.thermo.csv"), ["wall", "board_T", "chamber_T"],
                    [iso_stamps(wall[th]), [f"{v:.4f}" for v in ax.temp_c[th]],
                     [f"{v:.3f}" for v in chamber[th]]])
    _table_events(out.with_name(f"{out.stem}.table.csv"), run, wall)
    cmap: ColumnMap = {
        "time_s": f"unwrap(t_us, 2**32) * 1e-6 + {boot_wall!r}",
        "gyro_dps": f"rate_z * {DEG_PER_RAD!r}",
        "earth_rate_dps": earth_map_dps(run.protocol.latitude_deg, ax.cosine),
    }
    joins = {"thermo": {"file": "{stem}.thermo.csv", "time_s": "wall", "temp_c": "board_T",
                        "chamber_c": "chamber_T", "how": "interpolate",
                        "max_gap_s": max_gap_s},
             "table": {"file": "{stem}.table.csv", "time_s": "wall",
                       "table_rate_dps": "cmd_dps", "how": "hold"}}
    return RigLog(out, cmap, {"": run.truth(_one_axis(run), WALL_EPOCH_S)},
                  _write_map(out.parent, cmap, joins))


def _table_events(path: Path, run: RigRun, wall: np.ndarray) -> Path:
    change = np.flatnonzero(np.diff(run.command_dps, prepend=np.nan) != 0)
    return _write_text_csv(path, ["wall", "cmd_dps"],
                           [iso_stamps(wall[change]),
                            [f"{v:.6g}" for v in run.command_dps[change]]])


def write_px4(path: str | Path, run: RigRun, seed: int = 0, jitter: float = 0.15,
              drops_per_1000: float = 2.0) -> RigLog:
    """A PX4-style `sensor_gyro` export of a run: timestamp (us since boot, the samples'
    stamps jittered by +/- `jitter` of a sample, uniform), device_id, x, y, z (rad/s: the
    run's gyro on z, the others its noise), temperature (C); `drops_per_1000` samples in a
    thousand dropped (one or two in a row); the table controller's commands beside it
    (`{stem}.table.csv`, ISO wall time), joined by the map."""
    ax = run.axes[_one_axis(run)]
    out = Path(path)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x9E4]))
    n = run.stamp_s.shape[0]
    dt = run.protocol.dt_s
    boot_s = float(rng.uniform(30.0, 600.0))
    stamp = run.stamp_s + rng.uniform(-jitter, jitter, n) * dt
    keep = np.ones(n, dtype=bool)
    k = int(round(n * drops_per_1000 / 1000.0))
    at = rng.choice(np.arange(1, n - 2), size=k, replace=False)
    keep[at] = False
    keep[at[rng.random(k) < 0.3] + 1] = False  # some drop two in a row
    rows = np.flatnonzero(keep)
    t_us = np.round((stamp + boot_s) * 1e6).astype(np.int64)
    rate = ax.gyro_dps / DEG_PER_RAD
    other = rng.normal(0.0, 1e-4, (2, n))
    _write_text_csv(out, ["timestamp", "device_id", "x", "y", "z", "temperature"],
                    [[str(int(v)) for v in t_us[rows]], ["2293768"] * rows.size,
                     [f"{v:.9g}" for v in other[0, rows]], [f"{v:.9g}" for v in other[1, rows]],
                     [f"{v:.12g}" for v in rate[rows]], [f"{v:.4f}" for v in ax.temp_c[rows]]])
    boot_wall = float(WALL_EPOCH_S - boot_s)
    _table_events(out.with_name(f"{out.stem}.table.csv"), run, WALL_EPOCH_S + run.stamp_s)
    cmap: ColumnMap = {"time_s": f"timestamp * 1e-6 + {boot_wall!r}",
                       "gyro_dps": f"z * {DEG_PER_RAD!r}", "temp_c": "temperature",
                       "earth_rate_dps": earth_map_dps(run.protocol.latitude_deg, ax.cosine)}
    joins = {"table": {"file": "{stem}.table.csv", "time_s": "wall",
                       "table_rate_dps": "cmd_dps", "how": "hold"}}
    truth = run.truth(_one_axis(run), WALL_EPOCH_S)
    truth = Truth(*(getattr(truth, f)[rows] if isinstance(getattr(truth, f), np.ndarray)
                    and getattr(truth, f).shape == (n,) else getattr(truth, f)
                    for f in Truth.__dataclass_fields__))
    truth.time_s = boot_wall + t_us[rows] * 1e-6
    return RigLog(out, cmap, {"": truth}, _write_map(out.parent, cmap, joins))


def _write_map(folder: Path, cmap: ColumnMap, joins: dict[str, dict[str, Any]]) -> Path:
    text = "".join(f"{k} = {json.dumps(v)}\n" for k, v in cmap.items())
    for name, table in joins.items():
        text += f"\n[join.{name}]\n" + "".join(f"{k} = {json.dumps(v)}\n"
                                                for k, v in table.items())
    path = folder / "fogsf-columns.toml"
    path.write_text(text, encoding="utf-8")
    return path


def write_bursts(path: str | Path, run: RigRun, burst_s: float = 5.0,
                 every_s: float = 300.0) -> RigLog:
    """A burst logger's file of a stationary run: `burst_s` of samples every `every_s`
    (a thermal-vacuum chamber's data logger), time (epoch s), temp (C), rate (deg/s); the
    map gives the stopped table and the earth rate. Rows between bursts are not written."""
    ax = run.axes[_one_axis(run)]
    t = run.stamp_s
    keep = np.mod(t - t[0] + 1e-9, every_s) < burst_s - 1e-9
    cols = {"time": EPOCH_S + t[keep], "temp": ax.temp_c[keep], "rate": ax.gyro_dps[keep]}
    out = _write_csv(path, cols, ["%.6f", "%.10g", "%.12g"])
    cmap: ColumnMap = {"time_s": "time", "temp_c": "temp", "gyro_dps": "rate",
                       "table_rate_dps": 0,
                       "earth_rate_dps": earth_map_dps(run.protocol.latitude_deg, ax.cosine)}
    truth = run.truth(_one_axis(run), EPOCH_S)
    return RigLog(out, cmap, {"": truth}, write_mapping(out.parent, cmap))


def write_ros2_export(path: str | Path, run: RigRun, thermo_hz: float = 1.0) -> RigLog:
    """A ROS 2 bag exported to CSV, a file per topic: `path` (/imu: header.stamp.sec,
    header.stamp.nanosec, header.frame_id, angular_velocity.x/.y/.z in rad/s),
    `{stem}.board_temperature.csv` (/board_temperature at `thermo_hz`: the stamp,
    header.frame_id, temperature) and `{stem}.table.csv` (/table/cmd on each change: the
    stamp, data in deg/s); the map joins both topics onto /imu's stamps."""
    ax = run.axes[_one_axis(run)]
    out = Path(path)
    ns = np.int64(round(WALL_EPOCH_S * 1e9)) + np.round(run.stamp_s * 1e9).astype(np.int64)
    sec, nsec = ns // 1_000_000_000, ns % 1_000_000_000

    def stamp(rows: np.ndarray) -> list[list[str]]:
        return [[str(int(v)) for v in sec[rows]], [str(int(v)) for v in nsec[rows]]]

    head = ["header.stamp.sec", "header.stamp.nanosec", "header.frame_id"]
    rows = np.arange(run.stamp_s.shape[0])
    rate = ax.gyro_dps / DEG_PER_RAD
    _write_text_csv(out, [*head, "angular_velocity.x", "angular_velocity.y",
                          "angular_velocity.z"],
                    [*stamp(rows), ["imu_link"] * rows.size, ["0"] * rows.size,
                     ["0"] * rows.size, [f"{v:.12g}" for v in rate]])
    th = np.arange(0, rows.size, max(1, int(round(run.protocol.rate_hz / thermo_hz))))
    _write_text_csv(out.with_name(f"{out.stem}.board_temperature.csv"), [*head, "temperature"],
                    [*stamp(th), ["board"] * th.size, [f"{v:.4f}" for v in ax.temp_c[th]]])
    change = np.flatnonzero(np.diff(run.command_dps, prepend=np.nan) != 0)
    _write_text_csv(out.with_name(f"{out.stem}.table.csv"), [*head[:2], "data"],
                    [*stamp(change), [f"{v:.6g}" for v in run.command_dps[change]]])
    when = "`header.stamp.sec` + `header.stamp.nanosec` * 1e-9"
    cmap: ColumnMap = {"time_s": when, "gyro_dps": f"`angular_velocity.z` * {DEG_PER_RAD!r}",
                       "earth_rate_dps": earth_map_dps(run.protocol.latitude_deg, ax.cosine)}
    joins = {"board": {"file": "{stem}.board_temperature.csv", "time_s": when,
                       "temp_c": "temperature", "how": "interpolate", "max_gap_s": 5.0},
             "table": {"file": "{stem}.table.csv", "time_s": when,
                       "table_rate_dps": "data", "how": "hold"}}
    return RigLog(out, cmap, {"": run.truth(_one_axis(run), WALL_EPOCH_S)},
                  _write_map(out.parent, cmap, joins))
