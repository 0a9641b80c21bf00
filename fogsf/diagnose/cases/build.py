"""Planted-effect cases simulated (`diagnose.cases.planted` draws them): `build` gives a case's
logs and its truth. Strength is set as a multiple (drawn in [3, 20]) of the noise floor of the
part of the effect the base model cannot absorb: the RMS over windows of the base model's
residual on the noiseless output with the effect (profiled fit, the run's own noise weights).
An effect entirely absorbable by the base model is not an error of the base simulation, so
this is the only strength a diagnosis can be held to. Only the linear strength is scaled (for
`extra_lag`, its sensitivity in ppm/C; its time constant is drawn). The logs keep only what a
chamber log has: time, board thermometer, table rate, gyro, earth rate and the chamber air
(`chamber_c`); the simulator's truth columns are dropped.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from fogsf.diagnose import design, driver, profile_ls, runs
from fogsf.diagnose.cases import kinds as case_kinds
from fogsf.diagnose.cases.planted import CATALOGUE_EFFECTS, Case
from fogsf.logs.chamber_log import ChamberLog
from fogsf.sim.config import SimConfig
from fogsf.sim.effects import EFFECTS as SIM_EFFECTS
from fogsf.sim.gyro import simulate

WINDOW_S = 60.0
# starting strengths (the simulator's examples; extra_lag: its sensitivity in ppm/C)
EFFECT_INFO = {name: (4.0 if name == "extra_lag" else SIM_EFFECTS[name].example)
               for name in CATALOGUE_EFFECTS}


def _strip(log: ChamberLog, chamber: bool = True) -> ChamberLog:
    log.extra = {"chamber_c": log.extra["chamber_c"]} if chamber else {}
    return log


def ooc_signal(case: Case, t_s: np.ndarray) -> np.ndarray:
    """The out-of-catalogue SF term (ppm) per sample, unit amplitude."""
    p = case.params
    if case.name == "humidity":
        k = sum(1 for key in p if key.startswith("period"))
        x = sum(np.sin(2 * np.pi * t_s / p[f"period{i}_s"] + p[f"phase{i}"]) for i in range(k))
        return np.asarray(x, dtype=np.float64) / k
    if case.name == "supply_step":
        return (t_s >= p["at_fraction"] * t_s[-1]).astype(np.float64)
    if case.name == "periodic":
        return np.sin(2 * np.pi * t_s / p["period_s"] + p["phase"])
    raise ValueError(case.name)


def _with_sf(log: ChamberLog, sf_ppm: np.ndarray) -> ChamberLog:
    out = copy.copy(log)
    truth = log.table_rate_dps + log.earth(None)
    out.gyro_dps = log.gyro_dps + truth * sf_ppm * 1e-6
    return out


def base_residual(logs: list[ChamberLog], sigma: list[np.ndarray]) -> np.ndarray:
    """Residual per window of the base model (profiled, no cross-validation) fitted to logs
    with the given per-window noise weights."""
    rs = [runs.load_run(log, WINDOW_S, None) for log in logs]
    rates = np.unique(np.round(np.concatenate([r.rate for r in rs]), 6))
    ctxs = []
    for r, s in zip(rs, sigma, strict=True):
        r.sigma_ppm = s
        drv = driver.identify(r.log.time_s, r.log.temp_c, r.log.extra.get("chamber_c"))
        ctxs.append(design.RunContext(r, drv, drv.power_on, rates.shape[0] > 1))
    y = np.concatenate([r.y_ppm for r in rs])
    w = 1.0 / np.concatenate(sigma) ** 2
    st = profile_ls.build(ctxs, None)
    fit = profile_ls.solve(st, y, w, np.arange(y.shape[0]))
    return y - profile_ls.predict(st, fit)


def _calibrate(single: SimConfig, target: float, log0: ChamberLog, sigma: np.ndarray,
               r0: np.ndarray, fixed: bool = False) -> tuple[float, float]:
    """Scale the one effect of `single` so that its visible part (the base residual it adds,
    RMS over windows) is `target`: (strength, visible reached). `fixed`: an effect the base
    absorbs whole (asymmetry at one |rate|) is planted at `target` ppm as it is."""
    e = single.effects[0]
    key = "sens_ppm_per_c" if e.name == "extra_lag" else None

    def visible(scale: float) -> float:
        if key:
            e.params[key] = scale
        else:
            e.strength = scale
        ideal = simulate(single).ideal_dps
        return float(np.sqrt(np.mean(
            (base_residual([_noiseless(log0, ideal)], [sigma]) - r0) ** 2)))

    if fixed:
        return target, visible(target)
    # the base's absorption is not linear in the strength (its time constants are
    # profiled): a few secant steps from the simulator's example strength
    scale = EFFECT_INFO[e.name]
    for _ in range(4):
        v = visible(scale)
        if abs(v - target) < 0.05 * target:
            break
        scale *= target / max(v, 1e-12)
    return scale, visible(scale)


def _noiseless(log: ChamberLog, ideal: np.ndarray) -> ChamberLog:
    q = copy.copy(log)
    q.gyro_dps = ideal
    return q


def build(case: Case) -> tuple[list[ChamberLog], dict[str, Any]]:
    """Simulate a case: the logs and the truth (what was planted, with its final strength)."""
    cfg = case.config
    if case.kind == "ramp_only":
        res = simulate(cfg)
        log = _strip(res.log)
        k = int(case.crop_s / cfg.dt_s)
        return [log.slice(k, len(log))], {"effect": case.name, **case.params}
    if case.kind == "null":
        return [_strip(simulate(cfg).log, case.chamber)], {"effect": None}
    if case.kind == "effect" and case.variant == "coil_pair":
        return _build_coil_bias(case)
    if case.kind in ("effect", "short_soak", "two"):
        plain = copy.deepcopy(cfg)
        plain.effects = []
        base_res = simulate(plain)
        log0 = _strip(base_res.log, case.chamber)
        sigma = runs.load_run(log0, WINDOW_S, None).sigma_ppm
        floor = float(np.sqrt(np.mean(sigma**2)))
        r0 = base_residual([_noiseless(log0, base_res.ideal_dps)], [sigma])
        multiples = [case.multiple] + ([case.params["multiple2"]] if case.kind == "two" else [])
        final = copy.deepcopy(cfg)
        reached = []
        for e, mult in zip(final.effects, multiples, strict=True):
            single = copy.deepcopy(cfg)
            single.effects = [copy.deepcopy(e)]
            keep = e.name == "hysteresis"  # planted at the population's strength
            scale, got = _calibrate(single, e.strength if keep else mult * floor, log0, sigma,
                                    r0, fixed=case.variant == "one" or keep)
            reached.append(got / floor)
            if e.name == "extra_lag":
                e.params["sens_ppm_per_c"] = scale
            else:
                e.strength = scale
        case.multiple_reached = reached[0]
        if case.kind == "two":
            both = {"effects": [e.name for e in final.effects],
                    **{f"{e.name}.strength": e.strength for e in final.effects}}
            case.params = {**case.params, **both}  # type: ignore[dict-item]  # names the effects
            return [_strip(simulate(final).log, case.chamber)], {"effect": None, **both}
        e = final.effects[0]
        if e.name == "extra_lag":
            truth = {"tau_s": e.strength, "sens_ppm_per_c": e.params["sens_ppm_per_c"],
                     "strength": e.strength}
        else:
            truth = {"strength": e.strength, **e.params}
        if e.name == "temp_rate":
            truth["housing_ppm_per_c"] = housing_coupling(final, e.strength)
        if e.name == "hysteresis":
            truth["height_ppm"] = e.strength * e.params["width_c"]
        if e.name == "bias_shupe":
            truth["housing_dph_per_c"] = housing_coupling(final, e.strength)
            coils = [n for n in final.thermal.nodes if n.name.startswith("coil")]
            truth["coils_behind_housing"] = float(all(n.parent == "housing" for n in coils))
        case.params = truth
        return [_strip(simulate(final).log, case.chamber)], {"effect": case.name, **truth}
    # out of catalogue
    res = simulate(cfg)
    log = _strip(res.log, case.chamber)
    sigma = runs.load_run(log, WINDOW_S, None).sigma_ppm
    floor = float(np.sqrt(np.mean(sigma**2)))
    hop = case.name == "mode_hop"  # planted at its own step in ppm, not at a multiple
    x = case_kinds.mode_hop_signal(case.params, res) if hop else ooc_signal(case, log.time_s)
    ideal = _noiseless(log, res.ideal_dps)
    unit = np.sqrt(np.mean((base_residual([_with_sf(ideal, x)], [sigma])
                            - base_residual([ideal], [sigma])) ** 2))
    amp = 1.0 if hop else case.multiple * floor / max(float(unit), 1e-12)
    case.multiple_reached = float(amp * unit / floor)
    case.params = {**case.params, "amplitude_ppm": amp}
    return [_with_sf(log, amp * x)], {"effect": None, "ooc": case.name, "amplitude_ppm": amp}


def _build_coil_bias(case: Case) -> tuple[list[ChamberLog], dict[str, Any]]:
    """`bias_drift:coil_pair` (case_kinds): the coil bias's slope calibrated to the case's
    multiple of the floor over the log pair."""
    plain = case_kinds.pair_configs(case.config)
    for c in plain:
        c.bias.lin_dph_per_c = 0.0
    res0 = [simulate(c) for c in plain]
    logs0 = [_strip(r.log, case.chamber) for r in res0]
    sigma = [runs.load_run(log, WINDOW_S, None).sigma_ppm for log in logs0]
    floor = float(np.sqrt(np.mean(np.concatenate(sigma) ** 2)))
    r0 = base_residual([_noiseless(log, r.ideal_dps) for log, r in zip(logs0, res0,
                                                                       strict=True)], sigma)

    def visible(slope: float) -> float:
        quiet = []
        for c, log in zip(plain, logs0, strict=True):
            c.bias.lin_dph_per_c = slope
            quiet.append(_noiseless(log, simulate(c).ideal_dps))
        return float(np.sqrt(np.mean((base_residual(quiet, sigma) - r0) ** 2)))

    slope, got = case_kinds.calibrate_coil_bias(case.multiple * floor, visible)
    case.config.bias.lin_dph_per_c = slope
    case.multiple_reached = got / floor
    case.params = {"strength": slope,
                   "node": case.config.bias.node}  # type: ignore[dict-item]  # the node by name
    logs = [_strip(simulate(c).log, case.chamber) for c in case_kinds.pair_configs(case.config)]
    return logs, {"effect": case.name, **case.params}


def housing_coupling(cfg: SimConfig, strength: float) -> float:
    """A planted dT/dt term's coupling to the housing (ppm per C): the simulator's term is
    strength * d(mean of the coil nodes)/dt in C/min, and a coil node right behind the
    housing has dT/dt = (housing - T) / tau, so the term holds the housing with strength *
    60 * mean over the coil nodes of 1/tau (0 for a node behind another internal node).
    This is what a diagnosis can pin (catalogue.housing_coupling): the base model holds
    every lagged node but not the housing's lead over the board."""
    coils = [n for n in cfg.thermal.nodes if n.name.startswith("coil")]
    return strength * 60.0 * sum(1.0 / n.tau_s for n in coils if n.parent == "housing") \
        / len(coils)
