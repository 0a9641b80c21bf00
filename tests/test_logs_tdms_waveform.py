"""A LabVIEW DAQmx TDMS file of waveform channels (no time channel: each channel's
wf_start_time, wf_start_offset and wf_increment give its samples' times) reads to the same
log as its CSV (docs/logs.md, "The field's formats")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import read_log

pytest.importorskip("nptdms", reason="the optional package nptdms is not installed "
                                     "(pip install 'fogsf[rigs]')")

EPOCH_NS = 1_772_612_100 * 10**9 + 250_000_000
NAMES = ("temp_c", "table_rate_dps", "gyro_dps", "earth_rate_dps")


def _signals(n: int = 900, hz: float = 10.0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(11)
    t = np.arange(n) / hz
    temp = 16.0 + 8.0 * t / t[-1]
    table = np.where((np.arange(n) // 150) % 2 == 0, 10.0, -10.0)
    gyro = table * (1.0 + 1e-4 * (temp - 20.0)) + 0.00234 + rng.normal(0, 1e-4, n)
    return dict(zip(NAMES, (temp, table, gyro, np.full(n, 0.00234)), strict=True))


def _write(path: Path, cols: dict[str, np.ndarray], inc: dict[str, float] | None = None,
           offset_s: float = 0.0) -> None:
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(path)) as w:
        w.write_segment([ChannelObject("Dev1", n, v, properties={
            "wf_start_time": np.datetime64(EPOCH_NS, "ns"), "wf_start_offset": offset_s,
            "wf_increment": (inc or {}).get(n, 0.1), "wf_samples": v.size,
            "unit_string": "deg/s"}) for n, v in cols.items()])


def test_waveform_channels_read_with_their_time(tmp_path: Path, capsys) -> None:
    cols = _signals()
    path = tmp_path / "daqmx.tdms"
    _write(path, cols, offset_s=2.0)
    lg = read_log(path)
    t = EPOCH_NS * 1e-9 + 2.0 + np.arange(900) * 0.1
    assert np.abs(lg.time_s - t).max() < 1e-6
    assert lg.sample_rate_hz == pytest.approx(10.0)
    for n in NAMES[:3]:
        assert np.array_equal(getattr(lg, n), cols[n])
    capsys.readouterr()
    assert main(["inspect", str(path), "--window-s", "10"]) == 0
    assert "at 10 Hz" in capsys.readouterr().out


def test_waveforms_of_different_timing_refused(tmp_path: Path, capsys) -> None:
    path = tmp_path / "mixed.tdms"
    _write(path, _signals(), inc={"temp_c": 1.0})
    capsys.readouterr()
    assert main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert "waveform channels of different timing" in err and len(err.splitlines()) == 1, err
