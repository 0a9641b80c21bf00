"""The design's node count (`design_prior.choose_k`): one more node is taken when it lowers
the units' median misfit by more than STRUCTURE_TOLERANCE, the smallest K otherwise.

The misfits are given (`window_misfit` read off each fit's `sse`): the rule, not the fits, is
under test. The figures that set the tolerance: benchmarks/probes/README.md,
"fleet_structure_choice"."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.prior import design_prior as fp
from fogsf.prior.unit_fit import StepSeries, UnitFit

SEED = 5021


def _fits(misfits: dict[int, list[float]]) -> tuple[dict, dict]:
    n = len(next(iter(misfits.values())))
    series = {f"u{i}": StepSeries([np.zeros(4)], np.zeros(4), np.arange(4), 5.0)
              for i in range(n)}
    fits = {k: {f"u{i}": UnitFit(k, np.zeros(1), np.zeros((1, 1)), 1.0, float(m), 4)
                for i, m in enumerate(ms)} for k, ms in misfits.items()}
    return series, fits


@pytest.fixture
def by_sse(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fp, "window_misfit", lambda series, fit: fit.sse)


def test_a_node_that_gains_more_than_the_tolerance_is_taken(by_sse: None) -> None:
    """A third node lowering every unit's misfit by 0.5-1.5 points more than the tolerance
    is taken."""
    rng = np.random.default_rng(SEED)
    tol = fp.STRUCTURE_TOLERANCE
    k2 = rng.uniform(40.0, 200.0, 12)
    gain = rng.uniform(tol + 0.005, tol + 0.015, 12)
    series, fits = _fits({1: list(3 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    k, scores = fp.choose_k(series, fits)
    assert k == 3, f"seed {SEED}: scores {scores}"


def test_a_node_that_gains_less_than_the_tolerance_is_left_out(by_sse: None) -> None:
    """A gain 0.8-1.5 points under the tolerance: the smaller K, at 1 and at 2 nodes."""
    rng = np.random.default_rng(SEED + 1)
    tol = fp.STRUCTURE_TOLERANCE
    k2 = rng.uniform(40.0, 200.0, 12)
    gain = rng.uniform(tol - 0.015, tol - 0.008, 12)
    series, fits = _fits({1: list(1.002 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    k, scores = fp.choose_k(series, fits)
    assert k == 1, f"seed {SEED + 1}: scores {scores}"
    series, fits = _fits({1: list(2 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    assert fp.choose_k(series, fits)[0] == 2, f"seed {SEED + 1}"
