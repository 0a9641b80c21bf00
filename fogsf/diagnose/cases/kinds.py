"""Two planted kinds beside the catalogue's single effects (`diagnose.cases.planted` draws and
judges them; their ranges are here):

- `bias_drift:coil_pair`, a bias drifting with the coil temperature under a reversing table
  without chamber air, as a log pair: the gyro's own bias moved onto its first coil node
  (`fogsf.sim.population`'s internal parts), its slope calibrated like the catalogue's
  effects (3-20x the noise floor of the part the base cannot absorb); the table reverses
  +/- 5-20 deg/s every 120-240 s (`programs.table`, "alternating"); the chamber
  program is `draw`'s for bias_drift (a cycle: up 30-45 C and back, 1-2 C/min, 15-25 min
  soaks) run as a log pair: the up run and the down run, each a warm start with a soak at
  both ends (`pair_configs`); neither keeps `chamber_c`. Right when `bias_drift` is named
  (any form) with its slope within 30 % and nothing else.
- `ooc:mode_hop`, an SF step with hysteresis (a source mode hop): STEP_PPM (20-60 ppm) added
  to the SF once the source node passes T_up going up, taken away once it falls below T_up -
  gap going down (gap over GAP_C, 3-8 C), T_up at 30-70 % of the cycle's span above its
  start; on `draw`'s cycle program (up and back), constant or alternating table, half the
  logs without `chamber_c`. Out of the catalogue: right when no cause is named and the
  structure is reported unexplained; a step whose visible part (the RMS of the base residual
  it adds) stays under MODE_HOP_MIN_VISIBLE x the noise floor is not held to the report
  (right with no cause named).
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.gyro import SimResult

STEP_PPM = (20.0, 60.0)
GAP_C = (3.0, 8.0)
T_UP_FRACTION = (0.3, 0.7)
# under this visible part (x the floor) a 1.5-2 h log's residual cannot be told from a
# correct model's at verdict.WHITE_P (benchmarks/probes/README.md, "Diagnose whiteness
# threshold")
MODE_HOP_MIN_VISIBLE = 1.0


def coil_node(cfg: SimConfig) -> str:
    """The gyro's first coil node (every population gyro has one)."""
    return next(n.name for n in cfg.thermal.nodes if n.name.startswith("coil"))


def calibrate_coil_bias(target: float, visible: Callable[[float], float]
                        ) -> tuple[float, float]:
    """The coil bias's slope (deg/h per C) whose visible part `visible(slope)` is `target`
    (ppm RMS): a few secant steps, as `build._calibrate` (the base's absorption is not
    linear in the slope, its time constants being profiled). Returns (slope, visible part
    reached)."""
    slope = 0.05  # deg/h per C: 1.4 ppm per C at 10 deg/s
    for _ in range(4):
        got = visible(slope)
        if abs(got - target) < 0.05 * target:
            break
        slope *= target / max(got, 1e-12)
    return slope, visible(slope)


def pair_configs(cfg: SimConfig) -> list[SimConfig]:
    """A log pair from `cfg`'s cycle program (start_c to stop_c at rate_c_per_min, soaks
    soak_s): an up run and a down run, each a warm start (every node at equilibrium) with a
    soak at both ends, with their own simulator seeds."""
    p = cfg.profile
    out = []
    for i, levels in enumerate(([p.start_c, p.stop_c], [p.stop_c, p.start_c])):
        c = copy.deepcopy(cfg)
        c.seed = cfg.seed + i
        c.profile = ProfileConfig(kind="steps", levels_c=list(levels),
                                  rate_c_per_min=p.rate_c_per_min, soak_s=p.soak_s)
        out.append(c)
    return out


def draw_mode_hop(rng: np.random.Generator, p: ProfileConfig) -> dict[str, float]:
    """The mode hop's parameters for a cycle program `p` (start_c to stop_c and back)."""
    lo, hi = float(p.start_c), float(p.stop_c)
    t_up = lo + float(rng.uniform(*T_UP_FRACTION)) * (hi - lo)
    return {"step_ppm": float(rng.uniform(*STEP_PPM)), "t_up_c": t_up,
            "gap_c": float(rng.uniform(*GAP_C))}


def mode_hop_signal(params: dict[str, float], res: SimResult) -> np.ndarray:
    """The mode hop's SF term (ppm) per sample: a relay of the source node's temperature,
    on above t_up_c, off below t_up_c - gap_c, starting off."""
    src = res.nodes.get("source")
    if src is None:  # a gyro without a source node: its first internal one
        src = res.nodes[res.config.thermal.nodes[2].name]
    x = np.asarray(src, dtype=np.float64)
    up, down = params["t_up_c"], params["t_up_c"] - params["gap_c"]
    state = np.zeros(x.shape)
    on = False
    # the relay changes state rarely: find the crossings, not a loop over samples
    i = 0
    while i < x.shape[0]:
        nxt = np.flatnonzero(x[i:] <= down) if on else np.flatnonzero(x[i:] >= up)
        j = x.shape[0] if nxt.size == 0 else i + int(nxt[0])
        state[i:j] = 1.0 if on else 0.0
        on = not on
        i = j
    return params["step_ppm"] * state
