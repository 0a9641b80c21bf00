"""Rate transfer: the ramp rate of a log, and whether the training data pins the lag model
down on a target log (it does at the training rate and between two training rates, it does
not at another rate from one training rate)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from ramp_logs import short_ramp

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.writer import write_log
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import soak
from fogsf.training.interval.rate_transfer import rate_transfer
from fogsf.training.interval.transfer import ramp_rate_c_per_min


@pytest.fixture(scope="module")
def runs() -> dict[str, ChamberLog]:
    return {"a": short_ramp(0.6, 21), "b": short_ramp(0.6, 22), "fast": short_ramp(2.4, 23),
            "mid": short_ramp(1.2, 24)}


@pytest.mark.parametrize("rate", [0.5, 1.0, 2.5])
def test_ramp_rate_of_a_log(rate: float) -> None:
    assert ramp_rate_c_per_min(short_ramp(rate, 5)) == pytest.approx(rate, rel=0.05)


def test_a_soak_has_no_ramp_rate() -> None:
    cfg = soak(seed=3)
    cfg.thermal.start = "warm"  # a power-on start warms the board: that is a ramp
    assert ramp_rate_c_per_min(simulate(cfg).log) == 0.0


def test_one_rate_pins_its_own_rate_not_another(runs) -> None:
    same = rate_transfer([runs["a"]], runs["b"])
    other = rate_transfer([runs["a"]], runs["fast"])
    assert same.covered and not other.covered
    assert same.train_rates_c_per_min == [pytest.approx(0.6, rel=0.05)]
    assert same.consistent > 10  # many lag structures fit one ramp equally well ...
    assert same.spread_median_ppm < 3.0  # ... and agree on a run at the same rate
    assert other.spread_median_ppm > 10 * max(same.spread_median_ppm, 1.0)  # not at 4x it
    assert "OUTSIDE the training range" in other.message()


def test_two_rates_pin_the_rate_between(runs) -> None:
    one = rate_transfer([runs["a"]], runs["mid"])
    two = rate_transfer([runs["a"], runs["fast"]], runs["mid"])
    assert two.covered and not one.covered
    assert two.spread_median_ppm < 0.6 * one.spread_median_ppm


@pytest.mark.slow
def test_train_command_reports_rate_transfer(runs, tmp_path: Path) -> None:
    write_log(tmp_path / "a.csv", runs["a"])
    write_log(tmp_path / "fast.csv", runs["fast"])
    out = subprocess.run(
        [sys.executable, "-m", "fogsf", "train", "--train", str(tmp_path / "a.csv"),
         "--test", str(tmp_path / "fast.csv"), "--model", "poly", "--out", str(tmp_path / "m")],
        check=True, capture_output=True, text=True).stdout
    said = " ".join(out.split())
    assert "rate transfer: trained at 0.6 C/min, target at 2." in said
    assert "C/min: OUTSIDE the training range" in said
    saved = json.loads((tmp_path / "m" / "metrics.json").read_text())
    rt = saved["rate_transfer"]
    assert not rt["covered"] and rt["consistent"] >= 1 and rt["spread_max_ppm"] > 0


@pytest.mark.slow
def test_train_without_test_log_says_one_rate_is_an_extrapolation(runs, tmp_path: Path) -> None:
    write_log(tmp_path / "a.csv", runs["a"])
    write_log(tmp_path / "fast.csv", runs["fast"])
    cmd = [sys.executable, "-m", "fogsf", "train", "--model", "poly"]
    one = subprocess.run([*cmd, "--train", str(tmp_path / "a.csv"), "--out",
                          str(tmp_path / "one")], check=True, capture_output=True,
                         text=True).stdout
    two = subprocess.run([*cmd, "--train", str(tmp_path / "a.csv"), "--train",
                          str(tmp_path / "fast.csv"), "--out", str(tmp_path / "two")],
                         check=True, capture_output=True, text=True).stdout
    assert "one ramp rate (0.6 C/min)" in " ".join(one.split())
    assert "one ramp rate" not in " ".join(two.split())
    saved = json.loads((tmp_path / "two" / "metrics.json").read_text())
    assert saved["train_ramp_rates_c_per_min"] == [pytest.approx(0.6, rel=0.05),
                                                  pytest.approx(2.4, rel=0.05)]


def test_long_run_ratio_of_white_and_structured_residuals() -> None:
    import numpy as np

    from fogsf.training.interval.transfer import long_run_ratio

    rng = np.random.default_rng(9)
    white = rng.normal(size=4000)
    assert long_run_ratio(white, [2000, 2000]) == pytest.approx(1.0, abs=0.3)
    drift = white + 0.5 * np.sin(np.arange(4000) / 150.0)  # structure slower than a window
    assert long_run_ratio(drift, [2000, 2000]) > 2.0
    assert long_run_ratio(white[:5], [5]) == 1.0  # shorter than a window: no evidence


def _program_log(points: list[list[float]], seed: int) -> ChamberLog:
    from fogsf.sim.config import ProfileConfig

    cfg = soak(seed=seed)
    cfg.thermal.start = "warm"
    cfg.profile = ProfileConfig(kind="program", points=points)
    return simulate(cfg).log


def test_ramp_segments_read_up_and_down_rates_of_one_log() -> None:
    from fogsf.training.interval.transfer import ramp_rates, ramp_segments

    # 20 min soak, up 60 C at 1 C/min, 20 min soak, down 60 C at 2 C/min, 20 min soak
    log = _program_log([[0, -10], [1200, -10], [4800, 50], [6000, 50], [7800, -10],
                        [9000, -10]], seed=41)
    segs = ramp_segments(log)
    assert [s.rate_c_per_min for s in segs] == [pytest.approx(1.0, rel=0.05),
                                                pytest.approx(-2.0, rel=0.05)]
    assert segs[0].stop_s <= segs[1].start_s
    assert ramp_rates(log) == [pytest.approx(1.0, rel=0.05), pytest.approx(2.0, rel=0.05)]


def test_a_ramp_whose_rate_changes_is_two_segments() -> None:
    from fogsf.training.interval.transfer import ramp_rates

    # 0.5 C/min for 50 min, then 2 C/min for 20 min, no soak between
    log = _program_log([[0, -20], [600, -20], [3600, 5], [4800, 45]], seed=42)
    assert ramp_rates(log) == [pytest.approx(0.5, rel=0.08), pytest.approx(2.0, rel=0.08)]


def test_a_two_rate_target_outside_one_rate_training_is_not_covered(runs) -> None:
    log = _program_log([[0, -20], [600, -20], [3000, 20], [3600, 20], [4800, -20]], seed=43)
    rt = rate_transfer([runs["a"]], log)
    assert not rt.covered and rt.target_rate_c_per_min == pytest.approx(1.0, rel=0.1)
    lo, hi = rt.rms_interval_ppm
    assert 0 < lo < rt.noise_floor_ppm < hi


def test_interval_scales_what_the_training_logs_leave_open() -> None:
    """One ramp: the farthest consistent lag model times K_ONE_SEGMENT; several ramps: the
    farthest structure candidate times K_SEVERAL; the floor in quadrature either way."""
    import numpy as np

    from fogsf.training.interval.rate_transfer import (
        K_ONE_SEGMENT,
        K_SEVERAL,
        rms_interval,
    )
    from fogsf.training.interval.transfer import INTERVAL_LO

    lo, hi = rms_interval(5.0, 40.0, 10.0, one_segment=True)
    assert lo == INTERVAL_LO * 5.0 and hi == pytest.approx(np.hypot(5.0, K_ONE_SEGMENT * 40.0))
    lo, hi = rms_interval(5.0, 40.0, 10.0, one_segment=False)
    assert hi == pytest.approx(np.hypot(5.0, K_SEVERAL * 10.0))
    assert rms_interval(5.0, 0.0, 0.0, one_segment=False)[1] == pytest.approx(5.0)


def test_rate_transfer_reports_every_structure_and_what_the_logs_hold(runs) -> None:
    from fogsf.training.interval.rate_transfer import rms_interval
    from fogsf.training.structure.choice import CANDIDATES
    from fogsf.training.structure.heldout import candidate_compensation

    def judged(train: list) -> object:  # the lag bank by least squares, as the judged model
        return rate_transfer(train, runs["mid"], prediction_ppm=candidate_compensation(
            "bank", train)(runs["mid"]))

    one, two = judged([runs["a"]]), judged([runs["a"], runs["fast"]])
    assert one.one_segment and not two.one_segment
    for rt in (one, two):
        assert set(rt.structure_spread_ppm) == set(CANDIDATES)
        assert all(v >= 0 for v in rt.structure_spread_ppm.values())
        assert rt.structure_spread_ppm["bank"] < 1e-3  # the judged model is the bank
        assert rt.rms_interval_ppm == pytest.approx(rms_interval(
            rt.noise_floor_ppm, rt.model_spread_max_ppm, max(rt.structure_spread_ppm.values()),
            rt.one_segment))
    # two rates around the target pin the structures down: they agree more than on one ramp
    assert max(two.structure_spread_ppm.values()) < max(one.structure_spread_ppm.values())
    assert "structures fitted to the same logs differ" in two.message()


def test_a_slow_start_is_not_a_second_ramp() -> None:
    """The first 10 min of a ramp at 0.2 C/min (the board catching up with the chamber) and
    then 0.5 C/min: one ramp, not two segments."""
    from fogsf.training.interval.transfer import ramp_segments

    log = _program_log([[0, -30], [600, -28], [4800, 7]], seed=44)
    segs = ramp_segments(log)
    assert len(segs) == 1 and segs[0].rate_c_per_min == pytest.approx(0.5, rel=0.08)
