"""Scale factor from the physics of a digital closed-loop FOG, and the bias.

K = 2*pi*L*D / (Km * K_DA * lambda * c)   (paper eq. 2)

L, D: coil length and diameter (grow with the coil temperature); lambda: the source's mean
wavelength (moves with the source temperature); Km: the Y-waveguide's modulation
coefficient; K_DA: the D/A converter and driver gain. Each factor's relative change is a
quadratic (or cubic) in its own temperature (a weighted mean of node temperatures), and the SF error
is the exact product (1+eL)(1+eD) / ((1+eKm)(1+eDA)(1+elambda)) - 1, in ppm vs nominal.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import cast

import numpy as np

from fogsf.sim.config import SF_FACTORS, BiasConfig, ScaleFactorConfig, SFTermConfig


def term_temperature(nodes: Mapping[str, np.ndarray], term: SFTermConfig) -> np.ndarray:
    """The weighted mean temperature a factor sees."""
    return cast(np.ndarray,  # term.nodes is never empty (sim.config checks): an array
                sum(w * np.asarray(nodes[name], dtype=np.float64)
                    for name, w in term.nodes.items()))


def factor_change_ppm(temp_c: np.ndarray, term: SFTermConfig) -> np.ndarray:
    """Relative change of one factor (ppm) at temperature temp_c."""
    d = np.asarray(temp_c, dtype=np.float64) - term.ref_c
    out = term.lin_ppm_per_c * d + term.quad_ppm_per_c2 * d * d
    if term.cube_ppm_per_c3:
        out = out + term.cube_ppm_per_c3 * d * d * d
    return out


def sf_error_ppm(nodes: Mapping[str, np.ndarray], cfg: ScaleFactorConfig) -> np.ndarray:
    """SF error vs nominal (ppm) from node temperatures (arrays of one length)."""
    ratio: np.ndarray | float = 1.0
    for term in cfg.terms:
        e = factor_change_ppm(term_temperature(nodes, term), term) * 1e-6
        ratio = ratio * (1.0 + e) ** SF_FACTORS[term.factor]
    shape = np.shape(next(iter(nodes.values())))
    return np.broadcast_to((np.asarray(ratio) - 1.0) * 1e6 + cfg.offset_ppm, shape).copy()


def sf_contributions_ppm(nodes: Mapping[str, np.ndarray], cfg: ScaleFactorConfig
                         ) -> dict[str, np.ndarray]:
    """Each term's own first-order contribution to the SF error (ppm), by term name."""
    return {t.name: SF_FACTORS[t.factor] * factor_change_ppm(term_temperature(nodes, t), t)
            for t in cfg.terms}


def bias_dps(nodes: Mapping[str, np.ndarray], cfg: BiasConfig, dt_s: float = 0.1
             ) -> np.ndarray:
    """Bias (deg/s) from the temperature of cfg.node: its polynomial and the Shupe term
    (the node's rate of change, C/min, samples dt_s apart; none without it)."""
    t = np.asarray(nodes[cfg.node], dtype=np.float64)
    d = t - cfg.ref_c
    dph = (cfg.bias_dph + cfg.lin_dph_per_c * d + cfg.quad_dph_per_c2 * d * d
           + cfg.cube_dph_per_c3 * d * d * d)
    if cfg.shupe_dph_per_c_per_min and t.size > 1:
        dph = dph + cfg.shupe_dph_per_c_per_min * np.gradient(t, dt_s) * 60.0
    return dph / 3600.0
