"""inspect's and replay's figures of a log on disk (logs/read/stream_read.py) are those of the log
in memory, bit for bit: plateaus, +/- pairs (a long plateau summed in pieces, a stall), the
SF windows before and after a correction, the bias windows (pairs, stationary), read in
small blocks so that every border falls inside a plateau or a window."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_metric_blocks import reversals

from fogsf.cli.inspect import summary
from fogsf.cli.main import main
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.logio import read_log
from fogsf.logs.measure import bias as bias_mod
from fogsf.logs.measure import metrics, windows
from fogsf.logs.measure.bias import before_after, bias_windows
from fogsf.logs.read import columns
from fogsf.logs.read.stream_read import read_log_on_disk
from fogsf.logs.writer import write_log


def _stalled(log: ChamberLog) -> ChamberLog:
    """The reversals with a stall (valid = 0) inside a plateau and an earth rate column."""
    valid = np.ones(len(log), dtype=bool)
    valid[5_230:5_400] = False
    log.valid = valid
    log.earth_rate_dps = np.full(len(log), 0.003)
    return log


def _stationary() -> ChamberLog:
    n = 30_000
    rng = np.random.default_rng(4)
    t = np.arange(n) * 0.1
    return ChamberLog(t, 20.0 + t / 600.0, np.zeros(n), 0.003 + rng.normal(0, 1e-4, n),
                      np.full(n, 0.002))


LOGS = {"pairs-stall": lambda: _stalled(reversals()), "stationary": _stationary}


@pytest.fixture
def small(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", 97)  # a 60 s plateau is many reads
    monkeypatch.setattr(bias_mod, "BLOCK_WINDOWS_SAMPLES", 2_500)
    monkeypatch.setattr(columns, "STRICT", True)  # no whole column is read


def _same(a: object, b: object) -> None:
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


@pytest.mark.parametrize("name", list(LOGS))
def test_inspect_on_disk_is_the_same_bits(name: str, tmp_path: Path, small: None) -> None:
    p = tmp_path / "log.csv"
    write_log(p, LOGS[name]())
    whole, disk = read_log(p), read_log_on_disk(p)
    _same(summary(disk, 100.0, None, None), summary(whole, 100.0, None, None))
    _same(summary(disk, 100.0, None, None, 3.0, 250.0),
          summary(whole, 100.0, None, None, 3.0, 250.0))
    rng = np.random.default_rng(1)
    corr = rng.normal(0.0, 30.0, len(whole)).astype(np.float32)
    spill = columns.Spill()
    f = spill.file("corr", np.float32)
    for a in range(0, corr.size, 1234):
        f.append(corr[a:a + 1234])
    lazy = f.column()
    w_whole = bias_windows(whole, 100.0)
    w_disk = bias_windows(disk, 100.0)
    _same(before_after(w_disk, lazy.astype(np.float64)),
          before_after(w_whole, corr.astype(np.float64)))
    if name != "stationary":
        _same(metrics.log_metrics(disk, 100.0, correction_ppm=lazy),
              metrics.log_metrics(whole, 100.0, correction_ppm=corr))
        sw, sd = windows.sf_windows(whole, 100.0), windows.sf_windows(disk, 100.0)
        for k in ("t_s", "temp_c", "sf_ratio", "noise_ppm", "start", "stop"):
            assert np.array_equal(getattr(sw, k), getattr(sd, k), equal_nan=True), k
    spill.close()


def test_replay_on_disk_is_the_replay_in_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                ) -> None:
    """The replay command end to end: the output file and the JSON (metrics before and
    after, the bias of a bias head over the pairs) of a log read onto disk are those of
    the log read into memory."""
    import fogsf.cli.replay as replay
    from fogsf.logs.read import stream_read
    from fogsf.models import samples

    monkeypatch.setenv("FOGSF_BUILD_DIR", str(tmp_path / "kernels"))
    monkeypatch.setattr(replay, "REPLAY_BLOCK", 1001)
    model = samples.random_model(3, 4, 1, 8, decimation=10, seed=6, bias_head=True)
    model.save(tmp_path / "m")
    log = tmp_path / "run.csv"
    write_log(log, _stalled(reversals()))
    outs = {}
    for how in ("disk", "memory"):
        if how == "memory":
            monkeypatch.setattr(stream_read, "read_log_on_disk",
                                lambda p, d, spill=None, progress=None: read_log(p, d))
        for fmt in ("csv", "parquet"):
            out = tmp_path / f"{how}.{fmt}"
            assert main(["replay", str(tmp_path / "m"), str(log), "--out", str(out),
                         "--json", str(tmp_path / f"{how}.json")]) == 0
            outs[how, fmt] = out.read_bytes()
        outs[how, "json"] = json.loads((tmp_path / f"{how}.json").read_text())
    assert outs["disk", "json"]["bias"] is not None and outs["disk", "json"]["after"]
    for k in ("csv", "parquet", "json"):
        assert outs["disk", k] == outs["memory", k], k
