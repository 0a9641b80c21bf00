"""`benchmarks.rigs`' own checks: its bias score (moved from tests/test_sim_rigs.py: the
library's tests import no bench)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from benchmarks.rigs import score_bias
from fogsf.logs.logio import read_log
from fogsf.sim.rigs import benches, chambers


@pytest.mark.parametrize("name,floor,share", [("plain-reversals", 0.1, 0.05),
                                               ("ros-stationary", 0.2, 0.10)])
def test_bench_rigs_scores_the_bias_head_against_the_truth(tmp_path: Path, name: str,
                                                           floor: float, share: float) -> None:
    """`make bench-rigs`' bias score: per test pair (per 100 s window of a stationary log),
    std(predicted - true) against max(0.1 deg/h, 5 % of the true bias' std) (stationary:
    max(0.2, 10 %)) beside a cubic in T fitted to the training windows; a perfect prediction
    scores 0, no prediction scores the true bias' own std."""
    case = benches.bench_cases()[name]
    short = chambers.loop(-10.0, 20.0, 2.0, 2.0, 300.0)
    case = replace(case, train=replace(case.train, chamber=short),
                   test=replace(case.test, chamber=short))
    train, test = benches.write_case(tmp_path, case, (20003,), seed=3)
    logs = [read_log(r.path) for r in (train, test)]
    truth = test.truth[""]
    exact = score_bias(logs[0], logs[1], truth.bias_dph, truth)
    assert exact["bias_model_err_std_dph"] < 1e-9 and exact["bias_model_meets"]
    none = score_bias(logs[0], logs[1], np.zeros_like(truth.bias_dph), truth)
    assert none["bias_model_err_std_dph"] == pytest.approx(none["bias_true_std_dph"])
    assert none["bias_true_std_dph"] > 0.1  # the population's thermal bias moves
    assert none["bias_model_target_dph"] == max(floor, share * none["bias_true_std_dph"])
    assert 0.0 < none["bias_px4_cubic_err_std_dph"] < none["bias_true_std_dph"]
