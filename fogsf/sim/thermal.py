"""The thermal network: chamber air -> housing -> board, preamp, coil inner/outer, source.

Each node obeys tau * dT/dt = T_parent + q * p(t) - T, a first-order lag behind its parent
with a self-heating rise q (the node's equilibrium excess over its parent while powered;
p(t) = 1 once the gyro is on). Inputs are taken linear between samples (first-order hold),
and the lag is discretised exactly for that input, so the result does not depend on how
finely the input is sampled beyond its own shape, and a 3-hour 10 Hz run takes milliseconds.

Start modes: "warm" (the paper's hot start: every node at its powered equilibrium with the
chamber's first temperature) and "power-on" (every node at the chamber's first temperature,
self-heating switched on at t=0, so the gyro warms up over the first tens of minutes).
"""

from __future__ import annotations

import numpy as np

from fogsf.sim.config import NodeConfig, ThermalConfig
from fogsf.sim.lag import first_order_lag


def equilibrium(nodes: list[NodeConfig], chamber_c: float, powered: bool = True
                ) -> dict[str, float]:
    """Steady-state node temperatures with the chamber held at chamber_c."""
    temps: dict[str, float] = {"chamber": chamber_c}
    for n in nodes:
        temps[n.name] = temps[n.parent] + (n.self_heat_c if powered else 0.0)
    del temps["chamber"]
    return temps


def network(chamber_c: np.ndarray, cfg: ThermalConfig, dt_s: float,
            initial: dict[str, float] | None = None,
            power: np.ndarray | float = 1.0) -> dict[str, np.ndarray]:
    """Every node's temperature history for a chamber temperature history.

    initial: node temperatures at t=0 (default: from cfg.start, "warm" or "power-on");
    power: the self-heating fraction p(t) (scalar or per sample; 1 = powered).
    Returns {"chamber": chamber_c, node name: temperature, ...} in network order.
    """
    chamber_c = np.asarray(chamber_c, dtype=np.float64)
    if initial is None:
        initial = equilibrium(cfg.nodes, float(chamber_c[0]), powered=cfg.start == "warm")
    p = np.broadcast_to(np.asarray(power, dtype=np.float64), chamber_c.shape)
    out: dict[str, np.ndarray] = {"chamber": chamber_c}
    for n in cfg.nodes:
        drive = out[n.parent] + n.self_heat_c * p
        out[n.name] = first_order_lag(drive, n.tau_s, dt_s, initial[n.name])
    return out


def effective_tau_s(cfg: ThermalConfig, name: str) -> float:
    """Sum of the time constants from the chamber to a node: its delay on a steady ramp."""
    by_name = {n.name: n for n in cfg.nodes}
    total = 0.0
    while name != "chamber":
        total += by_name[name].tau_s
        name = by_name[name].parent
    return total
