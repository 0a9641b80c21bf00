"""Designs and units: a production line of one gyro design.

A design is a population gyro (`population.gyro_for_seed(design_seed)`: its thermal network,
node count, topology and SF law). Its units share all of that and differ in their
parameters, each drawn around the design's by the stated spreads (uniform, multiplicative,
independently per parameter):
- every node's time constant by +/- TAU_SPREAD (15 %) and self-heating by +/- HEAT_SPREAD;
- every SF factor's linear, quadratic and cubic coefficient by +/- SF_SPREAD (25 %);
- the bias's offset and its temperature terms by +/- BIAS_SPREAD (25 %);
- the SF hysteresis (a design that draws one) in strength and width by +/- HYST_SPREAD;
- the ARW by +/- ARW_SPREAD.
Unit `index` of design `design_seed` is drawn from the stream [design_seed, UNIT_STREAM,
index]: the same design seed and index give the same unit, whatever else was drawn. Unit 0
is a unit like any other (not the design itself).

`defective_unit` gives a unit unlike the line (for `fleet check`'s tests): one SF factor's
linear slope far off (x DEFECT_SLOPE_FACTOR), or one part's time constant far off
(x DEFECT_TAU_FACTOR).
"""

from __future__ import annotations

import copy

import numpy as np

from fogsf.sim.config import SimConfig
from fogsf.sim.population import gyro_for_seed

TAU_SPREAD = 0.15
HEAT_SPREAD = 0.15
SF_SPREAD = 0.25
BIAS_SPREAD = 0.25
HYST_SPREAD = 0.15
ARW_SPREAD = 0.15
UNIT_STREAM = 0xF1EE
DEFECT_STREAM = 0xDEFE
DEFECTS = ("slope", "tau")
DEFECT_SLOPE_FACTOR = 3.0
DEFECT_TAU_FACTOR = 2.5


def design_for_seed(design_seed: int) -> SimConfig:
    """The design: the population's gyro `design_seed` (docs/population.md)."""
    cfg = gyro_for_seed(design_seed)
    cfg.scenario = cfg.scenario.replace("population:", f"design{design_seed}:", 1)
    return cfg


def _vary(rng: np.random.Generator, value: float, spread: float, digits: int = 6) -> float:
    return float(f"{value * (1.0 + rng.uniform(-spread, spread)):.{digits}g}")


def unit_for(design_seed: int, index: int) -> SimConfig:
    """Unit `index` (>= 0) of design `design_seed`: the design's structure, its parameters
    drawn around the design's by the module's spreads."""
    if index < 0:
        raise ValueError(f"unit index must be >= 0, got {index}")
    cfg = copy.deepcopy(design_for_seed(design_seed))
    rng = np.random.default_rng([design_seed, UNIT_STREAM, index])
    for n in cfg.thermal.nodes:
        n.tau_s = _vary(rng, n.tau_s, TAU_SPREAD)
        n.self_heat_c = _vary(rng, n.self_heat_c, HEAT_SPREAD)
    for t in cfg.sf.terms:
        t.lin_ppm_per_c = _vary(rng, t.lin_ppm_per_c, SF_SPREAD)
        t.quad_ppm_per_c2 = _vary(rng, t.quad_ppm_per_c2, SF_SPREAD)
        t.cube_ppm_per_c3 = _vary(rng, t.cube_ppm_per_c3, SF_SPREAD)
    b = cfg.bias
    b.bias_dph = _vary(rng, b.bias_dph, BIAS_SPREAD)
    b.lin_dph_per_c = _vary(rng, b.lin_dph_per_c, BIAS_SPREAD)
    b.quad_dph_per_c2 = _vary(rng, b.quad_dph_per_c2, BIAS_SPREAD)
    b.cube_dph_per_c3 = _vary(rng, b.cube_dph_per_c3, BIAS_SPREAD)
    b.shupe_dph_per_c_per_min = _vary(rng, b.shupe_dph_per_c_per_min, BIAS_SPREAD)
    for e in cfg.effects:
        if e.name == "hysteresis":
            e.strength = _vary(rng, e.strength, HYST_SPREAD)
            e.params = {**e.params, "width_c": _vary(rng, e.params.get("width_c", 6.0),
                                                     HYST_SPREAD)}
    cfg.noise.arw_deg_per_sqrt_h = _vary(rng, cfg.noise.arw_deg_per_sqrt_h, ARW_SPREAD)
    cfg.scenario += f":unit{index}"
    return cfg


def defective_unit(design_seed: int, index: int, kind: str = "slope") -> SimConfig:
    """Unit `index` of the design with one defect (`DEFECTS`): "slope", the SF factor with
    the largest linear slope has it multiplied by DEFECT_SLOPE_FACTOR; "tau", the slowest
    internal part an SF factor reads has its time constant multiplied by DEFECT_TAU_FACTOR."""
    if kind not in DEFECTS:
        raise ValueError(f"defect must be one of {', '.join(DEFECTS)}, got {kind!r}")
    cfg = unit_for(design_seed, index)
    if kind == "slope":
        t = max(cfg.sf.terms, key=lambda t: abs(t.lin_ppm_per_c))
        t.lin_ppm_per_c *= DEFECT_SLOPE_FACTOR
    else:
        read = {name for t in cfg.sf.terms for name in t.nodes}
        parts = [n for n in cfg.thermal.nodes[2:] if n.name in read]
        slowest = max(parts, key=lambda n: n.tau_s)
        slowest.tau_s *= DEFECT_TAU_FACTOR
    cfg.scenario += f":defect-{kind}"
    return cfg
