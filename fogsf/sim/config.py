"""The simulator's configuration: nested dataclasses that round-trip through JSON.

`SimConfig.to_dict()` / `SimConfig.from_dict()` (and `to_json` / `from_json`) are exact
inverses; `fogsf simulate --write-config` dumps one and `--config` reads it back, and
`fogsf diagnose` writes its fitted, extended model in the same form. Unknown keys are refused
(a typo must not be silently ignored).

The defaults describe one gyro: a small, high-dynamic, digital closed-loop FOG whose SF
coefficients are calibrated so that the paper's protocol (`--scenario paper`) reproduces the
paper's magnitudes (see `scenarios.py`). Units are in every field name.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from fogsf.errors import UserError
from fogsf.sim.effects import EffectConfig, check_effect


@dataclass
class NodeConfig:
    """One thermal node: a first-order lag behind its parent plus a self-heating rise.

    tau_s: time constant behind the parent; self_heat_c: how far above its parent the node
    settles once powered (equilibrium). parent: "chamber" or the name of another node.
    """

    name: str
    parent: str
    tau_s: float
    self_heat_c: float = 0.0


def _default_nodes() -> list[NodeConfig]:
    # Ordered as the paper's Fig. 3: board fastest, then preamp, coil inner, coil outer,
    # source slowest. Seen from the chamber the board settles in ~5 min (housing 1.5 min +
    # board 4 min), the coil in ~20-30 min and the source in ~45 min.
    return [
        NodeConfig("housing", "chamber", 90.0, 1.0),
        NodeConfig("board", "housing", 240.0, 5.0),
        NodeConfig("preamp", "housing", 480.0, 3.0),
        NodeConfig("coil_inner", "housing", 1200.0, 2.0),
        NodeConfig("coil_outer", "housing", 1800.0, 1.5),
        NodeConfig("source", "housing", 2700.0, 4.0),
    ]


@dataclass
class ThermalConfig:
    """The thermal network. start: "warm" (every node at its powered equilibrium with the
    chamber at t=0, as in the paper) or "power-on" (every node at the chamber temperature,
    self-heating switched on at t=0). board_node: the node the on-board thermometer reads."""

    nodes: list[NodeConfig] = field(default_factory=_default_nodes)
    start: str = "warm"
    board_node: str = "board"


@dataclass
class SFTermConfig:
    """One factor of K = 2*pi*L*D / (Km*K_DA*lambda*c) and its temperature law.

    factor: one of L, D, Km, K_DA, lambda. The factor's relative change is
    lin_ppm_per_c*(T-ref_c) + quad_ppm_per_c2*(T-ref_c)**2 + cube_ppm_per_c3*(T-ref_c)**3
    (in ppm) where T is the weighted mean of the node temperatures in `nodes` (weights sum
    to 1). The cubic term is zero unless given (the gyro population draws some).
    """

    name: str
    factor: str
    nodes: dict[str, float]
    lin_ppm_per_c: float
    quad_ppm_per_c2: float = 0.0
    ref_c: float = 20.0
    cube_ppm_per_c3: float = 0.0


def _default_sf_terms() -> list[SFTermConfig]:
    # Residual temperature coefficients of a compensated small FOG (the SLD's wavelength is
    # partly stabilised, the Y-waveguide's Km and the D/A gain are tracked by the second
    # (2*pi) loop, so only residuals remain). Calibrated to the paper: see scenarios.py.
    return [
        SFTermConfig("source wavelength", "lambda", {"source": 1.0}, 9.858, 0.0),
        SFTermConfig("coil length", "L", {"coil_inner": 0.5, "coil_outer": 0.5}, 0.55, 0.0),
        SFTermConfig("coil diameter", "D", {"coil_inner": 0.5, "coil_outer": 0.5}, 13.14,
                     -0.3425),
        SFTermConfig("Y-waveguide Km", "Km", {"coil_inner": 1.0}, 1.643, 0.0),
        SFTermConfig("D/A gain", "K_DA", {"board": 1.0}, 5.696, 0.0),
    ]


@dataclass
class ScaleFactorConfig:
    """SF error (ppm vs the nominal SF) = product of the factor changes - 1, plus offset."""

    terms: list[SFTermConfig] = field(default_factory=_default_sf_terms)
    offset_ppm: float = 0.0


@dataclass
class BiasConfig:
    """Bias in deg/h: bias_dph + lin*(T-ref) + quad*(T-ref)^2 + cube*(T-ref)^3 + shupe *
    dT/dt (C/min), T the temperature of `node` (the coil's, for a FOG's thermal bias): the
    Shupe term is the bias a temperature gradient along the fibre gives while the coil's
    temperature changes."""

    bias_dph: float = 0.3
    lin_dph_per_c: float = 0.002
    quad_dph_per_c2: float = 0.0
    node: str = "board"
    ref_c: float = 20.0
    cube_dph_per_c3: float = 0.0
    shupe_dph_per_c_per_min: float = 0.0


@dataclass
class NoiseConfig:
    """Gyro and thermometer noise. Zero switches a term off.

    arw_deg_per_sqrt_h: angle random walk; pulse_arcsec: angle per output pulse (the output
    is the count of whole pulses per 0.1 s, remainder carried); temp_noise_c: thermometer
    white noise (1 sigma); temp_lsb_c: thermometer resolution (DS18B20 at 12 bits: 0.0625).
    """

    arw_deg_per_sqrt_h: float = 0.05
    pulse_arcsec: float = 1.0
    temp_noise_c: float = 0.02
    temp_lsb_c: float = 0.0625


@dataclass
class ProfileConfig:
    """The chamber program. kind and the fields it uses:

    soak: start_c, duration_s. ramp: start_c -> stop_c at rate_c_per_min, with soak_before_s
    and soak_after_s. cycle: start_c -> stop_c -> start_c, `cycles` times, soak_s at each
    end. steps: levels_c one after another at rate_c_per_min, soak_s on each.
    program: points [[time_s, temp_c], ...] (linear between points).
    total_s: if > 0, the run's length whatever the kind: a longer program is cut there, a
    shorter one holds its last temperature until then.
    """

    kind: str = "ramp"
    start_c: float = -40.0
    stop_c: float = 50.0
    rate_c_per_min: float = 1.0
    soak_before_s: float = 0.0
    soak_after_s: float = 0.0
    duration_s: float = 3600.0
    soak_s: float = 1800.0
    cycles: int = 1
    levels_c: list[float] = field(default_factory=list)
    points: list[list[float]] = field(default_factory=list)
    total_s: float = 0.0


@dataclass
class TableConfig:
    """The rate-table schedule. constant: rate_dps. alternating: +rate_dps, -rate_dps, ...
    each for dwell_s. levels: rates_dps one after another, each for dwell_s, repeated."""

    kind: str = "constant"
    rate_dps: float = 10.0
    rates_dps: list[float] = field(default_factory=list)
    dwell_s: float = 300.0


@dataclass
class SimConfig:
    """A full simulator configuration: one gyro, one chamber run, one seed."""

    scenario: str = "custom"
    seed: int = 0
    dt_s: float = 0.1
    latitude_deg: float = 34.26  # Xi'an, where the paper's gyro was tested
    profile: ProfileConfig = field(default_factory=ProfileConfig)
    table: TableConfig = field(default_factory=TableConfig)
    thermal: ThermalConfig = field(default_factory=ThermalConfig)
    sf: ScaleFactorConfig = field(default_factory=ScaleFactorConfig)
    bias: BiasConfig = field(default_factory=BiasConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    effects: list[EffectConfig] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SimConfig:
        cfg = _build(cls, d, "config")
        validate(cfg)
        return cfg

    @classmethod
    def from_json(cls, text: str, source: str = "config") -> SimConfig:
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise UserError(f"{source}: not valid JSON: {e}") from None
        if not isinstance(d, dict):
            raise UserError(f"{source}: the top level must be a JSON object")
        return cls.from_dict(d)

    @classmethod
    def load(cls, path: str | Path) -> SimConfig:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as e:
            raise UserError(f"{path}: cannot read: {e.strerror or e}") from None
        return cls.from_json(text, str(path))

    def save(self, path: str | Path) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(self.to_json(), encoding="utf-8")


# Nested types that from_dict must construct, per (class, field).
_NESTED: dict[tuple[type, str], tuple[str, type]] = {
    (SimConfig, "profile"): ("one", ProfileConfig),
    (SimConfig, "table"): ("one", TableConfig),
    (SimConfig, "thermal"): ("one", ThermalConfig),
    (SimConfig, "sf"): ("one", ScaleFactorConfig),
    (SimConfig, "bias"): ("one", BiasConfig),
    (SimConfig, "noise"): ("one", NoiseConfig),
    (SimConfig, "effects"): ("list", EffectConfig),
    (ThermalConfig, "nodes"): ("list", NodeConfig),
    (ScaleFactorConfig, "terms"): ("list", SFTermConfig),
}


def _build(cls: type, d: Any, where: str) -> Any:
    if not isinstance(d, dict):
        raise UserError(f"{where}: expected a JSON object, got {type(d).__name__}")
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - names)
    if unknown:
        raise UserError(f"{where}: unknown key(s) {', '.join(unknown)} "
                        f"(allowed: {', '.join(sorted(names))})")
    kwargs: dict[str, Any] = {}
    for k, v in d.items():
        nested = _NESTED.get((cls, k))
        if nested is None:
            kwargs[k] = v
        elif nested[0] == "one":
            kwargs[k] = _build(nested[1], v, f"{where}.{k}")
        else:
            if not isinstance(v, list):
                raise UserError(f"{where}.{k}: expected a list")
            kwargs[k] = [_build(nested[1], x, f"{where}.{k}[{i}]") for i, x in enumerate(v)]
    types = {f.name: f.type for f in fields(cls)}
    for k, v in kwargs.items():
        kind = types[k]
        if kind in ("float", "int") and not _finite(v):
            raise UserError(f"{where}.{k}: expected a finite number, got {v!r}")
        if kind == "int" and v != int(v):
            raise UserError(f"{where}.{k}: expected a whole number, got {v!r}")
        if kind == "float":
            kwargs[k] = float(v)
        elif kind == "int":
            kwargs[k] = int(v)
        elif kind == "str" and not isinstance(v, str):
            raise UserError(f"{where}.{k}: expected a string, got {v!r}")
        elif kind == "list[float]":
            if not isinstance(v, list) or not all(_finite(x) for x in v):
                raise UserError(f"{where}.{k}: expected a list of numbers, got {v!r}")
            kwargs[k] = [float(x) for x in v]
        elif kind == "list[list[float]]":
            if not isinstance(v, list) or not all(
                    isinstance(r, list) and all(_finite(x) for x in r) for r in v):
                raise UserError(f"{where}.{k}: expected a list of [time_s, temp_c] rows")
            kwargs[k] = [[float(x) for x in r] for r in v]
        elif kind == "dict[str, float]":
            if not isinstance(v, dict) or not all(_finite(x) for x in v.values()):
                raise UserError(f"{where}.{k}: expected an object of numbers, got {v!r}")
            kwargs[k] = {str(a): float(x) for a, x in v.items()}
    try:
        return cls(**kwargs)
    except TypeError as e:
        raise UserError(f"{where}: {e}") from None


SF_FACTORS = {"L": 1, "D": 1, "Km": -1, "K_DA": -1, "lambda": -1}  # exponent in K
PROFILE_KINDS = ("soak", "ramp", "cycle", "steps", "program")
TABLE_KINDS = ("constant", "alternating", "levels")
START_MODES = ("warm", "power-on")


def _finite(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def validate(cfg: SimConfig) -> None:
    """Refuse a configuration that cannot be simulated, naming the field and the rule."""
    if not _finite(cfg.dt_s) or cfg.dt_s <= 0:
        raise UserError(f"dt_s must be a positive number, got {cfg.dt_s!r}")
    if not _finite(cfg.latitude_deg) or abs(cfg.latitude_deg) > 90:
        raise UserError(f"latitude_deg must lie in -90..90, got {cfg.latitude_deg!r}")
    th = cfg.thermal
    if th.start not in START_MODES:
        raise UserError(f"thermal.start must be one of {', '.join(START_MODES)}, "
                        f"got {th.start!r}")
    known = {"chamber"}
    for n in th.nodes:
        if n.name in known:
            raise UserError(f"thermal node {n.name!r}: name used twice (or 'chamber')")
        if n.parent not in known:
            raise UserError(f"thermal node {n.name!r}: parent {n.parent!r} must be 'chamber' "
                            "or a node listed before it")
        if not _finite(n.tau_s) or n.tau_s < 0:
            raise UserError(f"thermal node {n.name!r}: tau_s must be >= 0, got {n.tau_s!r}")
        if not _finite(n.self_heat_c):
            raise UserError(f"thermal node {n.name!r}: self_heat_c must be a number")
        known.add(n.name)
    if th.board_node not in known - {"chamber"}:
        raise UserError(f"thermal.board_node {th.board_node!r} is not a node")
    for t in cfg.sf.terms:
        if t.factor not in SF_FACTORS:
            raise UserError(f"sf term {t.name!r}: factor must be one of "
                            f"{', '.join(SF_FACTORS)}, got {t.factor!r}")
        bad = [k for k in t.nodes if k not in known]
        if bad or not t.nodes:
            raise UserError(f"sf term {t.name!r}: nodes {bad or '(none)'} not in the network")
        if abs(sum(t.nodes.values()) - 1.0) > 1e-9:
            raise UserError(f"sf term {t.name!r}: node weights must sum to 1")
    if cfg.bias.node not in known:
        raise UserError(f"bias.node {cfg.bias.node!r} is not a node")
    nz = cfg.noise
    for name in ("arw_deg_per_sqrt_h", "pulse_arcsec", "temp_noise_c", "temp_lsb_c"):
        v = getattr(nz, name)
        if not _finite(v) or v < 0:
            raise UserError(f"noise.{name} must be >= 0, got {v!r}")
    if cfg.profile.kind not in PROFILE_KINDS:
        raise UserError(f"profile.kind must be one of {', '.join(PROFILE_KINDS)}, "
                        f"got {cfg.profile.kind!r}")
    if cfg.table.kind not in TABLE_KINDS:
        raise UserError(f"table.kind must be one of {', '.join(TABLE_KINDS)}, "
                        f"got {cfg.table.kind!r}")
    for e in cfg.effects:
        check_effect(e)
