"""The diagnosis as the JSON of docs/diagnose.md, a Markdown report with plots, and a short text.

JSON keys of the contract: base {rms_ppm, whiteness_p}, candidates [{effect, params,
heldout_rms_before_ppm, heldout_rms_after_ppm, gain_pct, evidence}], cause, unexplained,
extended_model. Added (documented, never replacing the contract's): base.heldout_rms_ppm,
base.noise_floor_ppm, base.params, base.drivers, base.correlations; per candidate
identifiable / significant / p_value / blocks_better / blocks; ambiguous (names that the
logs cannot tell apart); structure (whiteness and excess variance of the chosen model's
held-out residual, and remaining_pct: the share of the base's excess variance left);
causes (every significant cause in the order forward selection found them, `cause` its
first); per candidate confounded_with / separating_run (what it cannot be told from on
these logs, "base" included, and the run that would) and added_gain_pct (its held-out gain
over the causes before it); base.model_floor_ppm (added in quadrature to every window's
noise, see verdict.model_floor); simulation (distance of the base and extended simulations
to the logs).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.diagnose import design
from fogsf.diagnose.fits import Diagnosis
from fogsf.diagnose.stats import SMOOTH_WINDOWS


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _clean(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    if isinstance(v, float | np.floating):
        return _num(float(v))
    if isinstance(v, np.integer):
        return int(v)
    return v


def to_json(d: Diagnosis, extended_model: dict[str, Any],
            simulation: dict[str, Any] | None) -> dict[str, Any]:
    (tau1, tau2), _ = d.base.combo
    base_params = dict(zip(d.base.stack.names, (float(b) for b in d.base.fit.beta),
                           strict=True))
    base_params.update({"node1_tau_s": tau1, "node2_tau_s": tau2})
    drivers = [{
        "log": c.run.name, "source": c.driver.source, "tau_housing_s": c.driver.tau_housing_s,
        "tau_board_s": c.driver.tau_board_s, "power_on": c.power_on,
        "self_heat_housing_c": c.driver.self_heat_housing_c,
        "self_heat_board_c": c.driver.self_heat_board_c, "fit_rms_c": c.driver.rms_c,
    } for c in d.ctxs]
    cands = []
    for c in d.candidates:
        cands.append({
            "effect": c.name,
            "params": c.params,
            "heldout_rms_before_ppm": c.heldout_before,
            "heldout_rms_after_ppm": c.heldout_after,
            "gain_pct": c.gain_pct,
            "evidence": c.evidence,
            "identifiable": c.identifiable,
            "significant": c.significant,
            "p_value": c.p_value,
            "blocks_better": c.blocks_better,
            "blocks": c.blocks,
            "confounded_with": c.confounded_with,
            "separating_run": c.separating_run,
            "added_gain_pct": c.added_gain_pct,
        })
    out = {
        "base": {
            "rms_ppm": d.base_rms,
            "whiteness_p": d.base_whiteness_p,
            "heldout_rms_ppm": float(np.sqrt(np.mean(d.base.heldout**2))),
            "noise_floor_ppm": d.noise_floor_ppm,
            "model_floor_ppm": d.model_floor_ppm,
            "window_noise_ppm": d.window_noise_ppm,
            "window_s": d.window_s,
            "windows": int(d.y.shape[0]),
            "cv": d.cv_mode,
            "params": base_params,
            "drivers": drivers,
            "correlations": d.correlations,
        },
        "candidates": cands,
        "cause": d.cause,
        "causes": d.causes,
        "unexplained": d.unexplained,
        "extended_model": extended_model,
        "ambiguous": d.ambiguous,
        "structure": d.structure,
        "simulation": simulation,
        "skipped": d.skipped,
    }
    return _clean(out)


def summary_text(j: dict[str, Any]) -> str:
    b = j["base"]
    lines = [f"base model: in-sample RMS {b['rms_ppm']:.2f} ppm, held-out "
             f"{b['heldout_rms_ppm']:.2f} ppm, noise floor {b['noise_floor_ppm']:.2f} ppm "
             f"({b['windows']} windows of "
             f"{b['window_s']:g} s), whiteness p={b['whiteness_p']:.3g}",
             f"  noise floor = window noise {b['window_noise_ppm']:.2f} ppm (one log's is "
             f"what `fogsf inspect --window-s {b['window_s']:g}` reports) and the base's "
             f"resolution {b['model_floor_ppm']:.2f} ppm in quadrature"]
    lines.append(f"{'effect':18s} {'before':>7s} {'after':>7s} {'gain%':>6s}  evidence")
    for c in sorted(j["candidates"], key=lambda c: c["heldout_rms_after_ppm"] or 0.0):
        lines.append(f"{c['effect']:18s} {c['heldout_rms_before_ppm']:7.2f} "
                     f"{c['heldout_rms_after_ppm']:7.2f} {c['gain_pct']:6.1f}  {c['evidence']}")
    cause = j["cause"]
    if cause:
        for i, name in enumerate(j.get("causes") or [cause]):
            c = next(x for x in j["candidates"] if x["effect"] == name)
            ps = ", ".join(_fmt_param(k, v, c["params"].get(k + "_ci95"))
                           for k, v in c["params"].items() if not k.endswith("_ci95"))
            gain = (f"held-out RMS {c['heldout_rms_before_ppm']:.2f} -> "
                    f"{c['heldout_rms_after_ppm']:.2f} ppm, gain {c['gain_pct']:.1f}%"
                    if i == 0 else
                    f"held-out gain {c['added_gain_pct']:.1f}% over the causes before it")
            lines.append(f"{'cause' if i == 0 else 'and cause'}: {name} ({ps}; 95% intervals) "
                         f"{gain}")
        if j["unexplained"]:
            st = j["structure"]
            left = (f"{st.get('remaining_pct', 0.0):.0f}% of the structure remains"
                    if "variance" in st.get("flagged_by", ["variance"]) else
                    "the held-out residual is not white")
            lines.append(f"cause: {' + '.join(j.get('causes') or [cause])}; {left}: "
                         "unexplained beyond it")
    elif j["ambiguous"]:
        c = next(x for x in j["candidates"] if x["effect"] == j["ambiguous"][0])
        lines.append("cause: none named; confounded: " + ", ".join(j["ambiguous"])
                     + (f" (the run that would separate them: {c['separating_run']})"
                        if c.get("separating_run") else ""))
    else:
        lines.append("cause: none")
    st = j["structure"]
    lines.append(f"unexplained structure: {'yes' if j['unexplained'] else 'no'} (held-out "
                 f"whiteness p={st['whiteness_p']:.3g}, structure "
                 f"{100 * (st.get('structured_share') or 0.0):.0f}% of the residual's "
                 f"variance, {st.get('smoothed_rms_ppm') or 0.0:.2f} ppm RMS over "
                 f"{SMOOTH_WINDOWS}-window means; variance {st['excess_variance']:.2f}x noise)")
    for k in j.get("skipped") or []:
        lines.append(f"skipped: {k['effect']} in the {k['stage']}: {k['reason']}")
    s = j.get("simulation")
    if s and "rms_base_sim_ppm" in s:
        lines.append(f"simulation vs logs: base {s['rms_base_sim_ppm']:.2f} ppm -> extended "
                     f"{s['rms_extended_sim_ppm']:.2f} ppm RMS ({s['closer_pct']:.1f}% closer; "
                     f"noise floor {s['noise_floor_ppm']:.2f} ppm)")
    return "\n".join(lines)


def _fmt_param(k: str, v: object, ci: Sequence[float] | None = None) -> str:
    s = f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
    if ci:
        s += f" [{ci[0]:.4g}, {ci[1]:.4g}]"
    return s


def plot(d: Diagnosis, path: Path) -> None:
    """Held-out residual of the base and of the extended model vs time and temperature."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(9, 7))
    temp = np.concatenate([design.board(c) + design.T_REF_C for c in d.ctxs])
    t_h = np.concatenate([r.t_s for r in d.runs]) / 3600.0
    after_label = f"base + {d.cause}" if d.cause else "base (no cause named)"
    for ax, x, xl in ((axes[0], t_h, "time since power-on (h)"),
                      (axes[1], temp, "board temperature (C)")):
        for i, r in enumerate(d.runs):
            sel = d.run_ids == i
            tag = f" [{Path(r.name).name}]" if len(d.runs) > 1 else ""
            ax.plot(x[sel], d.base.heldout[sel], ".", color="0.6", ms=5,
                    label="base" + tag if ax is axes[0] else None)
            ax.plot(x[sel], d.extended.heldout[sel], ".", ms=5,
                    label=after_label + tag if ax is axes[0] else None)
        nf = d.noise_floor_ppm
        ax.axhspan(-nf, nf, color="tab:green", alpha=0.1)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(xl)
        ax.set_ylabel("held-out residual (ppm)")
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_title(f"SF residual per {d.window_s:g} s window, held out "
                      f"(green: +/- noise floor {d.noise_floor_ppm:.1f} ppm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown(j: dict[str, Any], d: Diagnosis, md_path: Path, config_path: str | None) -> str:
    png = md_path.with_name(md_path.stem + "_residual.png")
    plot(d, png)
    b = j["base"]
    out = ["# fogsf diagnose", "",
           "Logs: " + ", ".join(f"`{r.name}`" for r in d.runs), "",
           "## Base model", "",
           f"- windows: {b['windows']} of {b['window_s']:g} s; noise floor "
           f"{b['noise_floor_ppm']:.2f} ppm: the window noise {b['window_noise_ppm']:.2f} ppm "
           f"(`fogsf inspect --window-s {b['window_s']:g}`) and the base's resolution "
           f"{b['model_floor_ppm']:.2f} ppm in quadrature",
           f"- residual RMS {b['rms_ppm']:.2f} ppm in sample, {b['heldout_rms_ppm']:.2f} ppm "
           f"held out ({b['cv']} cross-validation); Ljung-Box whiteness p = "
           f"{b['whiteness_p']:.3g}",
           f"- internal nodes: tau1 = {b['params']['node1_tau_s']:g} s, tau2 = "
           f"{b['params']['node2_tau_s']:g} s (behind the housing)", ""]
    for dr in b["drivers"]:
        out.append(f"- `{dr['log']}`: driver from {dr['source']}, tau housing "
                   f"{dr['tau_housing_s']:g} s, tau board {dr['tau_board_s']:g} s, "
                   f"{'power-on' if dr['power_on'] else 'warm'} start")
    out += ["", "Correlation of the base residual with what an effect would follow "
            "(p on the effective sample size):", "",
            "| quantity | r | p | eta^2 (binned) | p |", "|---|---|---|---|---|"]
    for k, v in b["correlations"].items():
        out.append(f"| {k} | {v['r']:+.3f} | {v['p']:.3g} | {v['eta2']:.3f} | "
                   f"{v['eta_p']:.3g} |")
    out += ["", "## Candidates (held-out RMS, ppm)", "",
            "| effect | before | after | gain % | parameters | evidence |",
            "|---|---|---|---|---|---|"]
    for c in j["candidates"]:
        ps = "; ".join(_fmt_param(k, v, c["params"].get(k + "_ci95"))
                       for k, v in c["params"].items() if not k.endswith("_ci95"))
        out.append(f"| {c['effect']} | {c['heldout_rms_before_ppm']:.2f} | "
                   f"{c['heldout_rms_after_ppm']:.2f} | {c['gain_pct']:.1f} | {ps} | "
                   f"{c['evidence']} |")
    out += ["", "## Verdict", "", "```", summary_text(j), "```", ""]
    if config_path:
        out += [f"Extended model as a simulator configuration: `{config_path}` "
                f"(`fogsf simulate --config {config_path} --out sim.csv`).", ""]
    out += [f"![held-out residual before and after]({png.name})", ""]
    text = "\n".join(out)
    md_path.write_text(text, encoding="utf-8")
    return text
