"""Planted-effect cases for the diagnose tests and benchmark (`benchmarks.diagnose_rate`).

A case is a simulated chamber run (1.5-2 h at 10 Hz; 4.5 h for the lag / dT/dt pair) with a
profile, table schedule and start drawn by a seeded generator from the ranges stated in
`draw`, and one of:

- `effect`: one catalogue effect planted with the simulator (`--effect`);
- `null`: nothing planted;
- `ooc`: an effect outside the catalogue added to the gyro output after simulating:
  `humidity` (SF following an unlogged humidity: smooth, 2-3 random periods of 15-70 min),
  `supply_step` (SF step when an unlogged supply voltage changes, at 25-75 % of the run),
  `periodic` (SF ripple with an unlogged 8-25 min period, e.g. the lab's air conditioning
  acting on the electronics);
- `ramp_only`: a lag (`extra_lag`) or dT/dt (`temp_rate`) term in a log cut to the steady
  part of a single ramp, where the two cannot be told apart (nor from the base);
- `short_soak`: the same two in 110 min logs whose soaks are too short to watch a slow node
  settle: right if named, or reported ambiguous, never the other one.

The lag / dT/dt cases of kind `effect` use 4.5 h logs with 70-80 min soaks (up and back),
extra_lag time constants 5000-9000 s. The hysteresis cases (`hysteresis`: a play of the coil
temperature) are planted at the population's physics, not at a multiple of the floor:
width over HYST_WIDTH_C (4-10 C), strength over HYST_PPM_PER_C (3-8 ppm/C), on partial
cycles (`programs.partial`: up 25-40 C, back 10-20 C, up 10-20 C, back 15-25 C, up
10-20 C, back to the start, 1-2 C/min, 15-25 min soaks at each turn, 3.5-5 h: a play shows
only where the temperature turns back). One whose visible part stays under 3x the floor may go
unnamed (never misnamed); a named one is held to its loop's height (strength x width)
within 50 %.

How a case is simulated, its strength calibrated to the noise floor, is
`diagnose.cases.build`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fogsf.diagnose.cases import kinds as case_kinds
from fogsf.diagnose.cases import programs
from fogsf.sim.config import ProfileConfig, SimConfig, TableConfig
from fogsf.sim.effects import EffectConfig
from fogsf.sim.population import gyro_for_seed, with_gyro

MULTIPLE_RANGE = (3.0, 20.0)
EFFECTS = ("warmup", "extra_lag", "temp_rate", "rate_nonlinearity", "asymmetry", "bias_drift",
           "aging")
# bias effects planted beside EFFECTS (kept apart: the null cases draw their setup from
# EFFECTS, and those draws stay as they were)
BIAS_EFFECTS = ("bias_shupe",)
PLANTED = EFFECTS + BIAS_EFFECTS
# the catalogue's forms: the planted ones and the hysteresis (its cases on partial cycles)
CATALOGUE_EFFECTS = (*PLANTED, "hysteresis")
HYST_WIDTH_C = (4.0, 10.0)  # the planted play's width and strength (the population's)
HYST_PPM_PER_C = (3.0, 8.0)
OOC_KINDS = ("humidity", "supply_step", "periodic", "mode_hop")
# form variants (bench and tests): effect -> variant -> (effect params, table kinds)
VARIANTS: dict[str, dict[str, str]] = {
    "rate_nonlinearity": {"linear": "exponent 1", "quadratic": "exponent 2"},
    "bias_drift": {"board": "on the board", "node": "on an internal node lagging the housing "
                   "by 600-2400 s", "coil_pair": "the gyro's own bias on its coil node, a "
                   "reversing table, no chamber air, a log pair (case_kinds)"},
    "aging": {"linear": "linear", "settling": "settling, time constant 5400-14400 s"},
    "warmup": {"transient": "SF transient, tau 120-300 s",
               "slow": "slow self-heating of internal nodes, tau 900-2400 s"},
    "asymmetry": {"several": "at two or three |rate|, both signs",
                  "one": "at one |rate|, both signs (confounded with a constant bias)"},
    "bias_shupe": {"coil": "on the coils' rate of change, +/- table at one or two |rate|"},
}
# two-effect cases: pairs that one set of logs can show at once
PAIRS = (("asymmetry", "aging"), ("rate_nonlinearity", "aging"), ("bias_drift", "aging"),
         ("asymmetry", "rate_nonlinearity"))


@dataclass
class Case:
    kind: str  # effect / null / ooc / ramp_only
    name: str  # effect or out-of-catalogue kind ("" for null)
    seed: int
    config: SimConfig
    multiple: float = 0.0  # target visible strength / noise floor
    params: dict[str, float] = field(default_factory=dict)  # truth (after scaling)
    crop_s: float = 0.0  # ramp_only: samples before this are cut
    multiple_reached: float = 0.0  # the visible strength / noise floor actually planted
    variant: str = ""  # form variant (VARIANTS) or, for kind "two", the second effect
    gyro_seed: int | None = None  # population gyro (fogsf.sim.population), None: default
    chamber: bool = True  # the log keeps chamber_c

    def describe(self) -> str:
        p = self.config.profile
        t = self.config.table
        prof = (f"{p.kind} {p.levels_c or [p.start_c, p.stop_c]} at {p.rate_c_per_min:.2g} "
                f"C/min")
        tab = t.kind + (f" {t.rates_dps}" if t.kind == "levels" else f" {t.rate_dps:g}")
        return (f"{self.kind}:{self.name or '-'}{':' + self.variant if self.variant else ''} "
                f"seed={self.seed} gyro={self.gyro_seed} "
                f"{'chamber' if self.chamber else 'board-only'} x{self.multiple:.1f}"
                f"({self.multiple_reached:.1f}) "
                f"{prof}, table {tab}, {self.config.thermal.start}, truth {self.params}")


def draw(kind: str, name: str, seed: int) -> Case:
    """A case drawn from the stated ranges (see the module docstring and the code below)."""
    rng = np.random.default_rng(seed)
    cfg = SimConfig(seed=int(rng.integers(0, 2**31)))
    cfg.thermal.start = "warm"
    multiple = float(rng.uniform(*MULTIPLE_RANGE))
    params: dict[str, float] = {}
    table_kind = "constant"
    profile = programs.steps(rng, back=False, minutes=100)
    if kind in ("effect", "null"):
        eff = name if kind == "effect" else str(rng.choice(EFFECTS))  # null: that case's setup
        if eff == "warmup":
            cfg.thermal.start = "power-on"
            params["tau_s"] = float(rng.uniform(120.0, 300.0))  # >= 2 windows of 60 s
            profile = programs.steps(rng, back=False, minutes=100)
        elif eff == "extra_lag":
            params["tau_s"] = float(rng.uniform(5000.0, 9000.0))
            profile = programs.long_soaks(rng)
        elif eff == "temp_rate":
            profile = programs.long_soaks(rng)
        elif eff == "rate_nonlinearity":
            table_kind = "multi"
            profile = programs.cycle(rng)
        elif eff == "asymmetry":
            table_kind = "plusminus"
            profile = programs.cycle(rng)
        elif eff == "bias_drift":
            table_kind = "alternating"
            profile = programs.cycle(rng)
        elif eff == "aging":
            profile = programs.steps(rng, back=True, minutes=120)
        elif eff == "hysteresis":
            params["width_c"] = float(rng.uniform(*HYST_WIDTH_C))
            profile = programs.partial(rng)
        elif eff == "bias_shupe":
            table_kind = "alternating"
            profile = programs.cycle(rng)
        if kind == "effect":
            cfg.effects = [EffectConfig(name, 1.0, {k: v for k, v in params.items()})]
            if name == "hysteresis":
                cfg.effects[0].strength = float(rng.uniform(*HYST_PPM_PER_C))
            if name == "extra_lag":
                cfg.effects = [EffectConfig(name, params["tau_s"], {"sens_ppm_per_c": 1.0})]
        else:
            params = {}
    elif kind == "ooc":
        profile = (programs.steps(rng, back=True, minutes=110) if rng.random() < 0.5
                   else programs.cycle(rng))
        table_kind = str(rng.choice(["constant", "alternating"]))
        if name == "humidity":
            k = int(rng.integers(2, 4))
            params = {f"period{i}_s": float(rng.uniform(900.0, 4200.0)) for i in range(k)}
            params.update({f"phase{i}": float(rng.uniform(0, 2 * np.pi)) for i in range(k)})
        elif name == "supply_step":
            params = {"at_fraction": float(rng.uniform(0.25, 0.75))}
        elif name == "periodic":
            params = {"period_s": float(rng.uniform(480.0, 1500.0)),
                      "phase": float(rng.uniform(0, 2 * np.pi))}
        elif name == "mode_hop":  # up and back, so the source passes the hop both ways
            profile = programs.cycle(rng)
            params = case_kinds.draw_mode_hop(rng, profile)
    elif kind == "short_soak":  # a lag or dT/dt term with soaks too short to tell them apart
        cfg.effects = [EffectConfig("extra_lag", float(rng.uniform(5000.0, 9000.0)),
                                    {"sens_ppm_per_c": 1.0})] if name == "extra_lag" else [
            EffectConfig("temp_rate", 1.0)]
        cfg = _finish(cfg, programs.steps(rng, back=True, minutes=110),
                      programs.table(rng, "constant"))
        return Case(kind, name, seed, cfg, multiple, {})
    elif kind == "ramp_only":
        rate = float(rng.uniform(0.4, 0.5))  # -40..60 C: 200-250 min, 1-1.8 h kept
        profile = ProfileConfig(kind="ramp", start_c=-40.0, stop_c=60.0, rate_c_per_min=rate)
        if name == "extra_lag":
            tau = float(rng.uniform(4000.0, 9000.0))
            cfg.effects = [EffectConfig(name, tau, {"sens_ppm_per_c": 4.0})]
            params = {"tau_s": tau, "sens_ppm_per_c": 4.0}
        else:
            cfg.effects = [EffectConfig("temp_rate", 30.0)]
            params = {"strength": 30.0}
        crop = 3.0 * 2800.0  # past the network's settling onto the steady ramp
        return Case(kind, name, seed, _finish(cfg, profile, TableConfig()), 0.0, params, crop)
    cfg = _finish(cfg, profile, programs.table(rng, table_kind))
    return Case(kind, name, seed, cfg, multiple if kind != "null" else 0.0, params)


def draw_population(kind: str, name: str, variant: str, seed: int) -> Case:
    """A bench case on the population's gyro number `seed` (fogsf.sim.population; its bias
    temperature coefficient set to zero, so that nothing but the planted effect is a bias
    drift), with the chamber program of `draw` and:

    - kind "effect": `name` in form `variant` (VARIANTS: rate_nonlinearity exponent 1 or 2 on
      a one-sign or a +/- table at three |rate|; bias_drift on the board or on a node lagging
      the housing by 600-2400 s, +/- table at one or two |rate|; aging linear or settling
      over 5400-14400 s; warmup as an SF transient of 120-300 s or a slow one of 900-2400 s;
      asymmetry at two or three |rate| or at one);
    - kind "two": `name` and `variant` planted together (PAIRS), each at its own multiple,
      on a 150 min up-and-back program with a +/- table at three |rate|;
    - kind "null", name "mixed": nothing planted, table +/- 10, 50, 100, 200 deg/s;
    - other kinds as `draw`.
    Half the cases (a seeded draw) drop `chamber_c`, except ramp-only and short-soak ones,
    the lag and dT/dt terms (told from the base by the housing running ahead of the board,
    which needs the chamber air) and the Shupe bias (the coil's rate of change, the same)."""
    rng = np.random.default_rng([seed, 0xD1A6])
    if kind == "two":
        case = draw("effect", name, seed)
        cfg = case.config
        cfg.thermal.start = "warm"
        cfg.profile = programs.steps(rng, back=True, minutes=150)
        cfg.table = programs.table(rng, "multi_pm")
        cfg.effects = [EffectConfig(name, 1.0, {}), EffectConfig(variant, 1.0, {})]
        case.kind = "two"
        case.params = {"multiple2": float(rng.uniform(*MULTIPLE_RANGE))}
    elif kind == "null" and name == "mixed":
        case = draw("null", "", seed)
        case.config.table = programs.table(rng, "mixed")
        case.name = ""
    elif kind == "effect":
        case = draw("effect", name, seed)
        cfg = case.config
        e = cfg.effects[0]
        if name == "rate_nonlinearity":
            e.params["exponent"] = 2.0 if variant == "quadratic" else 1.0
            cfg.table = programs.table(rng, str(rng.choice(["multi", "multi_pm"])))
        elif name == "bias_drift":
            if variant == "node":
                e.params["node_tau_s"] = float(rng.uniform(600.0, 2400.0))
            cfg.table = programs.table(rng, str(rng.choice(["alternating", "plusminus"])))
            if variant == "coil_pair":  # the gyro's own bias, on its coil (build calibrates it)
                cfg.effects = []
                cfg.table = programs.table(rng, "alternating")
        elif name == "aging" and variant == "settling":
            e.params["settle_tau_s"] = float(rng.uniform(5400.0, 14400.0))
        elif name == "warmup" and variant == "slow":
            e.params["tau_s"] = float(rng.uniform(900.0, 2400.0))
        elif name == "asymmetry":
            cfg.table = programs.table(rng, "alternating" if variant == "one" else
                               str(rng.choice(["plusminus", "multi_pm"])))
        elif name == "bias_shupe":
            cfg.table = programs.table(rng, str(rng.choice(["alternating", "plusminus"])))
        case.params = dict(e.params)
    else:
        case = draw(kind, name, seed)
    case.variant = variant
    case.gyro_seed = seed
    gyro = gyro_for_seed(seed, hysteresis=False)  # nothing but what the case plants
    gyro.bias.lin_dph_per_c = 0.0
    gyro.bias.quad_dph_per_c2 = 0.0
    case.config = with_gyro(case.config, gyro)
    # the lag and dT/dt terms show as the housing running ahead of the board: with chamber_c
    case.chamber = (kind in ("ramp_only", "short_soak")
                    or name in ("extra_lag", "temp_rate", "bias_shupe")
                    or bool(rng.random() < 0.5))
    if kind == "effect" and variant == "coil_pair":
        case.config.bias.node = case_kinds.coil_node(case.config)
        case.chamber = False
    return case


def _finish(cfg: SimConfig, profile: ProfileConfig, table: TableConfig) -> SimConfig:
    cfg.profile = profile
    cfg.table = table
    return cfg
