"""Any sample rate, 1 Hz .. 4 kHz (issue 11, part 2): the reader's rules, one model step in
seconds at every rate, re-rating a model, the C kernel bit for bit at 1 kHz and over a 24 h
100 Hz log, and training at 100 Hz end to end from the command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from ramp_logs import short_ramp

from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog, LogError
from fogsf.logs.logio import _read_plain, parse_log, read_log
from fogsf.logs.measure.windows import sf_windows
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.writer import write_log
from fogsf.models import reference, samples
from fogsf.models.features import front_end_for
from fogsf.models.front_end import filter_alpha


def rows(rate_hz: float, n: int, t0: float = 0.0) -> list[str]:
    dt = 1.0 / rate_hz
    return [f"{t0 + i * dt:.10g},{20 + 0.001 * i:.6g},10,10.001" for i in range(n)]


def csv(lines: list[str]) -> str:
    return "time_s,temp_c,table_rate_dps,gyro_dps\n" + "\n".join(lines) + "\n"


@pytest.mark.parametrize("rate_hz", [1.0, 10.0, 100.0, 1000.0, 4000.0, 2.5, 333.0])
def test_reader_takes_any_constant_rate_in_range(rate_hz: float) -> None:
    log = parse_log(csv(rows(rate_hz, 50)), "x.csv")
    assert log.sample_dt_s == pytest.approx(1.0 / rate_hz, rel=1e-9)
    assert log.sample_rate_hz == pytest.approx(rate_hz, rel=1e-9)
    said = [n for n in log.read_notes if n.startswith("sample rate")]
    assert bool(said) == (rate_hz != 10.0), log.read_notes


@pytest.mark.parametrize("rate_hz", [0.995, 4000.02, 4030.0])
def test_a_clock_a_little_off_the_range_ends_is_read(rate_hz: float) -> None:
    assert parse_log(csv(rows(rate_hz, 20)), "x.csv").sample_rate_hz == pytest.approx(
        rate_hz, rel=1e-5)


@pytest.mark.parametrize("rate_hz", [0.5, 0.98, 4100.0, 5000.0])
def test_reader_refuses_rates_out_of_range(rate_hz: float) -> None:
    with pytest.raises(LogError) as e:
        parse_log(csv(rows(rate_hz, 20)), "x.csv")
    assert e.value.rule == "sample rate out of range"
    assert "1 Hz .. 4 kHz" in str(e.value)


@pytest.mark.parametrize("rate_hz", [100.0, 1000.0])
def test_drops_and_jitter_are_accepted_and_counted(rate_hz: float) -> None:
    dt = 1.0 / rate_hz
    good = rows(rate_hz, 30)
    gap = good[:10] + rows(rate_hz, 20, t0=11 * dt)  # sample 10 missing
    s = parse_log(csv(gap), "x.csv").sampling
    assert (s.dropped, s.drop_steps, s.jittered) == (1, 1, 0)
    jitter = good[:10] + [f"{9.5 * dt:.10g},20,10,10"] + rows(rate_hz, 19, t0=10 * dt)
    log = parse_log(csv(jitter), "x.csv")
    assert (log.sampling.dropped, log.sampling.jittered) == (0, 2)
    assert any("steps off it by more than 20%" in n for n in log.read_notes)
    late = good[:10] + rows(rate_hz, 20, t0=10.3 * dt)  # a step of 1.3: late, none missed
    s = parse_log(csv(late), "x.csv").sampling
    assert (s.dropped, s.jittered) == (0, 1) and s.worst_step_s == pytest.approx(1.3 * dt)


def test_a_stated_rate_is_checked_against_time_s() -> None:
    text = csv(rows(100.0, 40))
    log = parse_log(text, "x.csv", Dialect(sample_rate_hz=100.0))
    assert log.sample_dt_s == pytest.approx(0.01) and "--sample-rate-hz" in log.read_notes[-1]
    with pytest.raises(LogError) as e:  # the log is not at the rate the user says
        parse_log(text, "x.csv", Dialect(sample_rate_hz=10.0))
    assert e.value.rule == "sample rate" and "--sample-rate-hz" in str(e.value)
    with pytest.raises(UserError, match="allowed 1 .. 4000 Hz"):
        parse_log(text, "x.csv", Dialect(sample_rate_hz=8000.0))


def test_fast_and_general_readers_agree(tmp_path: Path) -> None:
    log = short_ramp(2.0, 5, sample_rate_hz=100.0).slice(0, 30_000)
    path = tmp_path / "a.csv"
    write_log(path, log)
    assert _read_plain(path, Dialect()) is not None  # the fast path takes a plain log
    fast = read_log(path)  # numpy straight from the file
    general = parse_log(path.read_text(), str(path))
    for name, col in general.columns().items():
        np.testing.assert_array_equal(fast.columns()[name], col, err_msg=name)
    assert fast.read_notes == general.read_notes and fast.sample_dt_s == general.sample_dt_s
    # blank lines at the end: still the fast path, the same log
    path.write_text(path.read_text() + "\n\n")
    assert _read_plain(path, Dialect()) is not None
    np.testing.assert_array_equal(read_log(path).gyro_dps, general.gyro_dps)
    # a blank line inside: numpy would skip it; the reader still refuses it with its line
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:100] + ["\n"] + lines[100:]))
    with pytest.raises(LogError) as e:
        read_log(path)
    assert (e.value.rule, e.value.line) == ("wrong number of cells", 101)


def test_write_rows_writes_what_savetxt_writes(tmp_path: Path) -> None:
    import io

    from fogsf.logs.writer import write_rows

    rng = np.random.default_rng(3)
    data = rng.normal(size=(1234, 3)) * np.array([1e-9, 1.0, 1e6])
    data[5, 1] = -0.0
    fmts = ["%.10g", "%.17g", "%.9g"]
    mine = io.StringIO()
    write_rows(mine, data, fmts, chunk=100)
    ref = io.StringIO()
    np.savetxt(ref, data, delimiter=",", fmt=fmts)
    assert mine.getvalue() == ref.getvalue()


def test_windows_are_seconds_at_every_rate() -> None:
    a = short_ramp(2.0, 7, sample_rate_hz=10.0)
    b = short_ramp(2.0, 7, sample_rate_hz=100.0)
    wa, wb = sf_windows(a, 100.0), sf_windows(b, 100.0)
    assert len(wa) == len(wb) > 20
    np.testing.assert_allclose(wa.t_s, wb.t_s, atol=0.06)
    # the same physics: window SFs differ by the noise only (a few floors at most)
    floor = np.sqrt(np.mean(wa.noise_ppm ** 2))
    assert np.sqrt(np.mean(((wa.sf_ratio - wb.sf_ratio) * 1e6) ** 2)) < 3 * floor


def test_model_step_is_seconds_and_re_rating_keeps_it() -> None:
    log10 = short_ramp(2.0, 7, sample_rate_hz=10.0)
    log100 = short_ramp(2.0, 7, sample_rate_hz=100.0)
    fe10 = front_end_for([log10], 5.0, (300.0, 1200.0))
    fe100 = front_end_for([log100], 5.0, (300.0, 1200.0))
    assert (fe10.decimation, fe100.decimation) == (50, 500)
    assert fe10.stuck_samples * 10 == fe100.stuck_samples
    assert fe10.filter_alpha.tobytes() == fe100.filter_alpha.tobytes()
    with pytest.raises(UserError, match="train on logs of one sample rate"):
        front_end_for([log10, log100], 5.0, ())
    with pytest.raises(UserError, match="2.5 samples at 10 Hz, not a whole number"):
        front_end_for([log10], 0.25, ())


def test_re_rated_model_keeps_its_step_and_comes_back_to_its_id() -> None:
    model = samples.random_model(2, 3, 1, 8, decimation=50, seed=4, taus_s=[200.0, 900.0],
                            stuck_samples=36000)
    fast = model.at_rate(0.001)
    assert (fast.decimation, fast.stuck_samples) == (5000, 3_600_000)
    assert fast.weights["filter_alpha"].tobytes() == model.weights["filter_alpha"].tobytes()
    assert fast.model_id != model.model_id and fast.extra["rated_from"] == model.model_id
    assert fast.at_rate(0.1).model_id == model.model_id
    assert model.at_rate(0.1 * 1.004) is model  # the same 50 samples, a step within 1 %
    slow = model.at_rate(1.0 / 3.0)  # 15 samples of 1/3 s
    assert slow.decimation == 15
    near = model.at_rate(1.0 / 10.3)  # 52 samples: a step of 5.05 s, the alphas for it
    assert near.decimation == 52
    want = filter_alpha([200.0, 900.0], 52, 1.0 / 10.3)
    assert near.weights["filter_alpha"].tobytes() == want.tobytes()
    assert near.weights["filter_alpha"].tobytes() != model.weights["filter_alpha"].tobytes()
    with pytest.raises(UserError, match="multiple of"):
        model.at_rate(1.0 / 7.5)  # 37.5 samples per step


def test_kernel_at_1khz_is_bit_exact() -> None:
    model = samples.random_model(2, 3, 1, 8, decimation=50, seed=8, taus_s=[120.0, 600.0],
                            poly_head=True).at_rate(0.001)
    rng = np.random.default_rng(8)
    n = 120_000  # 2 min at 1 kHz: 24 model steps
    temp = (20 + np.cumsum(rng.normal(0, 0.002, n)) + rng.normal(0, 0.05, n)).astype(np.float32)
    gyro = 10.0 + rng.normal(0, 0.01, n)
    got = Kernel(model, build_kernel(model)).run(temp, gyro)
    want = reference.replay(model, temp, gyro)
    assert got[1].tobytes() == want.sf_ppm.tobytes()
    assert got[0].tobytes() == want.corrected_dps.tobytes()


@pytest.mark.slow
def test_a_day_at_100hz_through_the_kernel_is_bit_exact() -> None:
    """24 h at 100 Hz (8.64 million samples): counters and the held output stay exact."""
    model = samples.random_model(2, 3, 1, 8, decimation=50, seed=9, taus_s=[300.0, 1800.0],
                            poly_head=True, stuck_samples=36000).at_rate(0.01)
    n = 24 * 3600 * 100
    t = np.arange(n) * 0.01
    temp = (5 + 45 * np.sin(2 * np.pi * t / 21600.0)
            + np.random.default_rng(9).normal(0, 0.03, n)).astype(np.float32)
    gyro = np.full(n, 10.0)
    got = Kernel(model, build_kernel(model)).run(temp, gyro)
    want = reference.replay(model, temp, gyro)
    assert got[1].tobytes() == want.sf_ppm.tobytes()
    assert np.array_equal(got[2], want.flags) and not got[2].any()


@pytest.mark.slow
def test_train_at_100hz_runs_at_10_and_1000hz(tmp_path: Path) -> None:
    """The command line end to end: a model trained on a 100 Hz log (D = 500 for 5 s) is
    replayed at 10 Hz and 1 kHz through the C kernel, re-rated, with about the same error
    left; export --sample-rate-hz writes the firmware constants for 1 kHz."""
    train = short_ramp(2.0, 21, sample_rate_hz=100.0)
    write_log(tmp_path / "train.csv", train)
    tests = {}
    for hz in (10.0, 1000.0):
        log: ChamberLog = short_ramp(3.0, 22, sample_rate_hz=hz)
        write_log(tmp_path / f"test{hz:g}.csv", log)
        tests[hz] = log
    fogsf = [sys.executable, "-m", "fogsf"]

    def run(*args: str) -> str:
        p = subprocess.run([*fogsf, *args], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        return p.stdout + p.stderr

    # the structure given: this test is about rates (the one-ramp choice may extrapolate to
    # 3 C/min differently, docs/decisions.md)
    run("train", "--train", str(tmp_path / "train.csv"), "--out", str(tmp_path / "m"),
        "--structure", "bank", "--iters", "40", "--hidden", "8", "--no-progress")
    metrics = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert (metrics["decimation"], metrics["model_step_s"], metrics["sample_rate_hz"]) == \
        (500, 5.0, 100.0)
    after = {}
    for hz in (10.0, 1000.0):
        out = run("replay", str(tmp_path / "m"), str(tmp_path / f"test{hz:g}.csv"),
                  "--out", str(tmp_path / f"c{hz:g}.csv"), "--json", str(tmp_path / "r.json"))
        assert f"D 500 -> {int(5 * hz)} samples" in out
        rep = json.loads((tmp_path / "r.json").read_text())
        assert rep["samples"] == len(tests[hz])
        after[hz] = rep["after"]["rms_ppm"] / rep["after"]["noise_floor_ppm"]
        assert rep["after"]["rms_ppm"] < 0.2 * rep["before"]["rms_ppm"], (hz, rep)
    assert after[1000.0] == pytest.approx(after[10.0], rel=0.35), after
    out = run("export", str(tmp_path / "m"), "--out", str(tmp_path / "fw"), "--name", "imu_z",
              "--sample-rate-hz", "1000")
    assert "D 500 -> 5000" in out
    header = (tmp_path / "fw" / "imu_z.h").read_text()
    assert "IMU_Z_DECIMATION 5000" in header


def test_model_step_and_test_log_at_a_rate_5s_does_not_divide(tmp_path: Path) -> None:
    """At 7.5 Hz a 5 s step is 37.5 samples: refused before any fitting, naming the log;
    --model-step-s 4 (30 samples) trains and checks the rate transfer at that step."""
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    train = short_ramp(2.0, 31, sample_rate_hz=7.5)
    test = short_ramp(3.0, 32, sample_rate_hz=7.5)
    with pytest.raises(UserError, match="37.5 samples at 7.5 Hz"):
        run_training(TrainOptions(model="poly", progress=False), [train], test, tmp_path / "a")
    assert not (tmp_path / "a").exists()
    m, _ = run_training(TrainOptions(model="poly", progress=False, model_step_s=4.0),
                        [train], test, tmp_path / "b")
    assert (m["decimation"], m["model_step_s"]) == (30, 4.0)
    assert m["rate_transfer"]["consistent"] >= 1


def test_simulate_writes_the_rate_asked_for(tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    p = subprocess.run([sys.executable, "-m", "fogsf", "simulate", "--profile", "soak",
                        "--duration-min", "5", "--sample-rate-hz", "50", "--seed", "1",
                        "--out", str(out)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    log = read_log(out)
    assert log.sample_rate_hz == 50.0 and len(log) == 5 * 60 * 50 + 1
    p = subprocess.run([sys.executable, "-m", "fogsf", "inspect", str(out),
                        "--sample-rate-hz", "10"], capture_output=True, text=True)
    assert p.returncode == 2 and "sample rate" in p.stderr and "--sample-rate-hz" in p.stderr
