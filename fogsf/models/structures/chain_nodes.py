"""Chain nodes: physics nodes that sit behind another node (a two-stage filter of T).

A gyro's inner parts (a coil's inner layers behind its outer ones, a source behind the
housing) see the board temperature T through two thermal stages, not one: a lag of a lag.
The firmware's front end filters T only, but a chain of two distinct first-order lags is
exactly a weighted sum of the two lags in a star (partial fractions, in the discrete filter
the firmware runs, primed alike), so a chain node is one feature row over two of the front
end's lags: no extension of the stream contract.

For the contract's filter y += a (x - y) (pole p = 1 - a), with a, b the two stages'
alphas:  chain(T) = w_a lag_a(T) + w_b lag_b(T),  w_a = b p_a / (p_a - p_b),
w_b = -a p_b / (p_a - p_b)  (w_a + w_b = 1). The stages' time constants are kept at least
CHAIN_MIN_RATIO apart so that the weights stay small (float32 features lose nothing).

The SF law over [T, chain nodes] is the physics nodes' quadratic with every cross term and a
cube of T (`physics_nodes.node_design`); the four (or two) time constants are identified by
the same variable projection (`node_fit.varpro`) from a grid start.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from fogsf.models.features import FeatureSpec
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import lag_alpha, ridge_fit, varpro
from fogsf.models.structures.physics_nodes import (
    NODE_LAMBDA,
    TAU_MAX_S,
    TAU_MIN_S,
    NodeTemperatures,
    node_design,
)

Chain = tuple[float, float]  # (tau of the first stage, tau of the second), seconds

CHAIN_MIN_RATIO = 1.5  # the slower stage's tau over the faster's, at least
CHAIN_MAX_TAU_S = 4.0 * TAU_MAX_S  # the slower stage's tau, at most
START_GRID_S = TAU_GRID_S[::2]  # the grid the fit starts from: 60 s .. 7200 s, 6 points


def chain_weights(chain: Chain, step_s: float) -> tuple[float, float]:
    """(w_a, w_b): chain(T) = w_a lag(T, tau_a) + w_b lag(T, tau_b) at one update per
    step_s (module docstring)."""
    a, b = lag_alpha(chain[0], step_s), lag_alpha(chain[1], step_s)
    pa, pb = 1.0 - a, 1.0 - b
    return b * pa / (pa - pb), -a * pb / (pa - pb)


def chain_z(nodes: NodeTemperatures, chains: tuple[Chain, ...]) -> np.ndarray:
    """[T, chain_1, ...], normalised as `NodeTemperatures.z`."""
    cols = [nodes.z(())[:, 0]]
    for ch in chains:
        wa, wb = chain_weights(ch, nodes.step_s)
        cols.append(wa * nodes.lag(ch[0]) + wb * nodes.lag(ch[1]))
    return np.column_stack(cols)


def chain_spec(chains: tuple[Chain, ...], step_s: float) -> FeatureSpec:
    """Features T and one row per chain over its two lags (the front end's filters are
    every chain's two time constants, in order)."""
    taus = tuple(float(t) for ch in chains for t in ch)
    width = 1 + len(taus)
    rows = [tuple(1.0 if j == 0 else 0.0 for j in range(width))]
    for k, ch in enumerate(chains):
        wa, wb = chain_weights(ch, step_s)
        row = [0.0] * width
        row[1 + 2 * k], row[2 + 2 * k] = wa, wb
        rows.append(tuple(row))
    names = ("T",) + tuple(f"chain(T,{a:.0f}s,{b:.0f}s)" for a, b in chains)
    return FeatureSpec(taus, tuple(rows), names)


def node_taus(chains: tuple[Chain, ...]) -> tuple[float, ...]:
    """One time constant per node (the slower stage): what `physics_nodes` keys a node by."""
    return tuple(float(ch[1]) for ch in chains)


def _chains_of(theta: np.ndarray) -> tuple[Chain, ...]:
    """theta = [log tau_a, log ratio] per node -> chains, the slower stage capped."""
    out = []
    for k in range(theta.size // 2):
        ta = math.exp(float(theta[2 * k]))
        tb = min(ta * math.exp(float(theta[2 * k + 1])), CHAIN_MAX_TAU_S)
        out.append((ta, max(tb, ta * CHAIN_MIN_RATIO)))
    return tuple(out)


def identify_chains(nodes: NodeTemperatures, y: np.ndarray, n_nodes: int,
                    rows: np.ndarray | None = None, lam: float | None = None
                    ) -> tuple[Chain, ...]:
    """The chains' time constants, ordered by their slower stage: the best combination of
    START_GRID_S pairs by the ridge fit's profile, refined by variable projection on
    (log tau_a, log tau_b / tau_a)."""
    lam = NODE_LAMBDA if lam is None else lam
    sel = np.arange(y.size) if rows is None else np.asarray(rows)
    ys = np.asarray(y, dtype=np.float64)[sel]

    def design_of(chains: tuple[Chain, ...]) -> np.ndarray:
        return node_design(chain_z(nodes, chains)[sel], node_taus(chains))

    grid_pairs = [(a, b) for a, b in itertools.combinations(START_GRID_S, 2)
                  if b >= CHAIN_MIN_RATIO * a]
    best: tuple[float, tuple[Chain, ...]] | None = None
    for combo in itertools.combinations(grid_pairs, n_nodes):
        sse = ridge_fit(design_of(combo), ys, lam).sse
        if best is None or sse < best[0]:
            best = (sse, combo)
    assert best is not None
    theta0 = np.array([v for a, b in best[1] for v in (math.log(a), math.log(b / a))])
    lo = np.tile([math.log(TAU_MIN_S), math.log(CHAIN_MIN_RATIO)], n_nodes)
    hi = np.tile([math.log(TAU_MAX_S), math.log(CHAIN_MAX_TAU_S / TAU_MIN_S)], n_nodes)
    vp = varpro(lambda th: design_of(_chains_of(th)), ys, theta0, lo, hi, lam)
    return tuple(sorted(_chains_of(vp.theta), key=lambda ch: ch[1]))
