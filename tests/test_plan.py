"""`fogsf plan`: programs within the limits, program.csv round trip, ranking, CLI."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.logio import read_log
from fogsf.plan.evaluate import evaluate_gyro
from fogsf.plan.programs import Limits, Program, _path, candidates, violations
from fogsf.plan.report import score


@pytest.mark.parametrize("seed", range(6))
def test_every_candidate_respects_drawn_limits(seed: int) -> None:
    rng = np.random.default_rng([seed, 0x91A])
    lo = float(rng.uniform(-55, 0))
    limits = Limits(lo, float(rng.uniform(30, 85)), float(rng.uniform(0.3, 6)),
                    float(rng.uniform(2, 12)))
    progs = candidates(limits)
    assert progs, f"seed {seed}: no program within {limits}"
    for p in progs:
        assert violations(p, limits) == [], (seed, p.name)
        assert p.hours <= limits.hours + 1e-9
        for run in p.runs:
            t = np.array([pt[0] for pt in run])
            temp = np.array([pt[1] for pt in run])
            assert np.all(np.diff(t) > 0)
            assert temp.min() >= limits.lo_c - 1e-9 and temp.max() <= limits.hi_c + 1e-9
            slope = np.abs(np.diff(temp) / np.diff(t)) * 60.0
            assert slope.max() <= limits.max_ramp_c_per_min + 1e-6, (seed, p.name)


def test_violations_names_what_breaks_the_limits() -> None:
    limits = Limits(-40, 50, 1.0, 2.0)
    fast = Program("fast", ((( 0.0, -40.0), (600.0, 50.0), (9000.0, 50.0)),), (9.0,))
    bad = violations(fast, limits)
    assert any("C/min > max" in b for b in bad) and any("lasts" in b for b in bad)
    hot = Program("hot", (((0.0, -40.0), (6000.0, 60.0)),), (1.0,))
    assert any("outside the range" in b for b in violations(hot, limits))
    with pytest.raises(UserError, match="20 C"):
        Limits(30, 80, 1, 4)


@pytest.mark.slow
def test_a_two_rate_program_ranks_above_a_one_rate_program_of_the_same_length() -> None:
    limits = Limits(-40, 50, 3, 4.5)
    # 3.5 h each: one up-ramp at 0.5 C/min with soaks, against up 1 / down 2 with soaks
    one = Program("one rate", (_path(-40, 50, [("soak", 900.0), ("ramp", 0.5),
                                               ("soak", 900.0)]),), (0.5,))
    two = Program("two rates", (_path(-40, 50, [("soak", 900.0), ("ramp", 1.0),
                                                ("soak", 1800.0), ("ramp", 2.0),
                                                ("soak", 1800.0)]),), (1.0, 2.0))
    assert abs(one.hours - two.hours) < 1e-9
    res = [evaluate_gyro((s, s), [one, two], limits, (0.3, 0.7)) for s in (1, 2, 3)]
    ranked = score([one, two], res)
    assert [s.program.name for s in ranked] == ["two rates", "one rate"], \
        [(s.program.name, s.median, s.p90) for s in ranked]
    assert ranked[0].median < ranked[1].median


@pytest.mark.slow
def test_plan_cli_writes_a_program_that_simulate_reads_back(tmp_path: Path, capsys) -> None:
    out = tmp_path / "plan"
    assert main(["plan", "--hours", "3", "--max-ramp", "2", "--gyros", "2", "--test-rates",
                 "2", "--interval-gyros", "1", "--workers", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "best:" in text and "paper: up 0.5 + up 1" in text
    for name in ("program.csv", "table.md", "plan.json", "plan.png"):
        assert (out / name).stat().st_size > 0, name
    plan = json.loads((out / "plan.json").read_text())
    best = plan["best"]
    assert best["hours"] <= 3 + 1e-9 and plan["gyro_seeds"] == [1, 2]
    # the interval's upper end is computed for the best and the paper's, not for the rest
    assert np.isfinite(best["interval_x_floor"]) and np.isfinite(plan["paper"]["interval_x_floor"])
    assert [p["interval_x_floor"] is None for p in plan["programs"][3:]] == \
        [True] * (len(plan["programs"]) - 3)
    # the written program is what simulate --program runs: the chamber air follows it
    run = tmp_path / "run.csv"
    assert main(["simulate", "--program", str(out / "program.csv"), "--seed", "1",
                 "--out", str(run)]) == 0
    log = read_log(run)
    pts = np.array(best["runs"][0])
    assert abs(log.time_s[-1] - pts[-1, 0]) <= 0.1
    want = np.interp(log.time_s, pts[:, 0], pts[:, 1])
    assert np.max(np.abs(log.extra["chamber_c"] - want)) < 0.01


def test_plan_refuses_evaluation_seeds_and_bad_ranges(capsys) -> None:
    assert main(["plan", "--first", "20000", "--out", "x"]) == 2
    assert "development seeds" in capsys.readouterr().err
    assert main(["plan", "--range", "30:80", "--out", "x"]) == 2
    assert "20 C" in capsys.readouterr().err
    assert main(["plan", "--hours", "0.6", "--max-ramp", "0.1", "--out", "x"]) == 2
    assert "no program fits" in capsys.readouterr().err


def test_axes_score_each_imu_by_its_worst_axis() -> None:
    p = Program("p", (((0.0, -40.0), (3600.0, 50.0)),), (1.5,))
    res = [{"ratios": {"p": {0.5: a, 2.0: b}}} for a, b in ((1.0, 4.0), (3.0, 2.0),
                                                            (1.5, 1.0), (1.2, 1.1))]
    (one,) = score([p], res)
    (two,) = score([p], res, axes=2)
    assert one.n == 8 and two.n == 4
    # IMU 1: worst 3.0 at 0.5, 4.0 at 2; IMU 2: 1.5 and 1.1
    assert two.per_rate[0.5] == (pytest.approx(2.25), pytest.approx(2.85))
    assert two.median == pytest.approx(np.median([3.0, 4.0, 1.5, 1.1]))


@pytest.mark.slow
def test_plan_from_logs_fits_a_gyro_to_each_log(tmp_path: Path, capsys) -> None:
    log = tmp_path / "earlier.csv"
    assert main(["simulate", "--random-gyro", "5", "--profile", "cycle", "--start-c", "-40",
                 "--stop-c", "50", "--ramp-rate", "2", "--soak-min", "20", "--cycles", "1",
                 "--out", str(log)]) == 0
    out = tmp_path / "plan"
    assert main(["plan", "--from-logs", str(log), "--hours", "2", "--test-rates", "1",
                 "--interval-gyros", "0", "--workers", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "fitted a gyro to" in text and "1 gyros fitted to earlier.csv" in text
    plan = json.loads((out / "plan.json").read_text())
    assert plan["from_logs"] == [str(log)] and plan["gyro_seeds"] is None
    assert plan["best"]["interval_x_floor"] is None  # --interval-gyros 0
    assert main(["plan", "--from-logs", str(log), "--axes", "2", "--out", str(out)]) == 2
    assert "multiple" in capsys.readouterr().err


def test_no_program_fits_says_how_many_hours_would(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--range", "-20:60", "--hours", "1", "--gyros", "1",
                 "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    hours = float(re.search(r"--hours ([0-9.]+) or more", err)[1])
    assert not candidates(Limits(-20.0, 60.0, 3.0, 1.0))
    assert candidates(Limits(-20.0, 60.0, 3.0, hours)), "the hint must be enough"
    assert not candidates(Limits(-20.0, 60.0, 3.0, hours - 0.1)), "and not more than needed"
