"""Diagnose's fits take a sample every few seconds, not every few samples: the same physics
logged at 10 Hz and at 100 Hz gives the same diagnosis (its driver and its verdict)."""

from __future__ import annotations

import copy

import pytest

from fogsf.diagnose import driver
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import planted as cases
from fogsf.diagnose.verdict import diagnose


def test_every_is_in_seconds() -> None:
    import numpy as np

    assert driver.every(np.arange(100) * 0.1) == 20
    assert driver.every(np.arange(100) * 0.01) == 200
    assert driver.every(np.arange(100) * 0.001) == 2000


@pytest.mark.slow
def test_ten_and_hundred_hz_give_the_same_diagnosis() -> None:
    case = cases.draw("effect", "bias_drift", 11)
    fast = copy.deepcopy(case)
    fast.config.dt_s = case.config.dt_s / 10.0
    verdicts = []
    for c in (case, fast):
        logs, _ = case_build.build(c)
        d = diagnose(logs)
        verdicts.append(d)
    slow_d, fast_d = verdicts
    for a, b in zip(slow_d.ctxs, fast_d.ctxs, strict=True):
        assert a.driver.source == b.driver.source and a.power_on == b.power_on
        assert (a.driver.tau_housing_s, a.driver.tau_board_s) == \
            (b.driver.tau_housing_s, b.driver.tau_board_s)
    assert (slow_d.cause, slow_d.causes, slow_d.ambiguous, slow_d.unexplained) == \
        (fast_d.cause, fast_d.causes, fast_d.ambiguous, fast_d.unexplained)
    assert slow_d.cause == "bias_drift"  # the planted effect, found at both rates
