"""Short simulated paper-scenario ramps shared by the trainer tests."""

from __future__ import annotations

from fogsf.logs.chamber_log import ChamberLog
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper


def short_ramp(rate: float, seed: int, gyro_seed: int | None = None,
               sample_rate_hz: float = 10.0, down: bool = False) -> ChamberLog:
    """-20 -> 40 C (40 -> -20 C if `down`) at `rate` C/min after a 10 min soak, warm start,
    10 deg/s: 1-2 h at 10 Hz (or `sample_rate_hz`); the default gyro, or the population's
    gyro `gyro_seed` (without its SF hysteresis, if it draws one: these tests are about the
    thermal structure)."""
    cfg = paper(rate, seed)
    cfg.dt_s = 1.0 / sample_rate_hz
    if gyro_seed is not None:
        from fogsf.sim.population import gyro_for_seed, with_gyro

        cfg = with_gyro(cfg, gyro_for_seed(gyro_seed, hysteresis=False))
    cfg.profile.start_c, cfg.profile.stop_c = (40.0, -20.0) if down else (-20.0, 40.0)
    cfg.profile.soak_before_s = 600.0
    return simulate(cfg).log
