"""What a chamber program buys: simulate it on population gyros, train, test elsewhere.

One unit of work is one gyro (so gyros run on the project's executor): the test loops at
every envelope rate are simulated once, then every program's runs are simulated, the
default model's fixed part (the lag bank, least squares: `training.inputs.bank_compensation`) is
trained on them, and its RMS error on each test loop is taken as a multiple of that loop's
noise floor (report.py also sums up the rates that are not in the program on their own).
Test loops go up and down at one rate with 30 min soaks, so both ramp directions and the
soaks' transients are scored.
"""

from __future__ import annotations

import math
import time

import numpy as np

from fogsf.logs.measure.metrics import log_metrics
from fogsf.plan.programs import START_SOAK_S, Limits, Program, _path
from fogsf.sim import simulate
from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.population import gyro_for_seed, run_on_gyro
from fogsf.training.inputs import bank_compensation
from fogsf.training.interval.rate_transfer import rate_transfer
from fogsf.training.interval.transfer import INTERVAL_LO

TEST_SOAK_S = 1800.0
RATE_NEAR = 0.10  # a test rate within 10 % of a program's ramp rate counts as trained on


def test_rates(lo: float, hi: float, n: int) -> tuple[float, ...]:
    """n rates log-spaced over the envelope lo..hi C/min, ends included."""
    if n == 1:
        return (math.sqrt(lo * hi),)
    return tuple(float(x) for x in np.geomspace(lo, hi, n))


def in_program(p: Program, rate: float) -> bool:
    """Whether a test rate is one of the program's ramp rates (within RATE_NEAR)."""
    return any(abs(rate - q) <= RATE_NEAR * q for q in p.rates_c_per_min)


def envelope_program(limits: Limits, rates: tuple[float, ...]) -> Program:
    """A reference, not a candidate: loops up and down at every test rate, one run each (the
    whole envelope as training data; other noise than the test loops')."""
    runs = tuple(_test_loop(limits, r) for r in rates)
    return Program("reference: the whole envelope (a loop at every test rate)", runs, rates)


def _test_loop(limits: Limits, rate: float) -> tuple[tuple[float, float], ...]:
    legs = [("soak", START_SOAK_S), ("ramp", rate), ("soak", TEST_SOAK_S), ("ramp", rate),
            ("soak", TEST_SOAK_S)]
    return _path(limits.lo_c, limits.hi_c, legs)


def _simulate(gyro, points, seed: int, name: str):  # noqa: ANN001, ANN202 - sim types
    prof = ProfileConfig(kind="program", points=[list(p) for p in points])
    return simulate(run_on_gyro(gyro, prof, seed, name)).log


def _program_logs(gyro, p: Program, seed: int) -> list:  # noqa: ANN001 - sim types
    """The program's runs simulated on `gyro`, run k with noise seed `seed + k` (common
    random numbers: every program's k-th run has the same noise, so programs differ by
    their chamber program only, not by where they sit in the list)."""
    return [_simulate(gyro, run, seed + k, f"plan-run{k}") for k, run in enumerate(p.runs)]


def gyro_of(ref: int | SimConfig) -> SimConfig:
    return gyro_for_seed(ref) if isinstance(ref, int) else ref


def evaluate_gyro(item: tuple[int, int | SimConfig], programs: list[Program], limits: Limits,
                  rates: tuple[float, ...]) -> dict:
    """Every program on one gyro, `item` = (seed of the runs' noise, population seed or
    gyro): {"gyro_seed", "ratios": {program name: {rate: test RMS / noise floor}},
    "seconds"}, at every envelope rate (those in the program too: the test loop is another
    run, up and down)."""
    t0 = time.perf_counter()
    gyro_seed, ref = item
    gyro = gyro_of(ref)
    tests = {r: _simulate(gyro, _test_loop(limits, r), gyro_seed * 1000 + 900 + i,
                          f"plan-test-{r:.3g}")
             for i, r in enumerate(rates)}
    out: dict[str, dict[float, float]] = {}
    for p in programs:
        predict = bank_compensation(_program_logs(gyro, p, gyro_seed * 1000))
        row = {}
        for r in rates:
            m = log_metrics(tests[r], correction_ppm=predict(tests[r]))
            row[r] = m["rms_ppm"] / m["noise_floor_ppm"]
        out[p.name] = row
    return {"gyro_seed": gyro_seed, "ratios": out, "seconds": time.perf_counter() - t0}


def interval_gyro(item: tuple[int, int | SimConfig], programs: list[Program], limits: Limits,
                  rate: float) -> dict[str, float]:
    """The rate-transfer interval's upper end, as a multiple of the noise floor, on the test
    loop at `rate` for each program trained on one gyro: how sure `fogsf train --test`
    would be."""
    gyro_seed, ref = item
    gyro = gyro_of(ref)
    test = _simulate(gyro, _test_loop(limits, rate), gyro_seed * 1000 + 990,
                     f"plan-interval-{rate:.3g}")
    out = {}
    for p in programs:
        logs = _program_logs(gyro, p, gyro_seed * 1000 + 500)
        pred = bank_compensation(logs)(test)
        lo, hi = rate_transfer(logs, test, prediction_ppm=pred).rms_interval_ppm
        out[p.name] = hi * INTERVAL_LO / lo if lo > 0 else float("inf")  # lo: 0.8 x floor
    return out
