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


def test_a_node_that_gains_four_per_cent_is_taken(by_sse: None) -> None:
    """A third node lowering every unit's misfit by 3.5-4.5 % (the gain of the designs whose
    fast loops a third node holds) is taken."""
    rng = np.random.default_rng(SEED)
    k2 = rng.uniform(40.0, 200.0, 12)
    gain = rng.uniform(0.035, 0.045, 12)
    series, fits = _fits({1: list(3 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    k, scores = fp.choose_k(series, fits)
    assert k == 3, f"seed {SEED}: scores {scores}"
    assert scores[2] / scores[3] - 1.0 < 0.05  # the gain is under 5 %: a 5 % tolerance keeps 2


def test_a_node_that_gains_little_is_left_out(by_sse: None) -> None:
    """Within the tolerance (a gain of 1-2 %) the smaller K."""
    rng = np.random.default_rng(SEED + 1)
    k2 = rng.uniform(40.0, 200.0, 12)
    gain = rng.uniform(0.01, 0.02, 12)
    series, fits = _fits({1: list(1.005 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    k, scores = fp.choose_k(series, fits)
    assert k == 1, f"seed {SEED + 1}: scores {scores}"
    series, fits = _fits({1: list(2 * k2), 2: list(k2), 3: list(k2 / (1 + gain))})
    assert fp.choose_k(series, fits)[0] == 2, f"seed {SEED + 1}"
