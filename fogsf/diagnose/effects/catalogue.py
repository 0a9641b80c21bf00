"""The candidate effects: the simulator's eight (fogsf.sim.effects), each as one extra
column of the base model with, where it has one, a nonlinear parameter profiled on a grid.

Every candidate's linear coefficient is the effect's strength in the simulator's unit, so a
fitted candidate maps one to one onto `--effect NAME=STRENGTH[,param=value]`:

    warmup             exp(-t/tau_s)                      coef: ppm at power-on; tau_s
    extra_lag          lag(housing, tau) - housing (C)    coef: sens_ppm_per_c; strength tau
    temp_rate          d/dt of the coil (C/min)           coef: ppm/(C/min); coil_tau_s
    rate_nonlinearity  |rate| / 100 deg/s                 coef: ppm at 100 deg/s
    asymmetry          sign(rate) / 2                     coef: ppm, SF(+) - SF(-)
    bias_drift         (T_board - 20) * 1e6/(3600 rate)   coef: deg/h per C
    aging              t / 3600 s                         coef: ppm/h
    bias_shupe         d/dt of the coil * 1e6/(3600 rate) coef: deg/h per C/min; coil_tau_s
    hysteresis         play(coil, w) - coil (C)           coef: ppm/C; width_c (and the
                                                          coil's lag behind the housing)

The hysteresis form (`diagnose.effects.hysteresis_form`) is the play (backlash) operator of a coil
node lagging the housing, profiled over its width and the node's time constant: it holds its
value through a soak and turns with the temperature's reversals, whatever the rate.

The coil of `temp_rate` is wound in layers: its temperature is the mean of an inner and an
outer layer node, each lagging the housing (the simulator's effect differentiates the mean
of its coil nodes). The inner layer's time constant is profiled over 600-3000 s (a small
FOG's coil: 10-50 min) and the outer layer's ratio to it over COIL_RATIOS (1: one node);
the outer layer stays within 3000 s. A single node cannot follow a layered coil's rate once
the term is strong (its held-out residual stays non-white). In that model the base's nodes
are held to 600-3000 s too (the FOG's own nodes). With the base's slower node free up to
4000 s, base + coil would be three nodes up to 4000 s plus the housing term, i.e. an extra
lag of 4000-6000 s by another name. An extra lag is an extra *slow* node, profiled from
4000 s up (the base's nodes stay within 600-4000 s) and above 1.4x the base's slower node.
Both terms are (node - housing) / tau in form, so what tells them apart is how long they
keep settling after a ramp stops (see selection.nested_choice); on steady ramps alone
neither is separable from the base.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.diagnose import design
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects import hysteresis_form

BaseTheta = tuple[float, float]
# a profiled parameter: a value, or (first, further...) for a candidate profiled over several
# (intervals and refinement act on the first; the rest are profiled out)
GridValue = float | tuple[float, ...] | None


def first(g: GridValue) -> float:
    """The leading profiled parameter of a grid value (the one intervals are reported on)."""
    assert g is not None
    return float(g[0]) if isinstance(g, tuple) else float(g)


@dataclass(frozen=True)
class Candidate:
    name: str
    coef_name: str  # the linear coefficient, with its unit in the name
    grid_name: str | None  # the profiled parameter, with its unit
    grid: tuple[GridValue, ...]
    column: Callable[[RunContext, BaseTheta, GridValue], np.ndarray]
    meaning: str
    admissible: Callable[[BaseTheta, GridValue], bool] = lambda b, g: True
    # report the coefficient and parameter as profile-likelihood averages over the grid
    # parameter (see intervals._profile_average) rather than at its best value
    average: bool = False
    # an effect of the start-up after a power-on: scored only when a run starts at power-on
    # (driver.identify, or --start); a warm start has no start-up transient
    needs_power_on: bool = False
    # a grid of discrete forms (e.g. an exponent): no refinement or profile interval, the
    # best form is reported as `grid_name`
    forms: bool = False
    # a combined model (forward selection): earlier causes at their chosen grid values, in
    # order, then this one's own; names() gives one coefficient per part
    parts: tuple[tuple[Candidate, GridValue], ...] = ()

    def names(self) -> list[str]:
        """The coefficient names of this candidate's columns (one, or one per part)."""
        if not self.parts:
            return [self.coef_name]
        return [f"{c.name}.{c.coef_name}" for c, _ in self.parts]

    def own(self) -> Candidate:
        """The candidate this one profiles (itself, or the last of a combined model)."""
        return self.parts[-1][0] if self.parts and self.parts[-1][1] is _OWN else self

    def to_effect(self, coef: float, theta: GridValue) -> dict:
        """The simulator's effect entry (fogsf.sim.config.EffectConfig as a dict); a form
        other than the simulator's default carries it in `params` (exponent, node_tau_s,
        settle_tau_s), which the simulator's effects take."""
        if self.name == "rate_nonlinearity":
            p = {"ref_rate_dps": 100.0}
            if theta is not None and first(theta) != 1.0:
                p["exponent"] = first(theta)
            return {"name": self.name, "strength": coef, "params": p}
        if self.name == "bias_drift":
            # a lead (node_tau_s < 0) is not the simulator's effect's: extend carries it as
            # the bias's dT/dt term on the board (bias.shupe_dph_per_c_per_min)
            p = {"ref_c": design.T_REF_C}
            if theta is not None and first(theta) > 0.0:
                p["node_tau_s"] = first(theta)
            return {"name": self.name, "strength": coef, "params": p}
        if self.name == "aging":
            p = {}
            if theta is not None and math.isfinite(first(theta)):
                p["settle_tau_s"] = first(theta)
            return {"name": self.name, "strength": coef, "params": p}
        if self.name == "hysteresis":
            return {"name": "hysteresis", "strength": coef,
                    "params": {"width_c": first(theta)}}
        if self.name == "warmup":
            return {"name": "warmup", "strength": coef, "params": {"tau_s": theta}}
        if self.name == "extra_lag":
            return {"name": "extra_lag", "strength": theta,
                    "params": {"sens_ppm_per_c": coef}}
        return {"name": self.name, "strength": coef, "params": {}}


def _warmup(ctx: RunContext, b: BaseTheta, tau: GridValue) -> np.ndarray:
    return design.decay(ctx, first(tau))


def _extra_lag(ctx: RunContext, b: BaseTheta, tau: GridValue) -> np.ndarray:
    return design.node(ctx, first(tau)) - design.drive(ctx)


def coil_taus(g: GridValue) -> tuple[float, float]:
    """(inner, outer) layer time constants of a temp_rate grid value (tau, ratio)."""
    assert isinstance(g, tuple)
    return float(g[0]), float(round(g[0] * g[1], 1))


def housing_coupling(strength: float, g: GridValue) -> float:
    """The dT/dt term's coupling to the housing (ppm per C): a layer lagging the housing by
    tau has dT/dt = (housing - T) / tau, so strength * dT_coil/dt holds the housing with
    strength * 60 * mean(1 / tau) (C/min). The base model holds every lagged node's
    temperature but not the housing's lead over the board, so this, not the strength, is
    what the logs pin; the strength needs the coil's time constants too."""
    return strength * 60.0 * float(np.mean([1.0 / t for t in coil_taus(g)]))


def _temp_rate(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    h = design.drive(ctx)
    rates = [(h - design.node(ctx, tau)) / tau for tau in coil_taus(g)]
    return 0.5 * (rates[0] + rates[1]) * 60.0


def _rate_nonlinearity(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    """(|rate| / 100)^p: p = 1 linear in |rate|, 2 quadratic, 1.5 between (both terms)."""
    return (np.abs(ctx.run.rate) / 100.0) ** (1.0 if g is None else first(g))


def _asymmetry(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    return 0.5 * np.sign(ctx.run.rate)


def _bias_drift(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    """A bias following the board thermometer (g = 0), an internal node lagging the driver
    by g seconds (e.g. the coil or the source), or (g < 0) a node the board thermometer
    lags by -g seconds: board + (-g) dT_board/dt. The last is a coil right behind the
    housing and faster than the board; without the chamber air the driver is the board
    itself, and a lag of it cannot lead it. With one table rate the bias is an SF term in
    temperature, and a lagged node would be a thermal node by another name: the board's
    form only, which the base absorbs."""
    tau = 0.0 if g is None or not ctx.bias_on else first(g)
    if tau < 0.0:
        temp = design.board(ctx) - tau / 60.0 * design.board_rate_c_per_min(ctx)
    else:
        temp = design.board(ctx) if tau == 0.0 else design.node(ctx, tau)
    return temp * design.PPM_PER_DPH / ctx.run.rate


def _bias_shupe(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    """The Shupe bias: the layered coil's rate of change (C/min, as temp_rate's) as a bias.
    With one table rate it is temp_rate's column times a constant, an SF term by another
    name: zero then (not identifiable), as a bias needs a second |rate| or both signs."""
    if not ctx.bias_on:
        return np.zeros(ctx.run.rate.shape)
    return _temp_rate(ctx, b, g) * design.PPM_PER_DPH / ctx.run.rate


def _aging(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
    """Drift with time: linear (g = inf), or settling as tau (1 - exp(-t/tau)) with time
    constant g; the coefficient is the initial slope in ppm/h either way."""
    tau = math.inf if g is None else first(g)
    if not math.isfinite(tau):
        return ctx.run.t_s / 3600.0
    return design.settle(ctx, tau) * tau / 3600.0


WARMUP_GRID_S = tuple(float(x) for x in np.round(np.geomspace(60.0, 3600.0, 13), -1))
# the coil's layers: 150-3000 s, the population's internal nodes from their fastest
# (docs/population.md) to the base's slowest next to a coil
COIL_TAU_GRID_S = tuple(float(x) for x in np.round(np.geomspace(150.0, 3000.0, 11), -1))
COIL_RATIOS = (1.0, 1.41, 2.0)  # outer / inner layer
COIL_GRID = tuple((t, r) for r in COIL_RATIOS for t in COIL_TAU_GRID_S
                  if t * r <= COIL_TAU_GRID_S[-1] + 1.0)
RATE_EXPONENTS = (1.0, 1.5, 2.0)
# 0: the board thermometer; < 0: a node the board lags by that much (at most the
# population's slowest board, fogsf.sim.population.BOARD_TAU_S)
BIAS_NODE_TAU_S = (0.0, 300.0, 600.0, 1200.0, 2400.0, 4000.0,
                   *(-float(x) for x in np.round(np.geomspace(30.0, 600.0, 11), -1)))
AGING_SETTLE_S = (math.inf, 21600.0, 10800.0, 5400.0)  # inf: linear
EXTRA_LAG_GRID_S = tuple(float(x) for x in np.round(np.geomspace(4000.0, 32000.0, 10), -2))

CATALOGUE: dict[str, Candidate] = {c.name: c for c in [
    Candidate("warmup", "strength_ppm", "tau_s", WARMUP_GRID_S, _warmup,
              "SF start-up transient after power-on, unseen by the thermometer",
              needs_power_on=True),
    Candidate("extra_lag", "sens_ppm_per_c", "tau_s", EXTRA_LAG_GRID_S, _extra_lag,
              "an extra slow thermal node lagging the housing",
              admissible=lambda b, g: g is not None and not isinstance(g, tuple)
              and g >= design.MIN_TAU_RATIO * b[1]),
    Candidate("temp_rate", "strength_ppm_per_c_per_min", "coil_tau_s", COIL_GRID,
              _temp_rate, "SF term in the coil's rate of temperature change",
              admissible=lambda b, g: b[1] <= COIL_TAU_GRID_S[-1], average=True),
    Candidate("rate_nonlinearity", "strength_ppm_at_100dps", "exponent", RATE_EXPONENTS,
              _rate_nonlinearity, "SF that grows with |rate| (linear, quadratic or between)",
              forms=True),
    Candidate("asymmetry", "strength_ppm", None, (None,), _asymmetry,
              "different SF for positive and negative rates"),
    Candidate("bias_drift", "strength_dph_per_c", "node_tau_s", BIAS_NODE_TAU_S, _bias_drift,
              "temperature-dependent bias (leaks into the SF as bias/rate), following the "
              "board (node_tau_s 0) or a lagged internal node", forms=True),
    Candidate("aging", "strength_ppm_per_h", "settle_tau_s", AGING_SETTLE_S, _aging,
              "SF drift with elapsed time, linear (settle_tau_s inf) or settling", forms=True),
    Candidate("hysteresis", "strength_ppm_per_c", "width_c", hysteresis_form.GRID,
              hysteresis_form.column, "rate-independent SF hysteresis: a play (backlash) "
              "of the coil temperature that holds through a soak"),
    Candidate("bias_shupe", "strength_dph_per_c_per_min", "coil_tau_s", COIL_GRID,
              _bias_shupe, "Shupe bias: a bias in the coil's rate of temperature change",
              average=True),
]}

# Not a cause: the reference that the node-like candidates (NODE_LIKE) must beat. The base's
# two nodes stand for the FOG's several (coil layers, source); on long logs a third node
# of the base's kind (within its 600-4000 s, away from both of its nodes) can still lower
# the residual a little, and any node-like candidate would take that gain for itself.
NODE_LIKE = ("temp_rate", "extra_lag")
# also checked against a third base node: a drift over a log is what a slow node the base
# lacks looks like (population gyros with 3-6 internal nodes), unless the log returns to
# a temperature it held before, where a node comes back and a drift does not
# a play of a lagged node too: on an up-and-back log its direction-dependent offset is
# what a node the base lacks looks like, unless the log holds a soak inside a loop
THIRD_NODE_CHECK = (*NODE_LIKE, "aging", "hysteresis")


def _node(ctx: RunContext, b: BaseTheta, tau: GridValue) -> np.ndarray:
    return design.node(ctx, first(tau))


EXTRA_NODE = Candidate(
    "extra_node", "node3_ppm_per_c", "node3_tau_s", design.BASE_TAU_GRID_S, _node,
    "a third node of the base's kind (reference only)",
    admissible=lambda b, g: g is not None and all(
        max(first(g), t) >= design.MIN_TAU_RATIO * min(first(g), t) for t in b))


_OWN: GridValue = None  # marks the profiled (last) part of a combined model


def combine(chosen: list[tuple[Candidate, GridValue]], cand: Candidate) -> Candidate:
    """`cand` added to earlier causes held at their chosen grid values (forward selection):
    one column per cause, `cand`'s profiled over its grid as on its own."""
    if any(c.name == cand.name for c, _ in chosen):
        raise ValueError(f"{cand.name} is already in the model")
    fixed = tuple(chosen)

    def column(ctx: RunContext, b: BaseTheta, g: GridValue) -> np.ndarray:
        return np.column_stack([c.column(ctx, b, gv) for c, gv in fixed]
                               + [cand.column(ctx, b, g)])

    def admissible(b: BaseTheta, g: GridValue) -> bool:
        return cand.admissible(b, g) and all(c.admissible(b, gv) for c, gv in fixed)

    return Candidate("+".join([c.name for c, _ in fixed] + [cand.name]), cand.coef_name,
                     cand.grid_name, cand.grid, column, cand.meaning, admissible,
                     forms=True, parts=(*fixed, (cand, _OWN)))


def with_extra_node(cand: Candidate) -> Candidate:
    """`cand` on a base with a third node of its kind (EXTRA_NODE), both profiled: its grid
    values get the node's time constant appended. Its design matrices carry one column more
    than its names say; it is for profile SSEs only (see intervals.interval_with_extra_node)."""
    nested = isinstance(cand.grid[0], tuple)

    def own(gg: GridValue) -> GridValue:
        assert isinstance(gg, tuple)
        return tuple(gg[:-1]) if nested else gg[0]

    def column(ctx: RunContext, b: BaseTheta, gg: GridValue) -> np.ndarray:
        assert isinstance(gg, tuple)
        return np.column_stack([cand.column(ctx, b, own(gg)), design.node(ctx, gg[-1])])

    grid = tuple((*(g if isinstance(g, tuple) else (g,)), t3)
                 for g in cand.grid for t3 in design.BASE_TAU_GRID_S)
    def admissible(b: BaseTheta, gg: GridValue) -> bool:
        assert isinstance(gg, tuple)
        return cand.admissible(b, own(gg)) and EXTRA_NODE.admissible(b, gg[-1])

    return Candidate(cand.name + "+node3", cand.coef_name, cand.grid_name, grid, column,
                     cand.meaning, admissible)

