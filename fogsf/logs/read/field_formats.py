"""The field's log formats (docs/logs.md, "The field's formats"), an optional extra
(`pip install fogsf[rigs]`): ROS 1 bags (`.bag`), ROS 2 bags (a folder with
metadata.yaml, SQLite or MCAP storage) and MCAP files (`rosbags`), PX4 ULog (`.ulg`,
`pyulog`), LabVIEW TDMS (`.tdms`, `nptdms`).

A file of these holds several streams: a ROS topic (`/imu`), a ULog message
(`sensor_gyro`, `sensor_gyro_1` for its second instance), a TDMS group. Each stream is a
table of numeric columns: a message's fields flattened (`header.stamp.sec`,
`angular_velocity.z`; a ROS topic also has `log_time`, the bag's receive time in epoch
seconds), a ULog message's fields (`timestamp` in us, `x`, ...), a group's channels. The
column map names the main stream (`stream = "/imu"`; a file of one stream needs none) and
maps its columns as a CSV's; `[join.NAME]` tables take another stream of the same file with
`stream = "/board_temperature"` instead of `file`. Text fields are left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fogsf.errors import UserError

SUFFIXES = {".bag": "ROS 1 bag", ".mcap": "MCAP", ".ulg": "PX4 ULog", ".tdms": "TDMS",
            ".db3": "ROS 2 bag"}
EXTRA = {"ROS 1 bag": "rosbags", "ROS 2 bag": "rosbags", "MCAP": "rosbags",
         "PX4 ULog": "pyulog", "TDMS": "nptdms"}

Stream = dict[str, np.ndarray]


def format_of(path: str | Path) -> str | None:
    """The field format of `path` (a name of SUFFIXES' values), None for a CSV or Parquet."""
    p = Path(path)
    if p.is_dir() and (p / "metadata.yaml").is_file():
        return "ROS 2 bag"
    return SUFFIXES.get(p.suffix.lower())


def _need(kind: str, path: str) -> None:
    module = EXTRA[kind]
    try:
        __import__(module)
    except ImportError:
        raise UserError(f"{path}: a {kind} needs the optional package {module}: pip install "
                        "'fogsf[rigs]'") from None


_CACHE: dict[tuple[str, float], dict[str, Stream]] = {}


def streams(path: str | Path) -> dict[str, Stream]:
    """Every stream of a field-format file, each its numeric columns (float64, one length)."""
    p = Path(path)
    kind = format_of(p)
    if kind is None:
        raise UserError(f"{p}: not a field format ({', '.join(sorted(SUFFIXES))})")
    if not p.exists():
        raise UserError(f"{p}: cannot read: no such file")
    key = (str(p.resolve()), p.stat().st_mtime)
    if key not in _CACHE:
        _need(kind, str(p))
        read = {"PX4 ULog": _ulog, "TDMS": _tdms}.get(kind, _ros)
        try:
            _CACHE.clear()  # one file at a time: a bag of a day is large
            _CACHE[key] = read(p)
        except UserError:
            raise
        except Exception as e:  # noqa: BLE001 - a library's own error on a broken file
            raise UserError(f"{p}: cannot read the {kind}: {e}") from None
    return _CACHE[key]


def main_stream(path: str | Path, name: str | None, origin: str, looked: str = ""
                ) -> tuple[str, Stream]:
    """The stream the map names (`stream = ...`), or the file's only one; `looked`: where
    a map was looked for and not found, for the refusal."""
    all_ = streams(path)
    if name is None:
        if len(all_) == 1:
            return next(iter(all_.items()))
        raise UserError(f"{path}: the file holds {len(all_)} streams ({', '.join(all_)}): "
                        "name the gyro's with stream = \"...\" in the column map (a file "
                        f"beside it, or inside a ROS 2 bag's folder, docs/logs.md){looked}")
    if name not in all_:
        raise UserError(f"{path}: no stream {name!r} ({origin}); the file holds "
                        f"{', '.join(all_)}")
    return name, all_[name]


def as_table(stream: Stream) -> tuple[list[str], np.ndarray]:
    """(names, data [rows, columns]) of a stream, for the column map."""
    names = list(stream)
    return names, np.column_stack([stream[n] for n in names]) if names else np.zeros((0, 0))


def _flat(msg: object, prefix: str, out: dict[str, float]) -> None:
    """A message's numeric fields by dotted name (arrays: name[i]; text left out)."""
    if isinstance(msg, bool | int | float | np.integer | np.floating):
        out[prefix] = float(msg)
        return
    if isinstance(msg, np.ndarray):
        if msg.dtype.kind in "biuf":
            for i, v in enumerate(msg.ravel()):
                out[f"{prefix}[{i}]"] = float(v)
        return
    if isinstance(msg, list | tuple):
        for i, v in enumerate(msg):
            _flat(v, f"{prefix}[{i}]", out)
        return
    fields = getattr(msg, "__dataclass_fields__", None)
    if fields is None:
        return  # text and anything else
    for f in fields:
        if f == "__msgtype__":
            continue
        _flat(getattr(msg, f), f"{prefix}.{f}" if prefix else f, out)


def _ros(path: Path) -> dict[str, Stream]:
    from rosbags.highlevel import AnyReader

    rows: dict[str, list[dict[str, float]]] = {}
    with AnyReader([path]) as reader:
        for conn, t_ns, raw in reader.messages():
            out: dict[str, float] = {"log_time": t_ns * 1e-9}
            _flat(reader.deserialize(raw, conn.msgtype), "", out)
            rows.setdefault(conn.topic, []).append(out)
    return {topic: _columns(r, f"{path}: topic {topic}") for topic, r in rows.items()}


def _columns(rows: list[dict[str, float]], where: str) -> Stream:
    names = list(rows[0])
    if any(list(r) != names for r in rows):
        raise UserError(f"{where}: messages of different fields (arrays of another length?)")
    return {n: np.array([r[n] for r in rows], dtype=np.float64) for n in names}


def _ulog(path: Path) -> dict[str, Stream]:
    from pyulog import ULog

    log = ULog(str(path))
    out: dict[str, Stream] = {}
    for d in log.data_list:
        name = d.name if d.multi_id == 0 else f"{d.name}_{d.multi_id}"
        out[name] = {k: np.asarray(v, dtype=np.float64) for k, v in d.data.items()
                     if np.asarray(v).dtype.kind in "biuf"}
    return out


def _tdms(path: Path) -> dict[str, Stream]:
    from nptdms import TdmsFile

    f = TdmsFile.read(str(path))
    out: dict[str, Stream] = {}
    for g in f.groups():
        cols: dict[str, np.ndarray] = {}
        for c in g.channels():
            data = np.asarray(c[:])
            if data.dtype.kind in "biuf":
                cols[c.name] = data.astype(np.float64)
            elif data.dtype.kind == "M":  # a time channel: epoch seconds
                cols[c.name] = data.astype("datetime64[ns]").astype(np.int64) * 1e-9
        lengths = {v.shape[0] for v in cols.values()}
        if "time_s" not in cols and lengths:
            wf = _waveform_time(g, str(path), max(lengths))
            if wf is not None:
                cols["time_s"] = wf
        if len(lengths) > 1:
            raise UserError(f"{path}: group {g.name!r}: channels of different lengths "
                            f"({', '.join(str(n) for n in sorted(lengths))})")
        if cols:
            out[g.name] = cols
    return out


def _waveform_time(group, path: str, n: int) -> np.ndarray | None:  # noqa: ANN001 - nptdms
    """A DAQmx waveform group's time (epoch seconds: TDMS times are UTC): wf_start_time +
    wf_start_offset + i x wf_increment, the same on every waveform channel of the group;
    None when no channel has wf_increment."""
    timing = set()
    for c in group.channels():
        p = c.properties
        if "wf_increment" not in p:
            continue
        start = p.get("wf_start_time")
        t0 = 0.0 if start is None else _epoch_s(start)
        timing.add((t0 + float(p.get("wf_start_offset", 0.0)), float(p["wf_increment"])))
    if not timing:
        return None
    if len(timing) > 1:
        raise UserError(f"{path}: group {group.name!r}: waveform channels of different timing "
                        f"(wf_start_time + wf_start_offset, wf_increment: "
                        f"{', '.join(f'{a:.6f} s, {b:g} s' for a, b in sorted(timing))}): "
                        "map a time channel, or write the group at one rate")
    t0, inc = timing.pop()
    if not (np.isfinite(t0) and np.isfinite(inc) and inc > 0):
        raise UserError(f"{path}: group {group.name!r}: waveform timing wf_increment {inc:g} "
                        "s: not a sample period")
    return t0 + np.arange(n, dtype=np.float64) * inc


def _epoch_s(when: object) -> float:
    """A TDMS time property (numpy datetime64, or a datetime: UTC) as epoch seconds."""
    if isinstance(when, np.datetime64):
        return float(when.astype("datetime64[ns]").astype(np.int64)) * 1e-9
    import datetime as dt

    if isinstance(when, dt.datetime):
        aware = when if when.tzinfo else when.replace(tzinfo=dt.UTC)
        return aware.timestamp()
    return float(when)  # type: ignore[arg-type]
