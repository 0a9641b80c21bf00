"""The field's formats (logs/read/field_formats.py; `pip install fogsf[rigs]`): a small file of
each written with its own library (a minimal writer for ULog, which pyulog only reads),
read through a column map to the numbers of the same run's plain CSV. Each test skips, and
says which package is missing, when the extra is not installed."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import read_log
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.rigs import chambers, rig_logs
from fogsf.sim.rigs import protocols as rigs

SEED = 7_0039
EPOCH_NS = 1_772_612_100 * 10**9


@pytest.fixture(scope="module")
def run() -> rigs.RigRun:
    rng = np.random.default_rng(SEED)
    gyro = int(rng.integers(20000, 30000))
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(15.0, 25.0, 4.0, 4.0,
                                                              soak_s=60.0), rate_hz=5.0)
    return rigs.run_rig(p, gyro, int(rng.integers(0, 1000)))


def _need(module: str) -> None:
    pytest.importorskip(module, reason=f"the optional package {module} is not installed "
                                       "(pip install 'fogsf[rigs]')")


def _check(lg, run: rigs.RigRun, temp_tol: float = 0.0) -> None:  # noqa: ANN001
    ax = run.axes[""]
    t = (EPOCH_NS + np.round(run.stamp_s * 1e9).astype(np.int64)) * 1e-9
    assert np.abs(lg.time_s - t).max() < 1e-6
    assert np.allclose(lg.gyro_dps, ax.gyro_dps, rtol=1e-6, atol=1e-9)  # float32 or 64
    assert np.array_equal(lg.table_rate_dps, run.command_dps)
    assert np.abs(lg.temp_c - ax.temp_c).max() <= temp_tol + 1e-4


def _map(folder: Path, text: str) -> None:
    (folder / "fogsf-columns.toml").write_text(text)


ROS_MAP = '''stream = "/imu"
time_s = "`header.stamp.sec` + `header.stamp.nanosec` * 1e-9"
gyro_dps = "`angular_velocity.z` * 57.29577951308232"
earth_rate_dps = 0.00234

[join.board]
stream = "/board_temperature"
time_s = "`header.stamp.sec` + `header.stamp.nanosec` * 1e-9"
temp_c = "temperature"
max_gap_s = 5

[join.table]
stream = "/table/cmd"
time_s = "log_time"
table_rate_dps = "data"
how = "hold"
'''


def _write_ros(path: Path, run: rigs.RigRun, ros1: bool, mcap: bool = False) -> None:
    """/imu (sensor_msgs/Imu, rad/s), /board_temperature (sensor_msgs/Temperature, 1 Hz),
    /table/cmd (std_msgs/Float64, deg/s, on each change; its receive time the stamp)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types  # noqa: N806
    Time = T["builtin_interfaces/msg/Time"]  # noqa: N806
    Header, Vec, Quat = (T["std_msgs/msg/Header"], T["geometry_msgs/msg/Vector3"],  # noqa: N806
                         T["geometry_msgs/msg/Quaternion"])
    ax = run.axes[""]
    ns = EPOCH_NS + np.round(run.stamp_s * 1e9).astype(np.int64)
    cov = np.zeros(9)

    def header(i: int) -> object:
        stamp = Time(sec=int(ns[i] // 10**9), nanosec=int(ns[i] % 10**9))
        return (Header(seq=i, stamp=stamp, frame_id="imu_link") if ros1
                else Header(stamp=stamp, frame_id="imu_link"))

    if ros1:
        from rosbags.rosbag1 import Writer

        w = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        w = Writer(path, version=8, storage_plugin=StoragePlugin.MCAP if mcap
                   else StoragePlugin.SQLITE3)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    with w:
        kw = {"typestore": ts}
        imu = w.add_connection("/imu", "sensor_msgs/msg/Imu", **kw)
        temp = w.add_connection("/board_temperature", "sensor_msgs/msg/Temperature", **kw)
        table = w.add_connection("/table/cmd", "std_msgs/msg/Float64", **kw)
        change = set(np.flatnonzero(np.diff(run.command_dps, prepend=np.nan) != 0).tolist())
        for i in range(ns.size):
            if i in change:
                m = T["std_msgs/msg/Float64"](data=float(run.command_dps[i]))
                w.write(table, int(ns[i]), ser(m, "std_msgs/msg/Float64"))
            m = T["sensor_msgs/msg/Imu"](
                header=header(i), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=cov, angular_velocity=Vec(
                    x=0.0, y=0.0, z=float(ax.gyro_dps[i] / rig_logs.DEG_PER_RAD)),
                angular_velocity_covariance=cov,
                linear_acceleration=Vec(x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=cov)
            w.write(imu, int(ns[i]), ser(m, "sensor_msgs/msg/Imu"))
            if i % 5 == 0:
                m = T["sensor_msgs/msg/Temperature"](header=header(i),
                                                      temperature=float(ax.temp_c[i]),
                                                      variance=0.0)
                w.write(temp, int(ns[i]), ser(m, "sensor_msgs/msg/Temperature"))


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite", "ros2-mcap"])
def test_ros_bags(run, tmp_path: Path, kind: str) -> None:
    _need("rosbags")
    folder = tmp_path / kind
    folder.mkdir()
    path = folder / ("run.bag" if kind == "ros1" else "run")
    _write_ros(path, run, kind == "ros1", kind.endswith("mcap"))
    _map(folder, ROS_MAP)
    lg = read_log(path)
    _check(lg, run, temp_tol=0.2)  # the thermometer at 1 Hz, interpolated
    assert any("stream /imu" in n for n in lg.read_notes)
    assert lg.valid is None or lg.valid.all()


def _ulog(path: Path, messages: dict[str, tuple[list[tuple[str, str]], np.ndarray]]) -> None:
    """A minimal ULog (the format pyulog reads): header, flag bits, a format and a
    subscription per message, then its data rows in time order."""
    types = {"uint64_t": "Q", "float": "f", "double": "d"}

    def msg(kind: bytes, payload: bytes) -> bytes:
        return struct.pack("<HB", len(payload), kind[0]) + payload

    out = [b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0),
           msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))]
    for name, (fields, _) in messages.items():
        text = f"{name}:" + "".join(f"{t} {f};" for t, f in fields)
        out.append(msg(b"F", text.encode()))
    rows = []
    for k, (name, (fields, data)) in enumerate(messages.items()):
        out.append(msg(b"A", struct.pack("<BH", 0, k) + name.encode()))
        fmt = "<" + "".join(types[t] for t, _ in fields)
        for r in data:
            vals = [int(v) if types[t] == "Q" else float(v) for (t, _), v in zip(fields, r,
                                                                                 strict=True)]
            rows.append((int(r[0]), msg(b"D", struct.pack("<H", k) + struct.pack(fmt, *vals))))
    out += [b for _, b in sorted(rows, key=lambda x: x[0])]
    path.write_bytes(b"".join(out))


def test_px4_ulog(run, tmp_path: Path) -> None:
    _need("pyulog")
    ax = run.axes[""]
    us = np.round(run.stamp_s * 1e6).astype(np.int64) + 5_000_000  # since boot
    change = np.flatnonzero(np.diff(run.command_dps, prepend=np.nan) != 0)
    path = tmp_path / "log_0.ulg"
    _ulog(path, {
        "sensor_gyro": ([("uint64_t", "timestamp"), ("float", "x"), ("float", "y"),
                         ("double", "z"), ("float", "temperature")],
                        np.column_stack([us, 0 * us, 0 * us, ax.gyro_dps / rig_logs.DEG_PER_RAD,
                                         ax.temp_c])),
        "table_command": ([("uint64_t", "timestamp"), ("double", "rate_dps")],
                          np.column_stack([us[change], run.command_dps[change]]))})
    boot = EPOCH_NS * 1e-9 - 5.0
    _map(tmp_path, f'''stream = "sensor_gyro"
time_s = "timestamp * 1e-6 + {boot!r}"
gyro_dps = "z * 57.29577951308232"
temp_c = "temperature"
earth_rate_dps = 0.00234

[join.table]
stream = "table_command"
time_s = "timestamp * 1e-6 + {boot!r}"
table_rate_dps = "rate_dps"
how = "hold"
''')
    lg = read_log(path)
    _check(lg, run, temp_tol=1e-5)  # float32 temperature


def test_tdms(run, tmp_path: Path, capsys) -> None:
    _need("nptdms")
    from nptdms import ChannelObject, TdmsWriter

    ax = run.axes[""]
    path = tmp_path / "chamber.tdms"
    t = (EPOCH_NS + np.round(run.stamp_s * 1e9).astype(np.int64)) * 1e-9
    with TdmsWriter(str(path)) as w:
        w.write_segment([ChannelObject("rig", "Time", t),
                         ChannelObject("rig", "Board T", ax.temp_c),
                         ChannelObject("rig", "Table (deg/s)", run.command_dps),
                         ChannelObject("rig", "Gyro (rad/s)", ax.gyro_dps / rig_logs.DEG_PER_RAD)])
    cols = ("time_s=Time,temp_c=Board T,table_rate_dps=Table (deg/s),"
            "gyro_dps=`Gyro (rad/s)` * 57.29577951308232,earth_rate_dps=0.00234")
    lg = read_log(path, Dialect(columns=Dialect.parse_columns(cols)))
    _check(lg, run)
    capsys.readouterr()
    assert main(["inspect", str(path), "--columns", cols]) == 0
    assert "TDMS stream rig" in capsys.readouterr().err


def test_a_missing_extra_is_named(tmp_path: Path, capsys, monkeypatch) -> None:
    import builtins

    real = builtins.__import__

    def no_nptdms(name: str, *a: object, **kw: object) -> object:
        if name == "nptdms":
            raise ImportError(name)
        return real(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_nptdms)
    (tmp_path / "x.tdms").write_bytes(b"TDSm")
    capsys.readouterr()
    assert main(["inspect", str(tmp_path / "x.tdms")]) == 2
    assert "pip install 'fogsf[rigs]'" in capsys.readouterr().err


def test_a_map_inside_a_ros2_bag_folder(run, tmp_path: Path, capsys) -> None:
    """The map kept inside the bag's own folder is found; with none anywhere, the refusal
    says where it looked."""
    _need("rosbags")
    path = tmp_path / "run"
    _write_ros(path, run, ros1=False)
    capsys.readouterr()
    assert main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert f"no fogsf-columns.json or fogsf-columns.toml in {path} or {tmp_path}" in err, err
    _map(path, ROS_MAP)
    lg = read_log(path)
    _check(lg, run, temp_tol=0.2)
    assert any(str(path / "fogsf-columns.toml") in n for n in lg.read_notes), lg.read_notes
