"""`fogsf diagnose` and `fogsf plan --from-logs` read their logs onto disk: the JSON they
write is the one of the log read into memory, at reads of 97 samples."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.diagnose import driver, runs
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import planted as cases
from fogsf.diagnose.effects import hysteresis_form
from fogsf.logs.logio import read_log
from fogsf.logs.read import columns, stream_read
from fogsf.logs.writer import write_log


def _outputs(tmp: Path, log: Path, earlier: Path, monkeypatch: pytest.MonkeyPatch, how: str
             ) -> dict:
    if how == "memory":
        monkeypatch.setattr(stream_read, "read_log_on_disk",
                            lambda p, d, spill=None, progress=None: read_log(p, d))
    out = tmp / how
    # on disk, diagnose reads no column whole (a block at a time: memory bounded)
    monkeypatch.setattr(columns, "STRICT", how == "disk")
    assert main(["diagnose", str(log), "--json", str(out / "d.json")]) == 0
    monkeypatch.setattr(columns, "STRICT", False)
    assert main(["plan", "--from-logs", str(earlier), "--hours", "2", "--test-rates", "1",
                 "--interval-gyros", "0", "--workers", "1", "--out", str(out / "plan")]) == 0
    files = {p.relative_to(out): p.read_bytes().replace(str(out).encode(), b"OUT")  # paths named
             for p in sorted(out.rglob("*")) if p.is_file()}
    plan = json.loads(files[Path("plan/plan.json")])
    plan.pop("seconds")  # the plan's own run time
    files[Path("plan/plan.json")] = json.dumps(plan).encode()
    return files


@pytest.mark.slow
def test_diagnose_and_plan_on_disk_are_in_memory(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(columns, "READ_SAMPLES", 97)
    for module in (runs, driver, hysteresis_form):  # lags made 1000 samples at a time
        monkeypatch.setattr(module, "STREAM_BLOCK", 1000)
    logs, _ = case_build.build(cases.draw("effect", "bias_drift", 11))
    log = tmp_path / "run.csv"
    write_log(log, logs[0])
    earlier = tmp_path / "earlier.csv"  # as test_plan's: a log plan fits a gyro to
    assert main(["simulate", "--random-gyro", "5", "--profile", "cycle", "--start-c", "-40",
                 "--stop-c", "50", "--ramp-rate", "2", "--soak-min", "20", "--cycles", "1",
                 "--out", str(earlier)]) == 0
    disk = _outputs(tmp_path, log, earlier, monkeypatch, "disk")
    memory = _outputs(tmp_path, log, earlier, monkeypatch, "memory")
    assert disk.keys() == memory.keys() and len(disk) >= 2
    for k in disk:
        assert disk[k] == memory[k], k
