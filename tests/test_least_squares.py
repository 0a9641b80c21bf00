"""The lag-structure profile: plausible candidates preferred, whichever kinds exist."""

from __future__ import annotations

from fogsf.models.features import front_end_for
from fogsf.models.structures.least_squares import (
    MAX_NODE_SLOPE_PPM_PER_C,
    node_candidates,
    profile_effective_node,
)
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper


def test_profile_when_every_candidate_is_plausible() -> None:
    """A one-candidate grid whose fit is plausible (no implausible candidate at all): the
    profile returns it (this once raised KeyError, seen on a 26 h cycle log)."""
    cfg = paper(1.0, seed=4)
    cfg.profile.start_c, cfg.profile.stop_c = 0.0, 30.0
    log = simulate(cfg).log
    fe = front_end_for([log], 5.0, ())
    (tau, w), score = profile_effective_node([log], fe, grid=(1000.0,), leads=(0.0,))
    assert (tau, w) == (1000.0, 0.0) and score > 0


def test_profile_prefers_a_plausible_candidate() -> None:
    """The default gyro's SF moves at most ~13 ppm/C per node: the chosen structure's fit
    stays under the bound, although the grid holds implausible ones."""
    import numpy as np

    from fogsf.models.structures.least_squares import grid_data

    cfg = paper(1.0, seed=4)
    cfg.profile.start_c, cfg.profile.stop_c = 0.0, 30.0
    log = simulate(cfg).log
    fe = front_end_for([log], 5.0, ())
    node, _ = profile_effective_node([log], fe)
    data, y = grid_data([log], fe, (node[0],), None)
    cand = next(c for c in node_candidates(1, (node[0],)) if c.nodes[0] == node)
    coef, *_ = np.linalg.lstsq(cand.design(data[0].s), y, rcond=None)
    assert cand.max_node_slope(coef, data[0].s) <= MAX_NODE_SLOPE_PPM_PER_C
