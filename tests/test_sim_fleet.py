"""Designs and units: the same seed and index give the same unit, the spreads are as stated,
the structure is the design's, a defective unit carries its defect."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.sim.config import SimConfig, validate
from fogsf.sim.fleet_units import (
    DEFECT_SLOPE_FACTOR,
    DEFECT_TAU_FACTOR,
    SF_SPREAD,
    TAU_SPREAD,
    defective_unit,
    design_for_seed,
    unit_for,
)

RNG_SEED = 3801
_rng = np.random.default_rng(RNG_SEED)
DESIGNS = [int(s) for s in _rng.integers(1, 10_000, size=4)]  # development designs


@pytest.mark.parametrize("design", DESIGNS)
def test_same_seed_same_unit_and_units_differ(design: int) -> None:
    a = unit_for(design, 7).to_json()
    assert a == unit_for(design, 7).to_json(), f"design {design} (rng seed {RNG_SEED})"
    assert a != unit_for(design, 8).to_json()
    validate(unit_for(design, 7))
    assert SimConfig.from_json(a) == unit_for(design, 7)


@pytest.mark.parametrize("design", DESIGNS)
def test_units_share_the_structure_and_vary_by_the_stated_spreads(design: int) -> None:
    d = design_for_seed(design)
    tau_r, sf_r = [], []
    for i in range(40):
        u = unit_for(design, i)
        assert [(n.name, n.parent) for n in u.thermal.nodes] == \
            [(n.name, n.parent) for n in d.thermal.nodes], f"design {design} unit {i}"
        assert [(t.factor, t.nodes) for t in u.sf.terms] == \
            [(t.factor, t.nodes) for t in d.sf.terms]
        tau_r += [a.tau_s / b.tau_s for a, b in zip(u.thermal.nodes, d.thermal.nodes,
                                                    strict=True)]
        sf_r += [a.lin_ppm_per_c / b.lin_ppm_per_c
                 for a, b in zip(u.sf.terms, d.sf.terms, strict=True) if b.lin_ppm_per_c]
    tau_r, sf_r = np.asarray(tau_r), np.asarray(sf_r)
    tol = 1e-5
    assert tau_r.min() >= 1 - TAU_SPREAD - tol and tau_r.max() <= 1 + TAU_SPREAD + tol
    assert sf_r.min() >= 1 - SF_SPREAD - tol and sf_r.max() <= 1 + SF_SPREAD + tol
    # the spreads are used, not only bounded: uniform draws reach near both ends
    assert tau_r.min() < 1 - 0.8 * TAU_SPREAD and tau_r.max() > 1 + 0.8 * TAU_SPREAD
    assert sf_r.min() < 1 - 0.8 * SF_SPREAD and sf_r.max() > 1 + 0.8 * SF_SPREAD


@pytest.mark.parametrize("design", DESIGNS[:2])
def test_defective_unit_carries_its_defect(design: int) -> None:
    u = unit_for(design, 3)
    bad = defective_unit(design, 3, "slope")
    ratios = [b.lin_ppm_per_c / a.lin_ppm_per_c for a, b in zip(u.sf.terms, bad.sf.terms,
                                                                 strict=True)
              if a.lin_ppm_per_c]
    assert sorted(ratios)[-1] == pytest.approx(DEFECT_SLOPE_FACTOR)
    assert sorted(ratios)[-2] == pytest.approx(1.0)
    slow = defective_unit(design, 3, "tau")
    t = [b.tau_s / a.tau_s for a, b in zip(u.thermal.nodes, slow.thermal.nodes, strict=True)]
    assert max(t) == pytest.approx(DEFECT_TAU_FACTOR) and sorted(t)[-2] == pytest.approx(1.0)
    with pytest.raises(ValueError):
        defective_unit(design, 3, "nonsense")
