"""Rig logs written the way rigs write them (docs/simulate.md, "Rig protocols"): `write_ros`,
`write_plain` and `write_imu3` write a `RigRun` (`sim.rigs.protocols`) as that rig's CSV with
the column map a user would write beside it (our name -> the log's column, an expression over
columns, or a number) and return a `RigLog` with the per-axis `Truth`; `rig_log` runs and
writes in one call. The same inputs give the same bytes.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.read.dialect import MAPPING_FILES
from fogsf.logs.writer import write_rows
from fogsf.sim.rigs.protocols import (
    RigProtocol,
    RigRun,
    Truth,
    earth_map_dps,
    reversal_protocol,
    run_imu3,
    run_rig,
    staircase_protocol,
    stationary_protocol,
)

STEPS_PER_REV = 577803.965671  # the ROS rig's stepper steps per table revolution
EPOCH_S = 1_700_000_000.0  # where absolute time stamps start (2023-11-14)
DEG_PER_RAD = 57.29577951308232

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


def write_csv(path: str | Path, cols: dict[str, np.ndarray], fmts: list[str]) -> Path:
    """`cols` as a CSV with a header row, each column in its printf format (the rigs' writer)."""
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
    out = write_csv(path, cols, ["%d", "%d", "%.12g", "%.10g", "%.12g", "%d", "%d", "%d"])
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
            "earth_rate_dps": ax.result.log.earth(), "valid": run.measures}
    out = write_csv(path, cols, ["%.6f", "%.10g", "%.12g", "%.12g", "%.10g", "%d"])
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
    out = write_csv(path, cols, fmts)
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
    return write_csv(path, cols, fmts)


def _one_axis(run: RigRun) -> str:
    if len(run.axes) != 1:
        raise ValueError(f"this writer takes a one-axis run, got axes {', '.join(run.axes)}")
    return next(iter(run.axes))


# --- one call: a protocol's log in a rig's convention ------------------------------------

PROTOCOLS: dict[str, Callable[..., RigProtocol]] = {
    "reversals": reversal_protocol, "staircase": staircase_protocol,
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
