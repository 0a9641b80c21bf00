"""Thermometers that read in 1 C, 0.25 C or 0.0625 C steps train without a loss beyond the
quantisation: the lag bank (the default model's least-squares part) trained and scored on
logs whose temp_c is quantised against the same runs read exactly.

The bound. One reading's quantisation error is uniform over one step q (std q / sqrt(12));
fed straight into a model whose SF moves k ppm per C it would cost k q / sqrt(12) ppm. The
front end averages readings before any model sees them (block means of D samples, lag
filters of 60 s and more) and the SF windows average again, so the loss allowed is a tenth
of that, plus 0.02 ppm for the noise of two fits: 0.21 ppm at 1 C steps, 0.07 at 0.25 C,
0.04 at 0.0625 C for the default gyro (k about 6.6 ppm/C). Measured: +0.05 ppm at 1 C,
+0.00 at the finer steps (an after-RMS of 0.51 ppm read exactly).
"""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import log_metrics
from fogsf.logs.measure.windows import sf_windows
from fogsf.sim.config import TableConfig
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper
from fogsf.training.inputs import bank_compensation


def run(seed: int, lsb_c: float) -> ChamberLog:
    """-20 -> 40 C at 1 C/min with 10 min soaks at both ends, 100 deg/s, a quiet gyro (ARW
    0.005 deg/sqrt(h): a noise floor of 0.09 ppm, so that the thermometer's steps are what
    shows) and a thermometer without white noise (no dither: the hardest case) reading in
    steps of `lsb_c` (0: exact)."""
    cfg = paper(1.0, seed)
    cfg.profile.start_c, cfg.profile.stop_c = -20.0, 40.0
    cfg.profile.soak_before_s = cfg.profile.soak_after_s = 600.0
    cfg.table = TableConfig(kind="constant", rate_dps=100.0)
    cfg.noise.arw_deg_per_sqrt_h = 0.005
    cfg.noise.temp_noise_c = 0.0
    cfg.noise.temp_lsb_c = lsb_c
    return simulate(cfg).log


def after_rms(lsb_c: float) -> tuple[float, ChamberLog]:
    train, test = run(21, lsb_c), run(24, lsb_c)
    predict = bank_compensation([train])
    return log_metrics(test, correction_ppm=predict(test))["rms_ppm"], test


@pytest.mark.parametrize("lsb_c", [1.0, 0.25, 0.0625])
def test_quantised_thermometer_trains_without_loss(lsb_c: float) -> None:
    exact, test = after_rms(0.0)
    quantised, qtest = after_rms(lsb_c)
    steps = np.unique(np.round(qtest.temp_c / lsb_c, 6))
    assert np.allclose(steps, np.round(steps)), "the generator did not quantise temp_c"
    w = sf_windows(test)
    k = abs(np.polyfit(w.temp_c, w.sf_ratio * 1e6, 1)[0])  # ppm per C
    allowed = 0.1 * k * lsb_c / np.sqrt(12.0) + 0.02
    assert quantised - exact <= allowed, (
        f"{lsb_c} C steps: after-RMS {quantised:.3f} ppm vs {exact:.3f} read exactly "
        f"(allowed +{allowed:.3f})")
