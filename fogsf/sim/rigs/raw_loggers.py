"""Raw logger output of a rig run (docs/logs.md, "Raw logger output"): `write_loggers` (an IMU
on a wrapping microsecond counter, a chamber logger on ISO wall time with a dropout, a table
controller's commands as events), `write_px4` (a PX4 `sensor_gyro` export with jittered
stamps and dropped samples), `write_bursts` (a burst logger's file) and `write_ros2_export` (a
ROS 2 bag exported a file per topic): several files on their own clocks, each with the column
map that joins them, and the truth on the joined clock.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from fogsf.sim.rigs.protocols import RigRun, Truth, earth_map_dps
from fogsf.sim.rigs.rig_logs import (
    DEG_PER_RAD,
    EPOCH_S,
    ColumnMap,
    RigLog,
    _one_axis,
    write_csv,
    write_mapping,
)

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
    joins: dict[str, dict[str, str | float]] = {
        "thermo": {"file": "{stem}.thermo.csv", "time_s": "wall", "temp_c": "board_T",
                   "chamber_c": "chamber_T", "how": "interpolate", "max_gap_s": max_gap_s},
        "table": {"file": "{stem}.table.csv", "time_s": "wall", "table_rate_dps": "cmd_dps",
                  "how": "hold"}}
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


def _write_map(folder: Path, cmap: ColumnMap, joins: Mapping[str, Mapping[str, str | float]]
               ) -> Path:
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
    out = write_csv(path, cols, ["%.6f", "%.10g", "%.12g"])
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
    joins: dict[str, dict[str, str | float]] = {
        "board": {"file": "{stem}.board_temperature.csv", "time_s": when,
                  "temp_c": "temperature", "how": "interpolate", "max_gap_s": 5.0},
        "table": {"file": "{stem}.table.csv", "time_s": when,
                  "table_rate_dps": "data", "how": "hold"}}
    return RigLog(out, cmap, {"": run.truth(_one_axis(run), WALL_EPOCH_S)},
                  _write_map(out.parent, cmap, joins))
