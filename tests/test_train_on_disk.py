"""`fogsf train` reads its logs onto disk and reads no column whole (its per-sample figures,
the ramps it finds, the bias fit's front end a block at a time): the model directory is the
one of the logs read into memory, byte for byte (but the run time)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import read_log
from fogsf.logs.read import columns, stream_read


def _trained(tmp: Path, logs: list[Path], model: str, monkeypatch: pytest.MonkeyPatch,
             how: str) -> dict[str, bytes]:
    with monkeypatch.context() as m:
        if how == "memory":
            m.setattr(stream_read, "read_log_on_disk",
                      lambda p, d, spill=None, progress=None: read_log(p, d))
        else:
            m.setattr(columns, "STRICT", True)  # no whole column is read
        out = tmp / f"{model}-{how}"
        chosen = [] if model == "default" else ["--model", model]
        assert main(["train", "--train", str(logs[0]), "--test", str(logs[1]), *chosen,
                     "--out", str(out), "--no-progress"]) == 0
    files = {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file()}
    for name in [k for k in files if k.endswith(".json")]:  # but the run times
        files[name] = json.dumps(_untimed(json.loads(files[name])), sort_keys=True).encode()
    return files


def _untimed(x: object) -> object:
    if isinstance(x, dict):
        return {k: _untimed(v) for k, v in x.items() if k not in ("seconds", "train_seconds")}
    if isinstance(x, list):
        return [_untimed(v) for v in x]
    return x


@pytest.mark.slow
@pytest.mark.parametrize("model", ["poly", "default"])
def test_train_on_disk_is_train_in_memory(model: str, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", 997)
    logs = [tmp_path / "train.csv", tmp_path / "test.csv"]
    for log, rate in zip(logs, ("1", "2"), strict=True):
        assert main(["simulate", "--random-gyro", "5", "--profile", "cycle", "--start-c",
                     "-20", "--stop-c", "40", "--ramp-rate", rate, "--soak-min", "20",
                     "--cycles", "1", "--out", str(log)]) == 0
    disk = _trained(tmp_path, logs, model, monkeypatch, "disk")
    memory = _trained(tmp_path, logs, model, monkeypatch, "memory")
    assert disk.keys() == memory.keys() and "metrics.json" in disk
    for k in disk:
        assert disk[k] == memory[k], k
