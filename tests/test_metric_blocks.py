"""Per-sample work in blocks (plateaus.BLOCK_SAMPLES, validation.VALIDATE_BLOCK): the same bits as
one block over the whole log, and the same refusals, on a log with +/- pairs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fogsf.logs import validation
from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import parse_log
from fogsf.logs.measure import metrics, pairs, plateaus, windows
from fogsf.sim.config import TableConfig
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper


def reversals() -> ChamberLog:
    """About an hour at 10 Hz, +/-100 deg/s reversals every 60 s, through 20 C."""
    cfg = paper(1.0, 3)
    cfg.table = TableConfig(kind="alternating", rate_dps=100.0, dwell_s=60.0)
    cfg.profile.start_c, cfg.profile.stop_c = 0.0, 40.0
    log = simulate(cfg).log
    return log.slice(0, 40_000)


def figures(log: ChamberLog) -> dict:
    corr = np.linspace(-50.0, 50.0, len(log)).astype(np.float32)
    w = windows.sf_windows(log, 100.0)
    pp = pairs.find_pairs(log)
    assert pp is not None
    return {
        "plateaus": np.asarray(plateaus.plateaus(log.table_rate_dps, log.measures)),
        "bias": pairs.bias_track(log),
        "signal": windows.sf_signal(log, correction_ppm=corr),
        **{f"w_{k}": v for k, v in dataclasses.asdict(w).items()},
        "pairs_sf": pp.sf_ratio,
        "pairs_bias": pp.bias_dps,
        "before": np.array(list(metrics.log_metrics(log, 100.0).values())),
        "after": np.array(list(metrics.log_metrics(log, 100.0, correction_ppm=corr).values())),
    }


@pytest.mark.slow
def test_metrics_in_blocks_are_the_same_bits(monkeypatch: pytest.MonkeyPatch) -> None:
    log = reversals()
    whole = figures(log)
    for block in (1, 997, 4096):
        for module in (windows, pairs, plateaus):  # each reads its own binding
            monkeypatch.setattr(module, "BLOCK_SAMPLES", block)
        got = figures(log)
        for k, v in whole.items():
            assert np.array_equal(np.asarray(got[k]), np.asarray(v), equal_nan=True), (block, k)


@pytest.mark.parametrize("block", [1, 3, 1 << 20])
def test_validation_in_blocks_names_the_first_broken_step(block: int, monkeypatch) -> None:
    monkeypatch.setattr(validation, "VALIDATE_BLOCK", block)
    head = "time_s,temp_c,table_rate_dps,gyro_dps"
    t = [0.1 * i for i in range(30)]
    t[20] = t[20] + 0.05  # jitter at line 22 (the step from row 20 to 21), then ...
    t[25] = t[24]  # ... a time that does not increase (refused first, wherever it is)
    rows = [f"{x:.2f},20,10,{11 if i == 25 else 10}" for i, x in enumerate(t)]  # no duplicate
    with pytest.raises(LogError, match=r"line 27: time not increasing"):
        parse_log("\n".join([head, *rows]) + "\n", "x.csv")
    t[25] = 2.5
    rows = [f"{x:.2f},20,10,10" for x in t]
    s = parse_log("\n".join([head, *rows]) + "\n", "x.csv").sampling  # jitter: counted
    assert (s.jittered, s.worst_step_s) == (2, pytest.approx(0.15))
