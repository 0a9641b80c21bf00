"""Chain nodes (a two-stage filter of T): the partial fractions that carry a chain through
the front end's star of lags, and their identification by the physics fit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_physics_nodes import STEP_S, _program

from fogsf.models import reference
from fogsf.models.structures.chain_nodes import (
    CHAIN_MIN_RATIO,
    chain_spec,
    chain_weights,
    chain_z,
    identify_chains,
    node_taus,
)
from fogsf.models.structures.node_fit import discrete_lag, lag_alpha
from fogsf.models.structures.physics_nodes import NodeTemperatures, fit_coefficients, identify_taus


@pytest.mark.parametrize("chain", [(60.0, 90.0), (300.0, 1200.0), (2000.0, 14000.0)])
def test_a_chain_is_two_lags_of_the_front_end(chain: tuple[float, float]) -> None:
    """lag(lag(T, a), b) = w_a lag(T, a) + w_b lag(T, b), both primed with T[0]; the feature
    row of `chain_spec` over the firmware's float32 lags gives the same to float32 rounding."""
    x = _program(3000)
    cascade = discrete_lag(discrete_lag(x, lag_alpha(chain[0], STEP_S)),
                           lag_alpha(chain[1], STEP_S))
    wa, wb = chain_weights(chain, STEP_S)
    assert wa + wb == pytest.approx(1.0)
    star = wa * discrete_lag(x, lag_alpha(chain[0], STEP_S)) \
        + wb * discrete_lag(x, lag_alpha(chain[1], STEP_S))
    assert np.max(np.abs(star - cascade)) < 1e-9
    spec = chain_spec((chain,), STEP_S)
    alphas = np.array([lag_alpha(t, STEP_S) for t in spec.taus_s], np.float32)
    s = np.column_stack([x, reference.lag_filters(x.astype(np.float32), alphas)])
    z = s @ spec.matrix().T
    assert np.allclose(z[:, 0], x) and np.max(np.abs(z[:, 1] - cascade)) < 1e-3


def test_identify_chains_finds_a_planted_chain() -> None:
    """SF error from a node two stages behind the board (250 s, then 1500 s) through a
    quadratic: the fit finds both stages and leaves the noise; a first-order node does not
    fit it as well."""
    t = _program()
    nodes = NodeTemperatures([t], STEP_S)
    z = chain_z(nodes, ((250.0, 1500.0),))
    truth = 20.0 + 400.0 * z[:, 1] + 120.0 * z[:, 1] ** 2 - 50.0 * z[:, 0]
    y = truth + np.random.default_rng(4).normal(0.0, 0.5, t.size)
    (chain,) = identify_chains(nodes, y, 1, lam=1e-8)
    assert chain[0] == pytest.approx(250.0, rel=0.1) and chain[1] == pytest.approx(1500.0,
                                                                                    rel=0.1)
    assert chain[1] >= CHAIN_MIN_RATIO * chain[0]
    fit = fit_coefficients(chain_z(nodes, (chain,)), y, node_taus((chain,)), lam=1e-8)
    assert math.sqrt(np.mean((fit.predict(chain_z(nodes, (chain,))) - truth) ** 2)) < 0.3
    (tau,) = identify_taus(nodes, y, 1, lam=1e-8)
    star = fit_coefficients(nodes.z((tau,)), y, (tau,), lam=1e-8)
    assert math.sqrt(np.mean((star.predict(nodes.z((tau,))) - truth) ** 2)) > 1.0
