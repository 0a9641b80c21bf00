"""Named runs of the default gyro: `fogsf simulate --scenario NAME`.

paper
    The paper's protocol: warm start at -40 C, chamber ramp to +50 C at --ramp-rate C/min
    (the paper uses 0.5 and 1.0), rate table constant at 10 deg/s, 10 Hz, Xi'an latitude.
    The default gyro's SF coefficients (config.py) are calibrated so that the 1 C/min run
    has max|SF error| ~835 ppm and RMS ~450 ppm about the SF at 20 C (board thermometer),
    the paper's Table 2 "before" figures; the 0.5 C/min run then shows the different
    hysteresis of the paper's Fig. 7. Calibration (`python -m fogsf.sim.calibrate`): the
    shape of the coefficients is physical (coil diameter and wavelength dominate, a
    quadratic share in each), and two scale factors, one for the linear and one for the
    quadratic coefficients, are solved so that the noiseless 1 C/min run hits both targets.
cycle
    Warm start at -40 C, two -40..+60 C cycles at --ramp-rate (default 1 C/min) with 30 min
    soaks at each end, table alternating +/-10 deg/s every 100 s (the +/- pairs separate SF
    from bias): the hysteresis loop.
steps
    Warm start at -40 C, steps of 20 C up to +60 C at 2 C/min with 40 min soaks, table at
    10, 50, 100 and 200 deg/s in turn, 100 s each (SF vs temperature and vs rate).
soak
    Power-on at 20 C and one hour at constant temperature, 10 deg/s: the warm-up (board
    +6 C in ~20 min, source still warming after an hour) and the noise floor.
partial, partial-test
    Partial cycles (`partial_cycles.py`): reversals inside -40..50 C with a soak at every
    turn, warm start, 10 deg/s; `partial` (6.3 h, legs at 2 and 0.75 C/min in turn) to
    train on, `partial-test`
    (5.8 h at 1 C/min, other turns) to test on: what SF hysteresis (`--effect hysteresis`)
    needs to be seen.
"""

from __future__ import annotations

from dataclasses import replace

from fogsf.errors import UserError
from fogsf.sim.config import ProfileConfig, SimConfig, TableConfig
from fogsf.sim.partial_cycles import PARTIAL_TEST, PARTIAL_TRAIN, PartialCycle

PAPER_TARGET_MAX_PPM = 835.1
PAPER_TARGET_RMS_PPM = 450.24
PAPER_RAMP_RATES = (0.5, 1.0)


def paper(ramp_rate_c_per_min: float = 1.0, seed: int = 0) -> SimConfig:
    cfg = SimConfig(scenario="paper", seed=seed)
    cfg.profile = ProfileConfig(kind="ramp", start_c=-40.0, stop_c=50.0,
                                rate_c_per_min=ramp_rate_c_per_min)
    cfg.table = TableConfig(kind="constant", rate_dps=10.0)
    cfg.thermal.start = "warm"
    return cfg


def cycle(ramp_rate_c_per_min: float = 1.0, seed: int = 0) -> SimConfig:
    cfg = SimConfig(scenario="cycle", seed=seed)
    cfg.profile = ProfileConfig(kind="cycle", start_c=-40.0, stop_c=60.0,
                                rate_c_per_min=ramp_rate_c_per_min, soak_s=1800.0, cycles=2)
    cfg.table = TableConfig(kind="alternating", rate_dps=10.0, dwell_s=100.0)
    cfg.thermal.start = "warm"
    return cfg


def steps(ramp_rate_c_per_min: float = 2.0, seed: int = 0) -> SimConfig:
    cfg = SimConfig(scenario="steps", seed=seed)
    cfg.profile = ProfileConfig(kind="steps", levels_c=[-40.0, -20.0, 0.0, 20.0, 40.0, 60.0],
                                rate_c_per_min=ramp_rate_c_per_min, soak_s=2400.0)
    cfg.table = TableConfig(kind="levels", rates_dps=[10.0, 50.0, 100.0, 200.0], dwell_s=100.0)
    cfg.thermal.start = "warm"
    return cfg


def soak(ramp_rate_c_per_min: float = 1.0, seed: int = 0) -> SimConfig:
    cfg = SimConfig(scenario="soak", seed=seed)
    cfg.profile = ProfileConfig(kind="soak", start_c=20.0, duration_s=3600.0)
    cfg.table = TableConfig(kind="constant", rate_dps=10.0)
    cfg.thermal.start = "power-on"
    return cfg


def _partial(program: PartialCycle, ramp_rate_c_per_min: float | None, seed: int
             ) -> SimConfig:
    if ramp_rate_c_per_min is not None:
        program = replace(program, rates_c_per_min=(ramp_rate_c_per_min,))
    cfg = SimConfig(scenario=program.name.replace("_", "-"), seed=seed)
    cfg.profile = program.profile()
    cfg.table = TableConfig(kind="constant", rate_dps=10.0)
    cfg.thermal.start = "warm"
    return cfg


def partial(ramp_rate_c_per_min: float | None = None, seed: int = 0) -> SimConfig:
    return _partial(PARTIAL_TRAIN, ramp_rate_c_per_min, seed)


def partial_test(ramp_rate_c_per_min: float | None = None, seed: int = 0) -> SimConfig:
    return _partial(PARTIAL_TEST, ramp_rate_c_per_min, seed)


SCENARIOS = {"paper": paper, "cycle": cycle, "steps": steps, "soak": soak,
             "partial": partial, "partial-test": partial_test}


def scenario(name: str, ramp_rate_c_per_min: float | None = None, seed: int = 0) -> SimConfig:
    if name not in SCENARIOS:
        raise UserError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}")
    fn = SCENARIOS[name]
    return fn(seed=seed) if ramp_rate_c_per_min is None else fn(ramp_rate_c_per_min, seed=seed)
