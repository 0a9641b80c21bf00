"""Irregular sampling, gaps, bursts and clock resets (logs/read/sampling.py; docs/logs.md,
"Irregular sampling, gaps and bursts"), on logs written the way loggers write them
(sim/rigs/raw_loggers.py `write_px4`, `write_bursts`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import parse_log, read_log
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.sampling import common_rate, on_grid
from fogsf.logs.read.stream_read import in_memory, read_log_on_disk
from fogsf.sim.rigs import chambers, raw_loggers, rig_logs
from fogsf.sim.rigs import protocols as rigs

SEED = 39_2026


def px4(folder: Path, rate_hz: float, gyro: int, seed: int, lo: float = 5.0,
        hi: float = 35.0) -> rig_logs.RigLog:
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(lo, hi, 3.0, 3.0, soak_s=120.0),
                               rate_hz=rate_hz)
    return raw_loggers.write_px4(folder / "gyro.csv", rigs.run_rig(p, gyro, seed), seed=seed)


def test_jitter_and_drops_are_read_as_logged_and_counted(tmp_path: Path) -> None:
    rng = np.random.default_rng(SEED)
    gyro, seed = int(rng.integers(20000, 30000)), int(rng.integers(0, 1000))
    rate = float(rng.choice([50.0, 100.0, 200.0]))
    rl = px4(tmp_path, rate, gyro, seed)
    msg = f"gyro {gyro} seed {seed} rate {rate:g}"
    lg = read_log(rl.path)
    truth = rl.truth[""]
    assert len(lg) == truth.time_s.size, msg  # every row as logged, none added
    assert np.abs(lg.time_s - truth.time_s).max() < 1e-6, msg
    s = lg.sampling
    # the writer drops about 2 in 1000, some two in a row; every one is counted
    written = int(np.round(np.diff(truth.time_s) * rate).sum()) - (len(lg) - 1)
    assert abs(s.dropped - written) <= 2, (msg, s.dropped, written)
    assert s.jittered > 0 and not s.gaps and abs(1.0 / s.nominal_s - rate) < 0.01 * rate, msg
    assert any(n.startswith("sampling: nominal") for n in lg.read_notes), msg
    disk = in_memory(read_log_on_disk(rl.path))
    assert np.array_equal(disk.gyro_dps, lg.gyro_dps) and disk.sampling.dropped == s.dropped


def test_on_grid_keeps_true_time() -> None:
    rng = np.random.default_rng(SEED + 1)
    dt = 0.01
    n = 20_000
    t = np.arange(n) * dt + rng.uniform(-0.15, 0.15, n) * dt
    keep = np.ones(n, dtype=bool)
    keep[rng.choice(np.arange(1, n - 1), 40, replace=False)] = False
    slope = 0.01  # deg/s per s: a signal linear in time
    rows = [f"{x:.6f},{20 + 0.001 * x:.6f},10,{10 + slope * x:.9f}" for x in t[keep]]
    lg = parse_log("time_s,temp_c,table_rate_dps,gyro_dps\n" + "\n".join(rows) + "\n")
    g = on_grid(lg, 2 * dt)
    assert np.allclose(np.diff(g.time_s), 2 * dt)
    # each grid row reads the signal at its own time, within the rows' jitter
    assert np.abs(g.gyro_dps - (10 + slope * g.time_s)).max() < slope * dt, SEED
    assert common_rate([lg])[0].sample_dt_s == lg.sample_dt_s  # irregular: on a grid


@pytest.mark.slow
def test_two_rates_train_together_and_replay_on_a_third(tmp_path: Path, capsys) -> None:
    """A model trained on jittered logs with drops at two rates, tested on a third, scores
    as one trained on the same runs logged without jitter or drops."""
    runs = {name: (rigs.run_rig(rigs.reversal_protocol(
        100.0, 60.0, chamber=chambers.loop(lo, hi, 3.0, 3.0, soak_s=120.0), rate_hz=rate),
        20005, seed), seed) for name, rate, seed, lo, hi in (("a", 20.0, 1, 5.0, 35.0),
                                                            ("b", 40.0, 2, 0.0, 40.0),
                                                            ("c", 50.0, 3, 10.0, 30.0))}
    logs = {name: raw_loggers.write_px4(tmp_path / "px4" / name / "gyro.csv", r, seed=seed)
            for name, (r, seed) in runs.items()}
    clean = {name: rig_logs.write_plain(tmp_path / "clean" / name / "gyro.csv", r,
                                        mapping=True) for name, (r, _) in runs.items()}
    after = {}
    for kind, lg in (("px4", logs), ("clean", clean)):
        out = tmp_path / f"m-{kind}"
        assert main(["train", "--train", str(lg["a"].path), "--train", str(lg["b"].path),
                     "--test", str(lg["c"].path), "--model", "poly", "--out", str(out)]) == 0
        m = json.loads((out / "metrics.json").read_text())
        assert m["sample_rate_hz"] == pytest.approx(20.0, rel=0.01)  # the slower's grid
        after[kind] = m["test"]["after"]["rms_ppm"]
    assert abs(after["px4"] - after["clean"]) <= 0.05 * after["clean"] + 0.2, after
    logs = [logs[k] for k in "abc"]
    # replay runs a kernel (a model of the firmware's form) on the rows as logged
    from fogsf.models import samples

    samples.random_model(3, 4, 1, 8, decimation=100, seed=6).save(tmp_path / "k1")
    capsys.readouterr()
    assert main(["replay", str(tmp_path / "k1"), str(logs[2].path), "--out",
                 str(tmp_path / "c.csv"), "--build-dir", str(tmp_path / "k")]) == 0
    text = capsys.readouterr().out
    assert "the kernel ran on the rows as logged" in text and "dropped samples" in text
    assert sum(1 for _ in open(tmp_path / "c.csv")) == len(read_log(logs[2].path)) + 1


def burst_log(folder: Path, gyro: int, seed: int) -> rig_logs.RigLog:
    p = rigs.stationary_protocol(chamber=chambers.Chamber([[0.0, 30.0], [3600.0, 22.0]]),
                                 rate_hz=20.0, arw_deg_per_sqrt_h=0.01)
    return raw_loggers.write_bursts(folder / "tvac.csv", rigs.run_rig(p, gyro, seed),
                                 burst_s=5.0, every_s=120.0)


def test_a_burst_log_is_segments_trains_a_bias_model_and_replays(tmp_path: Path,
                                                                  capsys) -> None:
    rng = np.random.default_rng(SEED + 2)
    gyro, seed = int(rng.integers(20000, 30000)), int(rng.integers(0, 1000))
    rl = burst_log(tmp_path, gyro, seed)
    lg = read_log(rl.path)
    s = lg.sampling
    msg = f"gyro {gyro} seed {seed}"
    assert len(s.gaps) == 30 and len(s.segment_starts) == 31, msg
    logged = lg.extra["logged"] != 0
    assert logged.sum() == len(read_log(rl.path, Dialect(max_gap_s=1000.0))), msg
    assert not lg.valid[~logged].any() and lg.valid[logged].all(), msg
    # carried: the temperature over a gap is the line between its ends
    a = s.segment_starts[1] - 1
    gap = np.flatnonzero(~logged[:a + 1000])[:5]
    assert np.allclose(np.diff(lg.temp_c[gap]), np.diff(lg.temp_c[gap])[0]), msg
    assert np.allclose(np.diff(lg.time_s), 0.05), msg
    out = tmp_path / "m"
    assert main(["train", "--train", str(rl.path), "--window-s", "5", "--out",
                 str(out)]) == 0, msg
    m = json.loads((out / "metrics.json").read_text())
    assert m["model"] == "bias" and m["bias"]["train"]["log0"]["windows"] == 30, msg
    capsys.readouterr()
    assert main(["replay", str(out), str(rl.path), "--window-s", "5", "--out",
                 str(tmp_path / "c.csv"), "--build-dir", str(tmp_path / "k")]) == 0
    text = capsys.readouterr().out
    assert "rows filled into 30 gaps" in text and "after  max|e|" in text, text
    # the output holds the file's rows, the filled ones run but not written
    assert sum(1 for _ in open(tmp_path / "c.csv")) - 1 == int(logged.sum()), msg


def test_restart_holds_the_next_segments_temperature(tmp_path: Path) -> None:
    rl = burst_log(tmp_path, 20007, 4)
    lg = read_log(rl.path, Dialect(gap_states="restart"))
    logged = lg.extra["logged"] != 0
    b = lg.sampling.segment_starts[1]
    filled = np.flatnonzero(~logged[:b])
    assert filled.size and np.all(lg.temp_c[filled] == lg.temp_c[b])


@pytest.mark.parametrize(("after_c", "said"), [
    # rebooted: the clock restarts at 0 and the temperature moved on 4 C while it was down
    (30.0, ("temperature jumps +4.000 C",)),
    # a short reboot: the temperature runs on along its trend, the restart at 0 tells
    (26.0, ("the clock restarts", "runs on")),
])
def test_a_clock_back_to_zero_is_a_reboot(after_c: float, said: tuple[str, ...]) -> None:
    """A clock that restarts at 0 starts a new segment (states restarted), whatever the
    temperature does across the step, and says why."""
    rows = [f"{0.1 * i:.1f},{20 + 0.01 * i:.3f},10,10" for i in range(600)]
    rows += [f"{0.1 * i:.1f},{after_c + 0.01 * i:.3f},10,10" for i in range(600)]
    lg = parse_log("time_s,temp_c,table_rate_dps,gyro_dps\n" + "\n".join(rows) + "\n")
    s = lg.sampling
    assert s.resets == [600] and s.clock_steps == [] and len(s.segment_starts) == 2
    b = s.segment_starts[1]
    assert lg.time_s[b] == pytest.approx(59.9 + 3600.0)
    assert np.all(lg.temp_c[600:b] == after_c)  # states restart at the next segment's start
    note = next(n for n in lg.read_notes if "line 602" in n)
    assert all(w in note for w in said) and "a reboot" in note, note


def test_a_step_back_in_a_soak_is_a_reboot_said_so() -> None:
    """A clock set back 30 s while the temperature is flat on both sides (a soak, a noisy
    thermometer): the temperature cannot tell, so it is read as a reboot, said so."""
    rng = np.random.default_rng(SEED + 54)
    n = 1200
    temp = 25.0 + 0.02 * rng.standard_normal(n)
    t = 100.0 + 0.1 * np.arange(n) - np.where(np.arange(n) >= 600, 30.0, 0.0)
    rows = [f"{t[i]:.1f},{temp[i]:.4f},10,10" for i in range(n)]
    lg = parse_log("time_s,temp_c,table_rate_dps,gyro_dps\n" + "\n".join(rows) + "\n")
    s = lg.sampling
    assert s.resets == [600] and s.clock_steps == [] and len(s.segment_starts) == 2
    note = next(n for n in lg.read_notes if "line 602" in n)
    assert "flat on both sides" in note and "cannot tell" in note, note
    assert "a reboot" in note, note


@pytest.mark.parametrize("noise_c", [0.0, 0.02])
def test_a_clock_step_back_is_not_a_reboot(noise_c: float) -> None:
    """A clock set back 30 s while the logger kept logging (the temperature runs on across
    the step, a noisy thermometer's too): no segment, the later rows timed on from the row
    before, said as a clock step."""
    rng = np.random.default_rng(SEED + 53)
    n = 1200
    temp = 20.0 + 0.01 * np.arange(n) + noise_c * rng.standard_normal(n)
    t = 0.1 * np.arange(n) - np.where(np.arange(n) >= 600, 30.0, 0.0)
    rows = [f"{t[i]:.1f},{temp[i]:.4f},10,10" for i in range(n)]
    lg = parse_log("time_s,temp_c,table_rate_dps,gyro_dps\n" + "\n".join(rows) + "\n")
    s = lg.sampling
    assert s.clock_steps == [600] and s.resets == [] and len(s.segment_starts) == 1
    assert len(lg) == n and lg.time_s[600] == pytest.approx(60.0)
    note = next(n for n in lg.read_notes if "line 602" in n)
    assert "time steps -29.9 s" in note and "a clock step" in note and "runs on" in note, note


def test_a_burst_log_takes_its_windows_from_the_bursts_unless_told(tmp_path: Path,
                                                                    capsys) -> None:
    """No --window-s: 5 s bursts every 2 min are 5 s windows, one a burst, said on stderr;
    a --window-s given is kept (and a window longer than a burst measures nothing)."""
    rl = burst_log(tmp_path, 20011, 5)
    assert main(["train", "--train", str(rl.path), "--out", str(tmp_path / "m")]) == 0
    err = capsys.readouterr().err
    assert "written in bursts of 5 s: windows of 5 s, one a burst" in err
    m = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert m["bias"]["train"]["log0"]["windows"] == 30
    assert main(["inspect", str(rl.path), "--window-s", "100"]) == 2
    assert "written in bursts" not in capsys.readouterr().err
