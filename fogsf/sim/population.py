"""A population of gyros: `sample_gyro(rng)` draws a physically plausible FOG with structural
variety, so that methods are measured on gyros they were not tuned on.

What varies (every range is a constant below; docs/population.md lists them):
- thermal network: housing and board (as the default gyro) plus 3-6 internal sensing nodes
  (coil layers, source, preamp, Y-waveguide), in a star (every node behind the housing), a
  chain (each behind the previous, slowest last) or a mix; time constants log-uniform over
  `INTERNAL_TAU_S`, self-heating over `*_SELF_HEAT_C`;
- SF law: the five factors of K = 2 pi L D / (Km K_DA lambda c), each on its own node(s)
  (lambda on the source, L and D on the coil layers, Km on the waveguide or coil, K_DA on the
  preamp or board), each linear, quadratic or cubic in its temperature, with either sign;
  in a share `CANCEL_SHARE` of gyros the slowest part (the source) opposes the others and
  cancels most of their static slope, so the SF error is small but strongly hysteretic;
- magnitude: the sum of the factors' static swings over -40..+50 C is log-uniform over
  `SWING_PPM` (the default gyro: about 2900 ppm of swings, 835 ppm max|error| at 1 C/min);
- bias and noise around the default gyro's;
- SF hysteresis: a share `HYST_SHARE` of gyros has a play (backlash) operator of the coil
  temperature in its SF (the simulator's `hysteresis` effect), width `HYST_WIDTH_C`,
  strength `HYST_PPM_PER_C`, drawn from a stream of its own (`hysteresis_for_seed`), so
  every other draw, and every gyro without it, is what it was before hysteresis existed;
- forms outside all of the above, for benches only (`outside_form`: the thermometer behind
  the board, or a part behind the chamber air), on a stream of their own too.

Seeds: `gyro_for_seed(seed)` is `sample_gyro(default_rng(seed))`, except seed 0, which is the
default gyro (`SimConfig()`'s). Development seeds (`DEV_SEEDS`) are for tuning; evaluation
seeds (`EVAL_SEEDS`) are for reporting only: no threshold or default may be tuned on them.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from fogsf.sim.config import (
    SF_FACTORS,
    BiasConfig,
    NodeConfig,
    NoiseConfig,
    ProfileConfig,
    ScaleFactorConfig,
    SFTermConfig,
    SimConfig,
    TableConfig,
    ThermalConfig,
)
from fogsf.sim.effects import EffectConfig

DEV_SEEDS = range(0, 10_000)
EVAL_SEEDS = range(20_000, 30_000)

HOUSING_TAU_S = (40.0, 200.0)
BOARD_TAU_S = (120.0, 600.0)
INTERNAL_TAU_S = (150.0, 4000.0)
HOUSING_SELF_HEAT_C = (0.3, 2.0)
BOARD_SELF_HEAT_C = (2.0, 8.0)
INTERNAL_SELF_HEAT_C = (0.0, 5.0)
N_INTERNAL = (3, 6)
TOPOLOGIES = ("star", "chain", "mixed")
LAWS = ("linear", "quadratic", "cubic")
LAW_P = (0.35, 0.45, 0.20)
SWING_PPM = (1000.0, 6000.0)
CANCEL_SHARE = 0.3
CANCEL_RATIO = (0.6, 1.0)  # the source's slope as a share of the others' (opposite sign)
QUAD_SHARE = (-0.6, 0.6)  # quadratic swing as a share of the linear one at 45 C
CUBE_SHARE = (-0.4, 0.4)
ARW_DEG_PER_SQRT_H = (0.03, 0.08)
BIAS_DPH = (-1.0, 1.0)
BIAS_LIN_DPH_PER_C = (-0.01, 0.01)
# The thermal bias's further terms (`thermal_bias`, drawn only when asked for): the Shupe
# term's magnitude log-uniform (deg/h per C/min of the coil's temperature change, either
# sign), the quadratic and cubic uniform; on the first coil node.
SHUPE_DPH_PER_C_PER_MIN = (0.1, 3.0)
BIAS_QUAD_DPH_PER_C2 = (-5e-4, 5e-4)
BIAS_CUBE_DPH_PER_C3 = (-1e-5, 1e-5)
SPAN_C = (-40.0, 50.0)  # the temperature span the swing is measured over
REF_C = 20.0
HYST_SHARE = 0.3
HYST_WIDTH_C = (4.0, 10.0)
HYST_PPM_PER_C = (3.0, 8.0)
HYST_STREAM = 0x4857  # the hysteresis draws' own stream: [seed, HYST_STREAM]
# An open-loop FOG (the `open_loop` effect), drawn only when asked for (`open_loop=True`):
# full scale (150 deg/s) reaches a fraction of pi/2 uniform over OPEN_LOOP_FRACTION, the
# phase scale moving uniform over OPEN_LOOP_TC_PPM_PER_C per C (the source's wavelength);
# its own stream, so every other draw stays what it was.
OPEN_LOOP_FRACTION = (0.1, 0.4)
OPEN_LOOP_TC_PPM_PER_C = (-600.0, -200.0)
OPEN_LOOP_STREAM = 0x0915
# A closed-loop FOG's rate response (`rate_response=True`): an SF nonlinearity of
# CLOSED_LOOP_NONLIN_PPM at 100 deg/s growing as |rate|^CLOSED_LOOP_EXPONENT (a fractional
# power: no polynomial holds it exactly) and an asymmetry of CLOSED_LOOP_ASYM_PPM between
# + and - rates, each uniform, its own stream.
CLOSED_LOOP_NONLIN_PPM = (20.0, 200.0)
CLOSED_LOOP_EXPONENT = (1.0, 2.0)
CLOSED_LOOP_ASYM_PPM = (10.0, 100.0)
RATE_RESPONSE_STREAM = 0x0A7E
# Forms outside the population's (`outside_form`, benches only): the thermometer behind the
# board ("sensor", its lag log-uniform over SENSOR_TAU_S), or one internal part that carries
# an SF factor moved behind the chamber air ("vent", VENT_TAU_S; the parts behind it follow
# it): in both the SF moves before the thermometer sees it, which no lag of the
# thermometer's reading holds exactly.
OUTSIDE_FORMS = ("sensor", "vent")
SENSOR_TAU_S = (30.0, 300.0)
VENT_TAU_S = (100.0, 1500.0)
OUTSIDE_STREAM = 0x0F0E
# effects that are the gyro's own physics (carried by `with_gyro`), not the run's
GYRO_EFFECTS = ("hysteresis", "open_loop")

# Internal parts in the order they are added; the first three are always there.
_ROLES = ("coil_inner", "source", "preamp", "coil_outer", "waveguide", "coil_mid")


def _log_uniform(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    lo, hi = lo_hi
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _uniform(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    return float(rng.uniform(*lo_hi))


def _thermal(rng: np.random.Generator) -> tuple[ThermalConfig, str]:
    n = int(rng.integers(N_INTERNAL[0], N_INTERNAL[1] + 1))
    topology = str(rng.choice(TOPOLOGIES))
    nodes = [NodeConfig("housing", "chamber", round(_log_uniform(rng, HOUSING_TAU_S), 1),
                        round(_uniform(rng, HOUSING_SELF_HEAT_C), 2)),
             NodeConfig("board", "housing", round(_log_uniform(rng, BOARD_TAU_S), 1),
                        round(_uniform(rng, BOARD_SELF_HEAT_C), 2))]
    roles = list(_ROLES[:n])
    taus = {r: round(_log_uniform(rng, INTERNAL_TAU_S), 1) for r in roles}
    if topology == "chain":  # slowest last: each part behind the one before it
        roles.sort(key=lambda r: taus[r])
        # a chain adds the time constants: keep its total within the range's top
        scale = min(1.0, INTERNAL_TAU_S[1] / sum(taus.values()) * 1.5)
        taus = {r: round(max(INTERNAL_TAU_S[0] / 2, t * scale), 1) for r, t in taus.items()}
    placed: list[str] = []
    for r in roles:
        if topology == "star" or not placed:
            parent = "housing"
        elif topology == "chain":
            parent = placed[-1]
        else:
            parent = "housing" if rng.random() < 0.5 else str(rng.choice(placed))
        nodes.append(NodeConfig(r, parent, taus[r], round(_uniform(rng, INTERNAL_SELF_HEAT_C),
                                                           2)))
        placed.append(r)
    return ThermalConfig(nodes=nodes, start="warm", board_node="board"), topology


def _weights(rng: np.random.Generator, names: list[str]) -> dict[str, float]:
    if len(names) == 1:
        return {names[0]: 1.0}
    w = rng.dirichlet(np.ones(len(names)))
    w = np.round(w, 3)
    w[-1] = round(1.0 - float(w[:-1].sum()), 3)
    return {n: float(x) for n, x in zip(names, w, strict=True)}


def _term_nodes(rng: np.random.Generator, factor: str, internal: list[str]
                ) -> dict[str, float]:
    coils = [r for r in internal if r.startswith("coil")]
    if factor == "lambda":
        return {"source": 1.0}
    if factor in ("L", "D"):
        return _weights(rng, coils)
    if factor == "Km":
        return {"waveguide": 1.0} if "waveguide" in internal else {"coil_inner": 1.0}
    return {str(rng.choice(["preamp", "board"])): 1.0}  # K_DA


def _shape(rng: np.random.Generator, law: str) -> tuple[float, float, float]:
    """(lin, quad, cube) of a law with a linear slope of magnitude in 0.2..1 and either sign."""
    lin = float(rng.choice([-1.0, 1.0])) * _uniform(rng, (0.2, 1.0))
    h = 45.0  # half the span: shares are of the linear swing at 45 C from the reference
    quad = lin * _uniform(rng, QUAD_SHARE) / h if law in ("quadratic", "cubic") else 0.0
    cube = lin * _uniform(rng, CUBE_SHARE) / h**2 if law == "cubic" else 0.0
    return lin, quad, cube


def _swing(lin: float, quad: float, cube: float) -> float:
    d = np.linspace(SPAN_C[0] - REF_C, SPAN_C[1] - REF_C, 181)
    v = lin * d + quad * d * d + cube * d**3
    return float(v.max() - v.min())


def _sf(rng: np.random.Generator, internal: list[str]) -> tuple[ScaleFactorConfig, bool]:
    factors = ("lambda", "L", "D", "Km", "K_DA")
    names = {"lambda": "source wavelength", "L": "coil length", "D": "coil diameter",
             "Km": "Y-waveguide Km", "K_DA": "D/A gain"}
    shapes = {f: _shape(rng, str(rng.choice(LAWS, p=LAW_P))) for f in factors}
    cancel = bool(rng.random() < CANCEL_SHARE)
    if cancel:  # the source's SF slope opposes the sum of the others' (signs through K)
        others = sum(SF_FACTORS[f] * shapes[f][0] for f in factors if f != "lambda")
        if abs(others) < 0.3:  # nothing to cancel: make the others agree first
            shapes = {f: (abs(s[0]), s[1] * np.sign(s[0]), s[2] * np.sign(s[0]))
                      if f != "lambda" else s for f, s in shapes.items()}
            others = sum(SF_FACTORS[f] * shapes[f][0] for f in factors if f != "lambda")
        target_sf_slope = -_uniform(rng, CANCEL_RATIO) * others
        lin, quad, cube = shapes["lambda"]
        new_lin = target_sf_slope * SF_FACTORS["lambda"]
        k = new_lin / lin
        shapes["lambda"] = (new_lin, quad * k, cube * k)
    swing = sum(_swing(*s) for s in shapes.values())
    scale = _log_uniform(rng, SWING_PPM) / swing
    terms = [SFTermConfig(names[f], f, _term_nodes(rng, f, internal),
                          float(f"{shapes[f][0] * scale:.5g}"),
                          float(f"{shapes[f][1] * scale:.5g}"), REF_C,
                          float(f"{shapes[f][2] * scale:.5g}"))
             for f in factors]
    return ScaleFactorConfig(terms=terms), cancel


def sample_gyro(rng: np.random.Generator) -> SimConfig:
    """One random gyro (thermal network, SF law, bias, noise) with the default chamber run
    (the paper's ramp; set `profile`, `table` and `seed` for the run you want)."""
    thermal, topology = _thermal(rng)
    internal = [n.name for n in thermal.nodes[2:]]
    sf, cancel = _sf(rng, internal)
    nodes = [n.name for n in thermal.nodes]
    bias = BiasConfig(bias_dph=round(_uniform(rng, BIAS_DPH), 3),
                      lin_dph_per_c=round(_uniform(rng, BIAS_LIN_DPH_PER_C), 4),
                      node=str(rng.choice(nodes)))
    noise = NoiseConfig(arw_deg_per_sqrt_h=round(_log_uniform(rng, ARW_DEG_PER_SQRT_H), 4))
    cfg = SimConfig(scenario=f"population:{topology}{':cancel' if cancel else ''}")
    cfg.thermal, cfg.sf, cfg.bias, cfg.noise = thermal, sf, bias, noise
    return cfg


def hysteresis_for_seed(seed: int) -> EffectConfig | None:
    """Gyro `seed`'s SF hysteresis (a `hysteresis` effect), or None (seed 0, and the gyros
    outside HYST_SHARE): its own stream, so the other draws do not move."""
    if seed == 0:
        return None
    rng = np.random.default_rng([seed, HYST_STREAM])
    if rng.random() >= HYST_SHARE:
        return None
    width = round(_uniform(rng, HYST_WIDTH_C), 2)
    strength = round(_uniform(rng, HYST_PPM_PER_C), 3)
    return EffectConfig("hysteresis", strength, {"width_c": width})


def open_loop_for_seed(seed: int) -> EffectConfig:
    """Gyro `seed`'s open-loop response (an `open_loop` effect) from a stream of its own."""
    rng = np.random.default_rng([seed, OPEN_LOOP_STREAM])
    return EffectConfig("open_loop", round(_uniform(rng, OPEN_LOOP_FRACTION), 4),
                        {"tc_ppm_per_c": round(_uniform(rng, OPEN_LOOP_TC_PPM_PER_C), 1)})


def rate_response_for_seed(seed: int) -> list[EffectConfig]:
    """Gyro `seed`'s closed-loop rate response: a `rate_nonlinearity` and an `asymmetry`."""
    rng = np.random.default_rng([seed, RATE_RESPONSE_STREAM])
    nonlin = round(_uniform(rng, CLOSED_LOOP_NONLIN_PPM), 2)
    exponent = round(_uniform(rng, CLOSED_LOOP_EXPONENT), 3)
    asym = round(_uniform(rng, CLOSED_LOOP_ASYM_PPM), 2)
    return [EffectConfig("rate_nonlinearity", nonlin, {"exponent": exponent}),
            EffectConfig("asymmetry", asym)]


def gyro_for_seed(seed: int, hysteresis: bool = True, thermal_bias: bool = False,
                  open_loop: bool = False, rate_response: bool = False) -> SimConfig:
    """The population's gyro number `seed` (seed 0: the default gyro). hysteresis=False:
    the same gyro without its SF hysteresis, if it draws one; with `thermal_bias`, its bias
    on the coil with a Shupe term, a quadratic and a cubic (`with_thermal_bias`); with
    `open_loop`, the same gyro as an open-loop FOG (`open_loop_for_seed`); with
    `rate_response`, as a closed-loop FOG with its rate terms (`rate_response_for_seed`)."""
    if rate_response:
        cfg = gyro_for_seed(seed, hysteresis, thermal_bias, open_loop)
        cfg.effects.extend(rate_response_for_seed(seed))
        cfg.scenario += ":rate-response"
        return cfg
    if open_loop:
        cfg = gyro_for_seed(seed, hysteresis, thermal_bias)
        cfg.effects.append(open_loop_for_seed(seed))
        cfg.scenario += ":open-loop"
        return cfg
    if seed == 0:
        cfg = SimConfig(scenario="population:default")
    else:
        cfg = sample_gyro(np.random.default_rng([seed, 0x9F0]))
        hyst = hysteresis_for_seed(seed) if hysteresis else None
        if hyst is not None:
            cfg.effects.append(hyst)
            cfg.scenario += ":hyst"
    return with_thermal_bias(cfg, seed) if thermal_bias else cfg


def sf_parts(cfg: SimConfig) -> list[str]:
    """The internal parts (not housing or board) whose temperature an SF factor reads, in
    the network's order."""
    read = {name for t in cfg.sf.terms for name in t.nodes}
    return [n.name for n in cfg.thermal.nodes[2:] if n.name in read]


def outside_form(cfg: SimConfig, seed: int, form: str) -> SimConfig:
    """`cfg` (a population gyro) given a form outside the population's (OUTSIDE_FORMS),
    drawn from (seed, OUTSIDE_STREAM), not from the gyro's own stream: "sensor" puts the
    thermometer on a node behind the board; "vent" moves one of `sf_parts` behind the
    chamber air, with its own time constant (the parts behind it follow it)."""
    if form not in OUTSIDE_FORMS:
        raise ValueError(f"outside form must be one of {', '.join(OUTSIDE_FORMS)}, got {form!r}")
    rng = np.random.default_rng([seed, OUTSIDE_STREAM])
    out = copy.deepcopy(cfg)
    if form == "sensor":
        tau = round(_log_uniform(rng, SENSOR_TAU_S), 1)
        out.thermal.nodes.append(NodeConfig("sensor", out.thermal.board_node, tau, 0.0))
        out.thermal.board_node = "sensor"
    else:
        parts = sf_parts(out)
        name = parts[int(rng.integers(len(parts)))]
        node = next(n for n in out.thermal.nodes if n.name == name)
        node.parent, node.tau_s = "chamber", round(_log_uniform(rng, VENT_TAU_S), 1)
    out.scenario += f":{form}"
    return out


def with_thermal_bias(cfg: SimConfig, seed: int) -> SimConfig:
    """`cfg` with its bias (offset and slope kept) moved onto its first coil node and given a
    Shupe term, a quadratic and a cubic, drawn from a stream of their own (seed, 0xB1A5): the
    gyro's thermal network, SF law, bias offset and slope and noise are those of
    `gyro_for_seed(seed)`. Not drawn by default: the SF benches run at a constant table
    rate, where a bias is an apparent SF (bias / rate), and their figures would move."""
    rng = np.random.default_rng([seed, 0xB1A5])
    out = copy.deepcopy(cfg)
    coils = [n.name for n in out.thermal.nodes if n.name.startswith("coil")]
    shupe = float(rng.choice([-1.0, 1.0])) * _log_uniform(rng, SHUPE_DPH_PER_C_PER_MIN)
    out.bias.node = coils[0] if coils else out.bias.node
    out.bias.shupe_dph_per_c_per_min = round(shupe, 3)
    out.bias.quad_dph_per_c2 = float(f"{_uniform(rng, BIAS_QUAD_DPH_PER_C2):.3g}")
    out.bias.cube_dph_per_c3 = float(f"{_uniform(rng, BIAS_CUBE_DPH_PER_C3):.3g}")
    return out


def with_gyro(run: SimConfig, gyro: SimConfig) -> SimConfig:
    """`run`'s chamber program, table, seed and effects on `gyro`'s physics (a new config):
    its thermal network, SF law, bias, noise and SF hysteresis (GYRO_EFFECTS, unless the
    run plants its own)."""
    out = copy.deepcopy(run)
    out.thermal = copy.deepcopy(gyro.thermal)
    out.thermal.start = run.thermal.start
    out.sf, out.bias, out.noise = (copy.deepcopy(gyro.sf), copy.deepcopy(gyro.bias),
                                   copy.deepcopy(gyro.noise))
    named = {e.name for e in out.effects}  # a run's own (planted) hysteresis stays
    out.effects += [copy.deepcopy(e) for e in gyro.effects
                    if e.name in GYRO_EFFECTS and e.name not in named]
    return out


def run_on_gyro(gyro: SimConfig, profile: ProfileConfig, seed: int, name: str,
                table_dps: float = 10.0) -> SimConfig:
    """A warm-start run of `profile` on `gyro` at a constant table rate (the benches' and
    the planner's runs)."""
    run = SimConfig(scenario=f"population:{name}", seed=seed)
    run.profile = profile
    run.table = TableConfig(kind="constant", rate_dps=table_dps)
    run.thermal.start = "warm"
    return with_gyro(run, gyro)


def seed_range(name: str) -> range:
    """DEV_SEEDS or EVAL_SEEDS by name ("dev" or "eval")."""
    ranges = {"dev": DEV_SEEDS, "eval": EVAL_SEEDS}
    if name not in ranges:
        raise ValueError(f"seed range must be one of {', '.join(ranges)}")
    return ranges[name]
