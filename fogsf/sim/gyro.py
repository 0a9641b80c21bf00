"""The gyro's output and thermometers, and `simulate()`: configuration -> chamber log.

gyro_dps = (table + earth) * (1 + SF error) + bias(T) + angle random walk (an open-loop FOG,
the `open_loop` effect: (1 + SF error) times sin(K w) / (K w), in the SF error), quantised as a
closed-loop FOG does it: whole output pulses of `pulse_arcsec` counted per 0.1 s sample, the
remainder carried to the next sample (so quantization never accumulates into angle).
Thermometers (board, each internal node) add white noise and round to their resolution.

Random numbers come from one numpy SeedSequence per run, split into fixed streams (gyro
noise, thermometers), so the same configuration and seed give the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog, earth_rate_vertical_dps
from fogsf.sim import profiles, thermal
from fogsf.sim.config import NoiseConfig, SimConfig, validate
from fogsf.sim.effects import EffectContext, apply_effects
from fogsf.sim.scale_factor import bias_dps, sf_error_ppm

ARCSEC_DEG = 1.0 / 3600.0


def arw_noise(rng: np.random.Generator, n: int, arw_deg_per_sqrt_h: float,
              dt_s: float) -> np.ndarray:
    """White rate noise (deg/s) whose integral is an angle random walk of the given size."""
    sigma = arw_deg_per_sqrt_h / 60.0 / np.sqrt(dt_s)  # deg/sqrt(h) -> deg/sqrt(s) -> per sample
    return rng.standard_normal(n) * sigma


def quantize_pulses(rate_dps: np.ndarray, pulse_arcsec: float, dt_s: float) -> np.ndarray:
    """Rate as whole pulses per sample, the remainder carried (a closed-loop FOG's counter)."""
    if pulse_arcsec <= 0:
        return np.asarray(rate_dps, dtype=np.float64)
    q = pulse_arcsec * ARCSEC_DEG
    counts = np.floor(np.cumsum(rate_dps * dt_s) / q)
    return np.diff(counts, prepend=0.0) * (q / dt_s)


def thermometer(rng: np.random.Generator, temp_c: np.ndarray, noise: NoiseConfig) -> np.ndarray:
    """A digital thermometer's reading: white noise, then rounding to its resolution."""
    reading = temp_c + rng.standard_normal(temp_c.shape[0]) * noise.temp_noise_c
    if noise.temp_lsb_c > 0:
        reading = np.round(reading / noise.temp_lsb_c) * noise.temp_lsb_c
    return reading


@dataclass
class SimResult:
    """A simulated run: the log as written, and the truth behind it."""

    config: SimConfig
    log: ChamberLog
    nodes: dict[str, np.ndarray]  # true temperatures, incl. "chamber"
    sf_ppm: np.ndarray  # true SF error vs nominal, all terms
    bias_dps: np.ndarray  # true bias, all terms
    ideal_dps: np.ndarray  # noiseless, unquantised gyro output


def simulate(cfg: SimConfig, table_dps: np.ndarray | None = None,
             earth_dps: np.ndarray | float | None = None) -> SimResult:
    """Run the whole chain for one configuration.

    table_dps: the rate the gyro's axis actually turns at, per sample (deg/s; any values,
    zero included), instead of `cfg.table`'s schedule: a slewing or stalling table, or a
    skew axis' share of it (sim/rigs/protocols.py). earth_dps: the earth rate on the axis (per
    sample or one number) instead of the vertical axis' at `cfg.latitude_deg`. Without them the
    output is exactly the configuration's.
    """
    validate(cfg)
    dt = cfg.dt_s
    t, chamber = profiles.chamber_series(cfg.profile, dt)
    table = profiles.table_series(cfg.table, t) if table_dps is None \
        else _per_sample(table_dps, t, "table_dps")
    nodes = thermal.network(chamber, cfg.thermal, dt)
    sf = sf_error_ppm(nodes, cfg.sf)
    bias = bias_dps(nodes, cfg.bias, dt)
    earth = np.full(t.shape, earth_rate_vertical_dps(cfg.latitude_deg)) if earth_dps is None \
        else _per_sample(earth_dps, t, "earth_dps")
    ctx = EffectContext(t, dt, table, nodes, cfg.thermal.board_node, earth)
    # the law's SF goes in as the base: an open-loop gain multiplies the whole of it
    sf_fx, bias_fx = apply_effects(ctx, cfg.effects, sf)
    sf = sf + sf_fx
    bias = bias + bias_fx
    ideal = (table + earth) * (1.0 + sf * 1e-6) + bias

    gyro_ss, temp_ss = np.random.SeedSequence(cfg.seed).spawn(2)
    rng_gyro = np.random.default_rng(gyro_ss)
    rng_temp = np.random.default_rng(temp_ss)
    out = ideal + arw_noise(rng_gyro, t.shape[0], cfg.noise.arw_deg_per_sqrt_h, dt)
    out = quantize_pulses(out, cfg.noise.pulse_arcsec, dt)

    board = cfg.thermal.board_node
    temp_c = thermometer(rng_temp, nodes[board], cfg.noise)
    extra: dict[str, np.ndarray] = {"chamber_c": np.round(chamber, 3)}
    for n in cfg.thermal.nodes:
        if n.name != board:
            extra[f"temp_{n.name}_c"] = thermometer(rng_temp, nodes[n.name], cfg.noise)
    extra["true_sf_ppm"] = sf
    extra["true_bias_dph"] = bias * 3600.0
    log = ChamberLog(time_s=t, temp_c=temp_c, table_rate_dps=table, gyro_dps=out,
                     earth_rate_dps=earth, extra=extra, path="<simulated>",
                     nominal_dt_s=cfg.dt_s)
    return SimResult(cfg, log, nodes, sf, bias, ideal)


def _per_sample(values: np.ndarray | float, t_s: np.ndarray, name: str) -> np.ndarray:
    """A number or an array of one value per sample, as a float64 array of t_s's length."""
    arr = np.array(values, dtype=np.float64)
    if arr.ndim == 0:
        return np.full(t_s.shape, float(arr))
    if arr.shape != t_s.shape:
        raise ValueError(f"{name}: {arr.shape} values for {t_s.shape[0]} samples")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: values must be finite")
    return arr
