"""The fitted model as a simulator configuration, and how close its simulation comes to the
measured logs.

The base model's pieces map onto the simulator's (fogsf.sim.config):
- driver identified from the chamber air -> nodes `housing` (tau_h) and `board` (tau_b, its
  self-heating); without a chamber column the chamber program is the board thermometer
  itself and both lags are zero;
- internal nodes `node1` (tau1) and `node2` (tau2), children of the housing; their unseen
  self-heating transients after a power-on (the base's exp(-t/tau) columns) become two
  `warmup` entries with tau1 and tau2, listed before the cause (a node's own self-heating
  and an SF start-up transient with its time constant are one and the same signature);
- each of board/node1/node2: one SF term (factor L, exponent +1) with the fitted linear
  and quadratic coefficients about 20 C; the intercept -> sf.offset_ppm;
- constant bias (when the rate varies) -> bias.bias_dph;
- the named cause -> one entry of `effects`, in the simulator's own units; a cause on the
  coil's temperature (COIL_EFFECTS: the simulator takes the mean of the nodes named coil*)
  brings its coil as fitted: temp_rate's and bias_shupe's two layers, hysteresis's one
  lagged node, children of the housing. A cause the configuration still cannot carry (a
  second coil form with other time constants) is left out of the simulation and recorded
  in `Diagnosis.skipped` with the reason, never an error for the run;
- the chamber program -> profile kind "program" (10 s points); the table schedule ->
  constant / alternating / levels from the log's rate plateaus; noise -> ARW from the
  noise floor.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from fogsf.diagnose import design
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects import catalogue
from fogsf.diagnose.fits import Diagnosis, ModelFit
from fogsf.logs.chamber_log import EARTH_RATE_DPS
from fogsf.logs.measure.plateaus import plateaus
from fogsf.logs.measure.windows import sf_windows
from fogsf.logs.read.columns import Column, derived, exact_mean
from fogsf.sim.config import SimConfig
from fogsf.sim.gyro import simulate

PROGRAM_STEP_S = 10.0
# the simulator's effects on the coil's temperature (fogsf.sim.effects: the mean of the
# nodes named coil*), and the coil each catalogue form fits: its layers' time constants
COIL_EFFECTS = ("temp_rate", "bias_shupe", "hysteresis")
SIM_STEP_S = 0.1  # closeness simulates at 10 Hz or slower (sim_step)
SIM_MAX_SAMPLES = 1_000_000


def _table(rate: Column, dt: float) -> tuple[dict[str, Any], bool]:
    """Table schedule from the rate plateaus; the flag says whether it reproduces the log.
    Rows at rest measure nothing (and a simulated table never rests): only the moving
    plateaus make the schedule, so a log with rests is not reproduced exactly."""
    pl = plateaus(rate, derived(len(rate), np.dtype(bool),
                                lambda s: np.asarray(rate[s]) != 0.0))
    rates = [float(rate[a]) for a, _ in pl]
    lengths = [b - a for a, b in pl]
    if len(pl) == 1:
        return {"kind": "constant", "rate_dps": rates[0]}, True
    dwell = lengths[0]
    exact = all(n == dwell for n in lengths[:-1]) and lengths[-1] <= dwell
    period = len(rates)
    for k in range(1, len(rates)):
        if all(rates[i] == rates[i % k] for i in range(len(rates))):
            period = k
            break
    cycle = rates[:period]
    if period == 2 and cycle[1] == -cycle[0]:
        return {"kind": "alternating", "rate_dps": cycle[0], "dwell_s": dwell * dt}, exact
    return {"kind": "levels", "rates_dps": cycle, "dwell_s": dwell * dt,
            "rate_dps": cycle[0]}, exact


def _latitude(ctx: RunContext) -> float:
    log = ctx.run.log
    if log.earth_rate_dps is None:
        return 0.0
    s = exact_mean(log.earth_rate_dps, 0, len(log.earth_rate_dps)) / EARTH_RATE_DPS
    return math.degrees(math.asin(max(-1.0, min(1.0, s))))


def _program(ctx: RunContext) -> list[list[float]]:
    log = ctx.run.log
    src = log.extra.get("chamber_c") if ctx.driver.source == "chamber" else log.temp_c
    assert src is not None
    t0 = float(log.time_s[0])
    k = max(1, int(round(PROGRAM_STEP_S / ctx.run.dt_s)))
    n = (len(log.time_s) - 1) // k * k + 1
    t = np.asarray(log.time_s[0:n:k], dtype=np.float64) - t0
    # block means keep the program smooth (the thermometer is quantised); the last point
    # closes the run so the simulation has as many samples as the log
    means = [float(np.mean(src[max(0, i - k // 2): i + k // 2 + 1])) for i in range(0, n, k)]
    pts = [[float(ti), m] for ti, m in zip(t, means, strict=True)]
    t_end = float(log.time_s[-1]) - t0
    if pts[-1][0] < t_end:
        pts.append([t_end, float(np.mean(src[-k:]))])
    return pts


def _sf_term(name: str, node: str, lin: float, quad: float) -> dict[str, Any]:
    return {"name": name, "factor": "L", "nodes": {node: 1.0}, "lin_ppm_per_c": lin,
            "quad_ppm_per_c2": quad, "ref_c": design.T_REF_C}


def _coil_taus(cand: catalogue.Candidate, g: catalogue.GridValue) -> tuple[float, ...]:
    """The coil node(s) a coil form was fitted with: temp_rate's and bias_shupe's two layers
    (inner, outer), hysteresis's one node (its grid value is (width_c, tau_s))."""
    if cand.name == "hysteresis":
        assert isinstance(g, tuple)
        return (float(g[1]),)
    return catalogue.coil_taus(g)


def _skip(d: Diagnosis, effect: str, reason: str) -> None:
    entry = {"effect": effect, "stage": "simulation of the extended model", "reason": reason}
    if entry not in d.skipped:
        d.skipped.append(entry)


def sim_config(d: Diagnosis, model: ModelFit, run_index: int = 0, seed: int = 0
               ) -> dict[str, Any]:
    """The simulator configuration (as a dict) of `model` fitted to the logs, for one run's
    chamber program and table schedule. A cause it cannot carry is left out and recorded in
    `d.skipped`."""
    ctx = d.ctxs[run_index]
    drv = ctx.driver
    (tau1, tau2), g = model.combo
    names = model.stack.names
    coef = dict(zip(names, (float(b) for b in model.fit.beta), strict=True))
    dt = round(ctx.run.dt_s, 6)
    power_on = ctx.power_on
    from_chamber = drv.source == "chamber"
    board_heat = (drv.self_heat_board_c if power_on else drv.board_offset_c) \
        if from_chamber else 0.0
    nodes = [
        {"name": "housing", "parent": "chamber",
         "tau_s": drv.tau_housing_s if from_chamber else 0.0,
         "self_heat_c": drv.self_heat_housing_c if power_on else 0.0},
        {"name": "board", "parent": "housing",
         "tau_s": drv.tau_board_s if from_chamber else 0.0, "self_heat_c": board_heat},
        {"name": "node1", "parent": "housing", "tau_s": tau1, "self_heat_c": 0.0},
        {"name": "node2", "parent": "housing", "tau_s": tau2, "self_heat_c": 0.0},
    ]
    cand = model.stack.candidate
    # the causes with their grid values (the profiled last part at the fit's own)
    parts = [] if cand is None else (
        [(c, g if gv is None else gv) for c, gv in cand.parts] if cand.parts else [(cand, g)])
    coil: tuple[float, ...] = ()
    coil_of = ""
    for c, gv in parts:
        if c.name in COIL_EFFECTS and not coil:
            # the simulator's coil effects act on the mean of the nodes named coil*: the
            # coil as this form fitted it
            coil, coil_of = _coil_taus(c, gv), c.name
            names_c = ("coil",) if len(coil) == 1 else ("coil_inner", "coil_outer")[:len(coil)]
            nodes += [{"name": n, "parent": "housing", "tau_s": tau, "self_heat_c": 0.0}
                      for n, tau in zip(names_c, coil, strict=True)]
    terms = [
        _sf_term("fitted board term", "board", coef["board_ppm_per_c"],
                 coef["board_ppm_per_c2"]),
        _sf_term("fitted node1 term", "node1", coef["node1_ppm_per_c"],
                 coef["node1_ppm_per_c2"]),
        _sf_term("fitted node2 term", "node2", coef["node2_ppm_per_c"],
                 coef["node2_ppm_per_c2"]),
    ]
    table, _ = _table(ctx.run.log.table_rate_dps, dt)
    rate0 = abs(float(ctx.run.rate[0]))
    sig0 = float(ctx.run.sigma_ppm[0])
    arw = sig0 * 1e-6 * rate0 * math.sqrt(d.window_s) * 60.0
    effects = []
    if power_on and "selfheat1_ppm" in coef:
        # the unseen self-heating transients of the internal nodes, exactly as fitted
        effects += [{"name": "warmup", "strength": coef[f"selfheat{i}_ppm"],
                     "params": {"tau_s": tau}} for i, tau in ((1, tau1), (2, tau2))]
    coef_names = cand.names() if cand is not None else []
    shupe_dph_per_c_per_min = 0.0
    for (c, gv), name in zip(parts, coef_names, strict=True):
        if c.name == "bias_drift" and gv is not None and catalogue.first(gv) < 0.0:
            # a node the board lags by lead_s: board + lead_s dT_board/dt, the bias's own
            # dT/dt term on the board node in deg/h per C/min
            shupe_dph_per_c_per_min += coef[name] * -catalogue.first(gv) / 60.0
        if c.name in COIL_EFFECTS and not coil:
            _skip(d, c.name, "needs coil nodes (names starting with 'coil'), the fitted base "
                  "has none")
            continue
        if c.name in COIL_EFFECTS and c.name != coil_of and _coil_taus(c, gv) != coil:
            _skip(d, c.name, f"needs its own coil nodes ({_coil_taus(c, gv)} s), the "
                  f"extended model's coil is {coil_of}'s ({coil} s)")
            continue
        effects.append(c.to_effect(coef[name], gv))
    return {
        "scenario": "diagnose",
        "seed": seed,
        "dt_s": dt,
        "latitude_deg": _latitude(ctx),
        "profile": {"kind": "program", "points": _program(ctx)},
        "table": table,
        "thermal": {"nodes": nodes, "start": "power-on" if power_on else "warm",
                    "board_node": "board"},
        "sf": {"terms": terms, "offset_ppm": coef["offset_ppm"]},
        "bias": {"bias_dph": coef.get("bias_dph", 0.0), "lin_dph_per_c": 0.0,
                 "quad_dph_per_c2": 0.0, "node": "board", "ref_c": design.T_REF_C,
                 "shupe_dph_per_c_per_min": shupe_dph_per_c_per_min},
        "noise": {"arw_deg_per_sqrt_h": arw, "pulse_arcsec": 1.0, "temp_noise_c": 0.02,
                  "temp_lsb_c": 0.0625},
        "effects": effects,
    }


def sim_step(cfg: dict[str, Any], duration_s: float, window_s: float) -> float:
    """The sample step closeness simulates at: the log's step times k, k as large as keeps
    at least SIM_STEP_S (10 Hz, what diagnose was built on) or at most SIM_MAX_SAMPLES
    samples, and at least 20 samples a window, and dividing the table's dwell (so the
    simulated table turns when the log's did). A noiseless simulation's window means hardly
    depend on the step; its memory grows with the samples."""
    dt = float(cfg["dt_s"])
    want = max(SIM_STEP_S, duration_s / SIM_MAX_SAMPLES)
    k = max(1, min(int(want / dt), int(window_s / 20.0 / dt)))
    table = cfg["table"]
    if table["kind"] != "constant":
        dwell = int(round(float(table["dwell_s"]) / dt))
        k = max(d for d in range(1, max(1, min(k, dwell)) + 1) if dwell % d == 0)
    return dt * k


def simulated_windows(cfg: dict[str, Any], window_s: float, dt_s: float | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(window centre times, apparent SF error in ppm) of the configuration simulated without
    noise (at dt_s when given, else at its own step)."""

    quiet = copy.deepcopy(cfg)
    quiet["noise"] = {"arw_deg_per_sqrt_h": 0.0, "pulse_arcsec": 0.0, "temp_noise_c": 0.0,
                      "temp_lsb_c": 0.0}
    if dt_s is not None:
        quiet["dt_s"] = dt_s
    res = simulate(SimConfig.from_dict(quiet))
    w = sf_windows(res.log, window_s, remove_bias=False)  # as diagnose.runs reads the logs
    return w.t_s, (w.sf_ratio - 1.0) * 1e6


def closeness(d: Diagnosis, base_cfgs: list[dict[str, Any]], ext_cfgs: list[dict[str, Any]]
              ) -> dict[str, float]:
    """RMS (ppm) between the measured windows and the noiseless simulation of the base and of
    the extended configuration, over all runs (windows matched by centre time)."""
    err_b: list[np.ndarray] = []
    err_e: list[np.ndarray] = []
    for i, run in enumerate(d.runs):
        t0 = float(run.log.time_s[0])
        step = sim_step(base_cfgs[i], run.log.duration_s, d.window_s)
        for cfgs, out in ((base_cfgs, err_b), (ext_cfgs, err_e)):
            ts, ys = simulated_windows(cfgs[i], d.window_s, step)
            tr = run.t_s - t0
            j = np.clip(np.searchsorted(ts, tr), 1, ts.shape[0] - 1)
            j -= np.abs(ts[j - 1] - tr) <= np.abs(ts[j] - tr)  # the nearest centre
            ok = np.abs(ts[j] - tr) < 0.5 * d.window_s
            out.append((run.y_ppm - ys[j])[ok])
    rb = float(np.sqrt(np.mean(np.concatenate(err_b) ** 2)))
    re = float(np.sqrt(np.mean(np.concatenate(err_e) ** 2)))
    return {"rms_base_sim_ppm": rb, "rms_extended_sim_ppm": re,
            "closer_pct": 100.0 * (1.0 - re / rb) if rb > 0 else 0.0,
            "noise_floor_ppm": d.noise_floor_ppm}


def extended(d: Diagnosis, seed: int = 0, compare: bool = True
             ) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """The extended model's simulator configuration for each run, and (compare) how close
    the base's and its noiseless simulations come to the logs (`closeness`)."""
    ext_cfgs = [sim_config(d, d.extended, i, seed) for i in range(len(d.runs))]
    if not compare:
        return ext_cfgs, None
    base_cfgs = [sim_config(d, d.base, i, seed) for i in range(len(d.runs))]
    return ext_cfgs, closeness(d, base_cfgs, ext_cfgs)

