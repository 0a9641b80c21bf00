"""Optional effects, switched on with `fogsf simulate --effect NAME=STRENGTH[,param=value]`.

Each effect is a pure function of the run's context (time, table rate, true node
temperatures) that returns its own additive terms: an SF term in ppm and/or a bias term in
deg/s. They are what `fogsf diagnose` must be able to find in a measured log.

warmup=PPM (ppm; param tau_s=600)
    Start-up transient of the SF after power-on that the board thermometer does not see:
    the SLD's wavelength settles as its junction and drive current stabilise (the paper's
    ref. [6]) and the loop gain settles. SF term = PPM * exp(-t/tau_s), t since power-on
    (t=0 of the log). Use with `--start power-on`.
extra_lag=SECONDS (s; param sens_ppm_per_c=4)
    An extra slow thermal node (potting, mounting plate, a second coil layer) that lags the
    housing with time constant SECONDS and whose temperature the SF feels:
    SF term = sens_ppm_per_c * (T_extra - T_housing). Zero at equilibrium, grows with the
    ramp rate, and keeps settling for several SECONDS after a ramp stops.
temp_rate=PPM_PER_C_PER_MIN (ppm/(C/min))
    SF term proportional to the coil's rate of temperature change (radial gradient across
    the winding and the stress it causes): SF term = STRENGTH * dT_coil/dt, T_coil the mean
    of the coil nodes, in C/min. Flips sign between up and down ramps.
rate_nonlinearity=PPM (ppm at ref_rate_dps; param ref_rate_dps=100)
    SF that depends on the input rate's magnitude (phase-ramp reset and 2*pi-gain errors of
    the closed loop): SF term = PPM * |rate| / ref_rate_dps. Seen only with several table
    rates; invisible at one constant rate (it is then a constant SF offset).
asymmetry=PPM (ppm)
    Different SF for positive and negative rates (polarity-dependent feedback-ramp
    electronics): SF term = +PPM/2 for positive rates, -PPM/2 for negative ones, the same at
    every |rate| (so, unlike a bias, it does not scale with 1/rate).
bias_drift=DPH_PER_C (deg/h per C; param ref_c=20)
    Temperature-dependent bias following the board node: bias += STRENGTH * (T_board -
    ref_c). At one table rate it leaks into the apparent SF as bias/rate (1 deg/h at
    10 deg/s is 27.8 ppm), so it scales with 1/rate and cancels in +/- pairs.
bias_shupe=DPH_PER_C_PER_MIN (deg/h per C/min)
    The Shupe bias: a temperature gradient along the fibre while the coil's temperature
    changes gives a bias proportional to its rate of change: bias += STRENGTH * dT_coil/dt,
    T_coil the mean of the coil nodes, in C/min. Flips sign between up and down ramps; at
    one table rate it is an apparent SF (bias/rate) of the temp_rate form, +/- pairs show
    it as a bias.
aging=PPM_PER_H (ppm/h)
    Slow SF drift with elapsed time (source ageing, fiber and potting relaxation): SF term =
    STRENGTH * t / 3600, at any temperature.
open_loop=FRACTION (of pi/2 at full_scale_dps; params full_scale_dps=150,
        tc_ppm_per_c=-400, ref_c=20)
    An open-loop FOG: the output follows the sine of the Sagnac phase, phi = K * w (w the
    rate the coil turns at, table + earth; K in rad per deg/s, K = FRACTION * (pi/2) /
    full_scale_dps at ref_c, so full scale reaches FRACTION of pi/2). Output =
    (1 + SF) * sin(phi) / K: the SF at small rate is the closed-loop law's (every SF term
    above), at full scale the output falls short by the factor sin(phi)/phi (FRACTION 0.2:
    1.6 %). K = 2 pi L D / (lambda c) moves with temperature: K(T) = K * (1 + tc_ppm_per_c
    * 1e-6 * (T - ref_c)), T the source node's (the wavelength; the coil's mean without a
    source node). Not an SF term: a gain on the whole rate response (EffectTerms.gain).
hysteresis=PPM_PER_C (ppm/C; params width_c=6, plays=1)
    Rate-independent hysteresis of the coil's potting stress, which sticks and releases: a
    play (backlash) operator of the coil temperature T_coil (the mean of the coil nodes),
    p = min(max(p, T_coil - width_c/2), T_coil + width_c/2), started at T_coil's first
    value; SF term = STRENGTH * (p - T_coil), within +-STRENGTH * width_c / 2. It holds its
    value through a soak (no filter of T does) and depends on the reversal points, not the
    rate. plays=N > 1: a small Preisach (Prandtl-Ishlinskii) sum of N plays of widths
    width_c * i / N (i = 1..N), each of strength STRENGTH / N.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from fogsf.errors import UserError
from fogsf.sim.lag import first_order_lag


@dataclass
class EffectConfig:
    """One optional effect (see EFFECTS below): name, strength in its unit, params."""

    name: str
    strength: float
    params: dict[str, float] = field(default_factory=dict)


@dataclass
class EffectContext:
    """What an effect may look at: times, table rate and true node temperatures."""

    t_s: np.ndarray
    dt_s: float
    table_dps: np.ndarray
    nodes: dict[str, np.ndarray]
    board_node: str = "board"
    earth_dps: np.ndarray | float = 0.0  # the earth rate on the axis (the coil turns at both)

    def coil_c(self) -> np.ndarray:
        names = [k for k in self.nodes if k.startswith("coil")]
        if not names:
            raise UserError("this effect needs coil nodes (names starting with 'coil')")
        return cast(np.ndarray,  # names not empty: an array
                    sum(self.nodes[k] for k in names) / len(names))

    def housing_c(self) -> np.ndarray:
        return self.nodes.get("housing", self.nodes["chamber"])


@dataclass
class EffectTerms:
    """An effect's additive terms (zeros where it has none), and for a response effect
    (open_loop) its gain on the whole rate response: the output is (rate) * (1 + SF) * gain,
    so sf_ppm is then (gain - 1) * 1e6, what the gain is on its own."""

    sf_ppm: np.ndarray
    bias_dps: np.ndarray
    gain: np.ndarray | None = None


def _terms(ctx: EffectContext, sf_ppm: np.ndarray | float = 0.0,
           bias_dps: np.ndarray | float = 0.0) -> EffectTerms:
    n = ctx.t_s.shape
    return EffectTerms(np.broadcast_to(np.asarray(sf_ppm, dtype=np.float64), n).copy(),
                       np.broadcast_to(np.asarray(bias_dps, dtype=np.float64), n).copy())


def warmup(ctx: EffectContext, strength: float, tau_s: float = 600.0) -> EffectTerms:
    return _terms(ctx, sf_ppm=strength * np.exp(-ctx.t_s / tau_s))


def extra_lag(ctx: EffectContext, strength: float, sens_ppm_per_c: float = 4.0) -> EffectTerms:
    h = ctx.housing_c()
    slow = first_order_lag(h, strength, ctx.dt_s, float(h[0]))
    return _terms(ctx, sf_ppm=sens_ppm_per_c * (slow - h))


def temp_rate(ctx: EffectContext, strength: float) -> EffectTerms:
    coil = ctx.coil_c()
    rate_c_per_min = np.gradient(coil, ctx.dt_s) * 60.0 if coil.shape[0] > 1 else coil * 0
    return _terms(ctx, sf_ppm=strength * rate_c_per_min)


def rate_nonlinearity(ctx: EffectContext, strength: float, ref_rate_dps: float = 100.0,
                      exponent: float = 1.0) -> EffectTerms:
    return _terms(ctx, sf_ppm=strength * (np.abs(ctx.table_dps) / ref_rate_dps) ** exponent)


def asymmetry(ctx: EffectContext, strength: float) -> EffectTerms:
    return _terms(ctx, sf_ppm=0.5 * strength * np.sign(ctx.table_dps))


def open_loop_gain(rate_dps: np.ndarray, phase_rad_per_dps: np.ndarray | float
                   ) -> np.ndarray:
    """sin(K w) / (K w), 1 at w = 0: the open-loop output over the closed-loop one."""
    phi = np.asarray(phase_rad_per_dps, dtype=np.float64) * np.asarray(rate_dps, np.float64)
    # np.sinc(x) = sin(pi x) / (pi x), exact 1 at 0 (no 0/0 at a zero-rate plateau)
    return np.sinc(phi / np.pi)


def open_loop(ctx: EffectContext, strength: float, full_scale_dps: float = 150.0,
              tc_ppm_per_c: float = -400.0, ref_c: float = 20.0) -> EffectTerms:
    """A gain, not an additive SF term: (1 + SF) * gain keeps the closed-loop SF at small
    rate whatever the other terms are (an additive ppm would be off by SF * (gain - 1)).

    An effect rather than a field of the gyro's configuration: every existing configuration
    (and every population gyro's, hashed in tests) keeps its JSON and its bytes, off unless
    given; `--effect`, the rigs' `effects=`, `--config` files and diagnose's extended models
    carry it as they carry rate_nonlinearity and asymmetry; and the population's
    `GYRO_EFFECTS` carries it as the gyro's own physics onto any run."""
    temp = ctx.nodes["source"] if "source" in ctx.nodes else ctx.coil_c()
    k = strength * (0.5 * math.pi) / full_scale_dps * (1.0 + tc_ppm_per_c * 1e-6
                                                      * (temp - ref_c))
    gain = open_loop_gain(ctx.table_dps + ctx.earth_dps, k)
    out = _terms(ctx, sf_ppm=(gain - 1.0) * 1e6)
    out.gain = gain
    return out


def bias_drift(ctx: EffectContext, strength: float, ref_c: float = 20.0,
               node_tau_s: float = 0.0) -> EffectTerms:
    """On the board (node_tau_s 0), or on an internal node lagging the housing by node_tau_s."""
    if node_tau_s > 0.0:
        h = ctx.housing_c()
        temp = first_order_lag(h, node_tau_s, ctx.dt_s, float(h[0]))
    else:
        temp = ctx.nodes[ctx.board_node]
    return _terms(ctx, bias_dps=strength * (temp - ref_c) / 3600.0)


def bias_shupe(ctx: EffectContext, strength: float) -> EffectTerms:
    coil = ctx.coil_c()
    rate_c_per_min = np.gradient(coil, ctx.dt_s) * 60.0 if coil.shape[0] > 1 else coil * 0
    return _terms(ctx, bias_dps=strength * rate_c_per_min / 3600.0)


def aging(ctx: EffectContext, strength: float, settle_tau_s: float = 0.0) -> EffectTerms:
    """Linear (settle_tau_s 0), or settling: STRENGTH * tau/3600 * (1 - exp(-t/tau)), the
    same initial slope in ppm/h."""
    if settle_tau_s > 0.0:
        t = ctx.t_s - float(ctx.t_s[0])
        return _terms(ctx, sf_ppm=strength * settle_tau_s / 3600.0
                      * (1.0 - np.exp(-t / settle_tau_s)))
    return _terms(ctx, sf_ppm=strength * ctx.t_s / 3600.0)


def play_operator(x: np.ndarray, width_c: float, p0: float | None = None) -> np.ndarray:
    """The play (backlash) operator: p = min(max(p, x - width/2), x + width/2) per sample,
    from p0 (default x[0]). width 0: p = x."""
    xs = np.asarray(x, dtype=np.float64)
    out = np.empty_like(xs)
    if xs.size == 0:
        return out
    half = 0.5 * float(width_c)
    p = float(xs[0]) if p0 is None else float(p0)
    for i, v in enumerate(xs.tolist()):
        lo, hi = v - half, v + half
        p = lo if p < lo else (hi if p > hi else p)
        out[i] = p
    return out


def preisach_offset(x: np.ndarray, width_c: float, plays: int = 1) -> np.ndarray:
    """mean over i = 1..N of play(x, width_c * i / N) - x: the hysteresis term per unit
    strength (C)."""
    n = max(1, int(round(plays)))
    xs = np.asarray(x, dtype=np.float64)
    return cast(np.ndarray,  # n >= 1 terms: an array
                sum(play_operator(xs, width_c * (i + 1) / n) - xs for i in range(n)) / n)


def hysteresis(ctx: EffectContext, strength: float, width_c: float = 6.0,
               plays: float = 1.0) -> EffectTerms:
    return _terms(ctx, sf_ppm=strength * preisach_offset(ctx.coil_c(), width_c, int(plays)))


@dataclass(frozen=True)
class EffectInfo:
    name: str
    unit: str
    meaning: str
    func: Callable[..., EffectTerms]
    params: dict[str, float] = field(default_factory=dict)
    example: float = 0.0
    positive: bool = False  # strength must be > 0 (a time constant)


EFFECTS: dict[str, EffectInfo] = {e.name: e for e in [
    EffectInfo("warmup", "ppm", "SF start-up transient after power-on, decaying with tau_s "
               "(SLD wavelength and loop settling), unseen by the thermometer", warmup,
               {"tau_s": 600.0}, 200.0),
    EffectInfo("extra_lag", "s", "an extra slow thermal node lagging the housing by STRENGTH "
               "seconds; SF term sens_ppm_per_c * (T_extra - T_housing)", extra_lag,
               {"sens_ppm_per_c": 4.0}, 3600.0, positive=True),
    EffectInfo("temp_rate", "ppm/(C/min)", "SF term proportional to the coil's dT/dt "
               "(radial gradient in the winding); flips sign between up and down ramps",
               temp_rate, {}, 30.0),
    EffectInfo("rate_nonlinearity", "ppm at ref_rate_dps", "SF grows with |rate|: "
               "STRENGTH * (|rate| / ref_rate_dps)^exponent (closed-loop reset / 2pi-gain "
               "errors)", rate_nonlinearity, {"ref_rate_dps": 100.0, "exponent": 1.0}, 200.0),
    EffectInfo("asymmetry", "ppm", "SF(+rate) - SF(-rate), the same at every |rate| "
               "(polarity-dependent feedback electronics)", asymmetry, {}, 100.0),
    EffectInfo("bias_drift", "deg/h/C", "bias following the board temperature, "
               "STRENGTH * (T - ref_c), T the board's or (node_tau_s > 0) an internal node "
               "lagging the housing by node_tau_s; leaks into the apparent SF as bias/rate",
               bias_drift, {"ref_c": 20.0, "node_tau_s": 0.0}, 0.05),
    EffectInfo("bias_shupe", "deg/h/(C/min)", "Shupe bias: a bias proportional to the "
               "coil's dT/dt (a gradient along the fibre); flips sign between up and down "
               "ramps, leaks into the apparent SF as bias/rate", bias_shupe, {}, 2.0),
    EffectInfo("aging", "ppm/h", "SF drift with elapsed time at any temperature "
               "(source ageing, fiber/potting relaxation); linear, or settling with "
               "settle_tau_s > 0 (initial slope STRENGTH)", aging, {"settle_tau_s": 0.0},
               20.0),
    EffectInfo("open_loop", "of pi/2 at full_scale_dps", "an open-loop FOG: output "
               "(1 + SF) sin(K w) / K, w the rate (table + earth), K = STRENGTH (pi/2) / "
               "full_scale_dps rad per deg/s moving tc_ppm_per_c per C of the source node "
               "from ref_c; the SF at small rate is the closed-loop one", open_loop,
               {"full_scale_dps": 150.0, "tc_ppm_per_c": -400.0, "ref_c": 20.0}, 0.2,
               positive=True),
    EffectInfo("hysteresis", "ppm/C", "rate-independent hysteresis of the coil's potting "
               "stress: STRENGTH * (play(T_coil, width_c) - T_coil), a backlash that holds "
               "through a soak; plays > 1: a Preisach sum of plays up to width_c",
               hysteresis, {"width_c": 6.0, "plays": 1.0}, 5.0),
]}


def check_effect(e: EffectConfig) -> None:
    info = EFFECTS.get(e.name)
    if info is None:
        raise UserError(f"unknown effect {e.name!r}; known: {', '.join(EFFECTS)} "
                        "(see fogsf simulate --list-effects)")
    if not isinstance(e.strength, int | float) or not math.isfinite(e.strength):
        raise UserError(f"effect {e.name}: strength must be a finite number")
    if info.positive and e.strength <= 0:
        raise UserError(f"effect {e.name}: strength ({info.unit}) must be > 0")
    bad = sorted(set(e.params) - set(info.params))
    if bad:
        allowed = ", ".join(info.params) or "none"
        raise UserError(f"effect {e.name}: unknown parameter(s) {', '.join(bad)} "
                        f"(allowed: {allowed})")
    for k, v in e.params.items():
        if not isinstance(v, int | float) or not math.isfinite(v):
            raise UserError(f"effect {e.name}: parameter {k} must be a finite number")
    if e.name == "warmup" and e.params.get("tau_s", 1.0) <= 0:
        raise UserError("effect warmup: tau_s must be > 0")
    if any(e.params.get(k, 0.0) < 0 for k in ("node_tau_s", "settle_tau_s", "exponent")):
        raise UserError(f"effect {e.name}: node_tau_s, settle_tau_s and exponent must be >= 0")
    if e.name == "hysteresis" and (e.params.get("width_c", 6.0) < 0
                                   or not 1 <= e.params.get("plays", 1.0) <= 16
                                   or e.params.get("plays", 1.0) != int(e.params.get("plays",
                                                                                     1.0))):
        raise UserError("effect hysteresis: width_c must be >= 0 and plays a whole number "
                        "in 1..16")
    if e.name == "rate_nonlinearity" and e.params.get("ref_rate_dps", 1.0) <= 0:
        raise UserError("effect rate_nonlinearity: ref_rate_dps must be > 0")
    # past pi/2 the sine turns back: two rates give one output, no gyro is run there
    if e.name == "open_loop" and (e.strength >= 1.0 or e.params.get("full_scale_dps", 1.0) <= 0
                                  or abs(e.params.get("tc_ppm_per_c", 0.0)) >= 1e4):
        raise UserError("effect open_loop: the strength (a fraction of pi/2 at full scale) "
                        "must lie in 0..1, full_scale_dps > 0, |tc_ppm_per_c| < 10000")


def parse_effect(text: str) -> EffectConfig:
    """'NAME=STRENGTH[,param=value...]' -> EffectConfig (checked)."""
    parts = [p.strip() for p in text.split(",")]
    head = parts[0]
    if "=" not in head:
        raise UserError(f"--effect {text!r}: expected NAME=STRENGTH, e.g. temp_rate=30")
    name, _, val = head.partition("=")
    try:
        strength = float(val)
    except ValueError:
        raise UserError(f"--effect {text!r}: strength {val!r} is not a number") from None
    params: dict[str, float] = {}
    for p in parts[1:]:
        k, sep, v = p.partition("=")
        try:
            if not sep:
                raise ValueError
            params[k.strip()] = float(v)
        except ValueError:
            raise UserError(f"--effect {text!r}: parameter {p!r} must be key=number") from None
    e = EffectConfig(name.strip(), strength, params)
    check_effect(e)
    return e


def effect_terms(ctx: EffectContext, e: EffectConfig) -> EffectTerms:
    """One effect's terms."""
    check_effect(e)
    info = EFFECTS[e.name]
    return info.func(ctx, e.strength, **{**info.params, **e.params})


def apply_effects(ctx: EffectContext, effects: list[EffectConfig],
                  base_sf_ppm: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Sum of every effect's SF term (ppm) and bias term (deg/s). A response effect's gain
    (open_loop) multiplies the whole SF, 1 + (base_sf_ppm + the sum) * 1e-6; the SF term
    returned is then that product's less base_sf_ppm, so base + it stays the exact total."""
    sf = np.zeros(ctx.t_s.shape)
    bias = np.zeros(ctx.t_s.shape)
    gains = []
    for e in effects:
        terms = effect_terms(ctx, e)
        if terms.gain is not None:
            gains.append(terms.gain)
            continue
        sf += terms.sf_ppm
        bias += terms.bias_dps
    if gains:  # only here: runs without a gain keep their bytes
        total = 1.0 + (base_sf_ppm + sf) * 1e-6
        for g in gains:
            total = total * g
        sf = (total - 1.0) * 1e6 - base_sf_ppm
    return sf, bias


def describe() -> str:
    """The --list-effects text: name, unit, default params, meaning."""
    lines = []
    for info in EFFECTS.values():
        params = ", ".join(f"{k}={v:g}" for k, v in info.params.items())
        lines.append(f"{info.name:18s} [{info.unit}] e.g. --effect {info.name}={info.example:g}"
                     + (f" (params: {params})" if params else ""))
        lines.append(f"{'':18s} {info.meaning}")
    return "\n".join(lines)
