"""The paper-scenario figure: internal temperatures (paper Fig. 3) and the SF error against
the board temperature at two ramp rates (paper Fig. 7). matplotlib is imported inside."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.measure.metrics import sf_error_ppm
from fogsf.logs.measure.sf_reference import reference_sf
from fogsf.logs.measure.windows import sf_windows
from fogsf.sim.config import SimConfig
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.thermal import effective_tau_s

NODE_LABELS = {"board": "board thermometer", "preamp": "preamp board",
               "coil_inner": "coil inner", "coil_outer": "coil outer", "source": "light source",
               "housing": "housing"}


def runs_for_plot(cfg: SimConfig, result: SimResult | None = None,
                  rates: tuple[float, ...] = (0.5, 1.0)) -> list[SimResult]:
    """The run itself and, for a ramp, the same gyro at the paper's other ramp rates."""
    if result is None:
        result = simulate(cfg)
    if cfg.profile.kind != "ramp":
        return [result]
    out = []
    for r in rates:
        if abs(r - cfg.profile.rate_c_per_min) < 1e-12:
            out.append(result)
        else:
            c = copy.deepcopy(cfg)
            c.profile.rate_c_per_min = r
            out.append(simulate(c))
    if all(abs(r - cfg.profile.rate_c_per_min) > 1e-12 for r in rates):
        out.append(result)
    return out


def plot_runs(runs: list[SimResult], path: str | Path, window_s: float = 100.0) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    temp_run = max(runs, key=lambda r: r.config.profile.rate_c_per_min)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=90)
    t_min = temp_run.log.time_s / 60.0
    ax1.plot(t_min, temp_run.nodes["chamber"], color="0.6", lw=1, ls="--", label="chamber air")
    cfg = temp_run.config
    for n in cfg.thermal.nodes:
        if n.name == "housing":
            continue
        lw = 2.0 if n.name == cfg.thermal.board_node else 1.2
        ax1.plot(t_min, temp_run.nodes[n.name], lw=lw,
                 label=f"{NODE_LABELS.get(n.name, n.name)} "
                       f"(lag {effective_tau_s(cfg.thermal, n.name) / 60:.1f} min)")
    p = cfg.profile
    what = f"{p.rate_c_per_min:g} C/min ramp" if p.kind == "ramp" else f"{p.kind} profile"
    ax1.set_title(f"Temperatures inside the gyro ({what}, {cfg.thermal.start} start)",
                  fontsize=10)
    ax1.set_xlabel("time since start (min)")
    ax1.set_ylabel("temperature (C)")
    ax1.grid(alpha=0.3)
    ax1.legend(fontsize=7.5, loc="best")

    colors = ["tab:blue", "tab:red", "tab:green", "tab:purple"]
    for i, run in enumerate(sorted(runs, key=lambda r: r.config.profile.rate_c_per_min)):
        w = sf_windows(run.log, window_s)
        try:
            err = sf_error_ppm(w, reference_sf(w))
        except UserError:
            err = (w.sf_ratio / np.median(w.sf_ratio) - 1.0) * 1e6
            ax2.set_ylabel("SF error vs median (ppm)")
        label = (f"{run.config.profile.rate_c_per_min:g} C/min" if p.kind == "ramp"
                 else f"{p.kind}")
        ax2.plot(w.temp_c, err, "o-", ms=2.5, lw=1, color=colors[i % len(colors)], label=label)
    ax2.axhline(0, color="0.5", lw=0.8)
    ax2.axvline(20, color="0.5", lw=0.8, ls=":")
    ax2.set_title(f"SF error vs board temperature ({window_s:g} s windows, ref. SF at 20 C)",
                  fontsize=10)
    ax2.set_xlabel("board thermometer (C)")
    if not ax2.get_ylabel():
        ax2.set_ylabel("SF error (ppm)")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    effects = ", ".join(f"{e.name}={e.strength:g}" for e in cfg.effects)
    fig.suptitle(f"fogsf simulate: scenario {cfg.scenario}"
                 + (f", effects {effects}" if effects else ""), fontsize=11)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
