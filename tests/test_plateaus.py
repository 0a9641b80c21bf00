"""Rate-table plateaus (IEEE Std 952 style): the settle margin after each change of
commanded rate, +/- pairs separating SF and bias, a staircase's SF per rate step,
nonlinearity and asymmetry, the bias taken off before SF and targets, one windowing for
every command (--window-s, --settle-s), and a log that starts while the temperature moves
(--skip-s). Truth comes from the generator."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import log_metrics, start_note
from fogsf.logs.measure.model_steps import step_means, step_windows, windows_rms
from fogsf.logs.measure.pairs import find_pairs, plateau_pairs, rate_steps
from fogsf.logs.measure.windows import sf_spans, sf_windows
from fogsf.logs.writer import write_log
from fogsf.models.features import step_targets
from fogsf.sim.config import TableConfig
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.scenarios import paper

EARTH_DPS = 0.0023


def reversal_run(seed: int, rate_dps: float = 100.0, dwell_s: float = 60.0,
                 ramp_c_per_min: float = 1.0) -> SimResult:
    """-20 -> 40 C at `ramp_c_per_min` after a 10 min soak, the table reversing +/-rate every
    `dwell_s`; bias 1 deg/h + 0.02 deg/h/C (board), ARW 0.005 deg/sqrt(h) (a navigation-grade
    FOG; the paper scenario's 0.05 would put 0.2 deg/h of noise on each pair's bias)."""
    cfg = paper(ramp_c_per_min, seed)
    cfg.profile.start_c, cfg.profile.stop_c = -20.0, 40.0
    cfg.profile.soak_before_s = 600.0
    cfg.table = TableConfig(kind="alternating", rate_dps=rate_dps, dwell_s=dwell_s)
    cfg.bias.bias_dph, cfg.bias.lin_dph_per_c = 1.0, 0.02
    cfg.noise.arw_deg_per_sqrt_h = 0.005
    return simulate(cfg)


def test_reversal_pairs_give_bias_within_0p1_dph_and_sf() -> None:
    res = reversal_run(5)
    log = res.log
    pp = plateau_pairs(log)
    assert len(pp) == 35  # 70 plateaus of 60 s
    true_bias_dph = np.interp(pp.t_s, log.time_s, res.bias_dps) * 3600.0
    true_sf_ppm = np.interp(pp.t_s, log.time_s, res.sf_ppm)
    # the SF moves ~5 ppm/min on the ramp: a bare pair would read 1.8 deg/h of it as bias
    assert np.max(np.abs(pp.bias_dps * 3600.0 - true_bias_dph)) < 0.1
    assert np.max(np.abs((pp.sf_ratio - 1.0) * 1e6 - true_sf_ppm)) < 1.0
    assert pp.bias_drift_dph_per_c() == pytest.approx(0.02, abs=0.003)


def test_bias_is_taken_off_before_sf_windows_and_targets() -> None:
    res = reversal_run(6, rate_dps=10.0, dwell_s=100.0)  # 1 deg/h reads 28 ppm at 10 deg/s
    log = res.log
    truth = [res.sf_ppm[a:b].mean() for a, b in zip(*sf_spans(log).T, strict=True)]
    w = sf_windows(log)
    raw = sf_windows(log, remove_bias=False)
    assert np.max(np.abs((w.sf_ratio - 1.0) * 1e6 - truth)) < 3.0
    assert np.max(np.abs((raw.sf_ratio - 1.0) * 1e6 - truth)) > 20.0
    # training targets (per 5 s model step) carry no bias either
    t = step_targets(log, 50)
    true_steps = step_means(res.sf_ppm, 50)
    ok = np.isfinite(t)
    assert abs(np.mean(t[ok] - true_steps[ok])) < 1.0


def staircase(slew_s: float = 1.0, e0: float = 150.0, asym: float = 20.0, quad: float = 30.0,
              bias_dph: float = 1.0) -> tuple[ChamberLog, dict[float, tuple[float, float]]]:
    """0, 4, 8 ... 100 deg/s, each +r then -r for 16 s, at 20 C; the table reaches each new
    command by a linear slew over `slew_s` (the commanded column steps). SF error vs nominal:
    e0 + quad (|r| / 100)^2 ppm, +asym/2 for r > 0 and -asym/2 for r < 0. Returns the log and,
    per |rate|, the true (SF+, SF-) in ppm."""
    dt, per = 0.1, 160
    levels = [4.0 * k for k in range(26)]
    cmd = np.repeat([s * r for r in levels for s in (1.0, -1.0)], per)
    actual = cmd.copy()
    k = int(round(slew_s / dt))
    for c in np.flatnonzero(np.diff(cmd) != 0) + 1:
        a, b = cmd[c - 1], cmd[c]
        actual[c:c + k] = a + (b - a) * (np.arange(k) + 0.5) / k
    mag = np.abs(actual)
    e = e0 + quad * (mag / 100.0) ** 2 + np.sign(actual) * asym / 2
    gyro = actual * (1 + e * 1e-6) + bias_dph / 3600.0 + EARTH_DPS
    n = cmd.size
    log = ChamberLog(np.arange(n) * dt, np.full(n, 20.0), cmd, gyro, np.full(n, EARTH_DPS))
    truth = {r: (e0 + quad * (r / 100) ** 2 + asym / 2, e0 + quad * (r / 100) ** 2 - asym / 2)
             for r in levels[1:]}
    return log, truth


def test_staircase_with_a_slewing_table_needs_the_settle_margin() -> None:
    log, truth = staircase()
    st = rate_steps(log)
    assert st is not None and st.rates_dps.tolist() == pytest.approx(sorted(truth))
    want_pos = np.array([truth[r][0] for r in sorted(truth)])
    want_neg = np.array([truth[r][1] for r in sorted(truth)])
    np.testing.assert_allclose(st.sf_pos_ppm, want_pos, atol=0.05)
    np.testing.assert_allclose(st.sf_neg_ppm, want_neg, atol=0.05)
    assert st.asymmetry_ppm == pytest.approx(20.0, abs=0.05)
    # IEEE 952 nonlinearity: the largest deviation of a rate level's output from the
    # least-squares line through every plateau, ppm of the full-scale output
    r = np.array([s * q for q in sorted(truth) for s in (1.0, -1.0)])
    m = np.array([q * (1 + 1e-6 * (truth[q][0] if s > 0 else truth[q][1])) * s
                  for q in sorted(truth) for s in (1.0, -1.0)])
    slope, icpt = np.polyfit(r, m, 1)
    want_nl = np.max(np.abs(m - slope * r - icpt)) / (slope * 100.0) * 1e6
    assert st.nonlinearity_ppm == pytest.approx(want_nl, rel=0.02)
    assert st.bias_dps * 3600 == pytest.approx(1.0, abs=1e-3)  # the bias under asymmetry
    # windows (one per 14 s settled plateau) read the mean of SF+ and SF- at each rate
    w = sf_windows(log)
    want = np.array([np.mean(truth[abs(float(x))]) for x in w.rate_dps])
    assert np.max(np.abs((w.sf_ratio - 1.0) * 1e6 - want)) < 0.05
    # without the settle margin the slewing second is measured as if the table were there
    bad = rate_steps(log, settle_s=0.0)
    assert bad is not None and np.max(np.abs(bad.sf_pos_ppm - want_pos)) > 1000.0
    raw = sf_windows(log, settle_s=0.0)
    want0 = np.array([np.mean(truth[abs(float(x))]) for x in raw.rate_dps])
    assert np.max(np.abs((raw.sf_ratio - 1.0) * 1e6 - want0)) > 1000.0


def test_the_sf_series_taken_off_a_staircases_pairs() -> None:
    """A staircase pair has no neighbour at its own rate, so an SF drifting between its two
    plateaus reads as bias (r/2 x the drift); `minus_sf` with that SF series takes it off,
    and an SF series constant in time leaves every pair's bias as it was."""
    dt, per = 0.1, 160
    cmd = np.repeat([s * 4.0 * k for k in range(1, 26) for s in (1.0, -1.0)], per)
    n = cmd.size
    t = np.arange(n) * dt
    sf = 150.0 + 20.0 * np.sin(2 * np.pi * t / 1800.0)  # ppm: up to 0.07 ppm/s
    bias_dph = 1.0
    gyro = cmd * (1 + sf * 1e-6) + bias_dph / 3600.0 + EARTH_DPS
    log = ChamberLog(t, np.full(n, 20.0), cmd, gyro, np.full(n, EARTH_DPS))
    pp = find_pairs(log)
    assert pp is not None and len(pp) == 25
    raw = pp.bias_dps * 3600.0 - bias_dph
    assert np.max(np.abs(raw)) > 0.1  # 0.07 ppm/s x 16 s x 100 deg/s / 2: 0.2 deg/h
    fixed = pp.minus_sf(sf).bias_dps * 3600.0 - bias_dph
    assert np.max(np.abs(fixed)) < 1e-6
    same = pp.minus_sf(np.full(n, 123.0)).bias_dps
    np.testing.assert_allclose(same, pp.bias_dps, rtol=0, atol=1e-12)
    # reversals at one rate (groups of 3 and 4 plateaus): the neighbours cancel a drift
    # linear in time, not a faster one; minus_sf takes any drift off, also where a stall cut
    # a plateau in two (the SF averaged over the rows the plateau's mean has)
    rev = np.repeat([s * 100.0 for _ in range(20) for s in (1.0, -1.0)], 600)
    tr = np.arange(rev.size) * dt
    drift = 150.0 + 20.0 * np.sin(2 * np.pi * tr / 1200.0)
    valid = np.ones(rev.size, bool)
    valid[6300:6330] = False  # 3 s of stall in the 11th plateau
    lg = ChamberLog(tr, np.full(rev.size, 20.0), rev, rev * (1 + drift * 1e-6)
                    + bias_dph / 3600.0 + EARTH_DPS, np.full(rev.size, EARTH_DPS),
                    valid=valid)
    pr = find_pairs(lg)
    assert pr is not None and len(pr) == 20
    assert np.unique(pr.plateau_spans[:, 2]).size < pr.plateau_spans.shape[0]  # the cut one
    assert np.max(np.abs(pr.bias_dps * 3600.0 - bias_dph)) > 0.01
    np.testing.assert_allclose(pr.minus_sf(drift).bias_dps * 3600.0, bias_dph, atol=1e-6)


def test_staircase_at_bang_bang_set_points() -> None:
    """The staircase at four heater set points (-20, 10, 40, 70 C) held bang-bang (+/-0.5 C,
    2 min), the table at rest on the 30 min ramps between them; SF 150 + 5 (T - 20) + 0.05
    (T - 20)^2 ppm and bias 1 + 0.02 (T - 20) deg/h on top of the rate terms; ARW 0.005
    deg/sqrt(h). The thermal polynomial keeps the rate figures clean."""
    dt, per = 0.1, 160
    stair = np.repeat([s * 4.0 * k for k in range(26) for s in (1.0, -1.0)], per)
    cmds, temps = [], []
    prev = -20.0
    for sp in (-20.0, 10.0, 40.0, 70.0):
        cmds.append(np.zeros(18000))
        temps.append(np.linspace(prev, sp, 18000))
        tt = np.arange(stair.size) * dt
        temps.append(sp + 0.5 * (4 * np.abs((tt / 120.0) % 1.0 - 0.5) - 1))
        cmds.append(stair)
        prev = sp
    cmd, temp = np.concatenate(cmds), np.concatenate(temps)
    mag = np.abs(cmd)
    e = (150 + 5 * (temp - 20) + 0.05 * (temp - 20) ** 2 + 30 * (mag / 100) ** 2
         + np.sign(cmd) * 10)
    rng = np.random.default_rng(1)
    gyro = (cmd * (1 + e * 1e-6) + (1 + 0.02 * (temp - 20)) / 3600 + EARTH_DPS
            + rng.normal(0, 0.005 / 60 / np.sqrt(dt), cmd.size))
    n = cmd.size
    log = ChamberLog(np.arange(n) * dt, temp, cmd, gyro, np.full(n, EARTH_DPS))
    st = rate_steps(log)
    _, truth = staircase()
    nl = rate_steps(staircase()[0]).nonlinearity_ppm  # the same rate terms at 20 C, noiseless
    assert st is not None and st.temp_c == 20.0
    assert st.asymmetry_ppm == pytest.approx(20.0, abs=0.3)
    assert st.nonlinearity_ppm == pytest.approx(nl, abs=0.5)
    assert st.bias_dps * 3600 == pytest.approx(1.0, abs=0.02)
    want = np.array([truth[r][0] for r in sorted(truth)])
    assert np.max(np.abs(st.sf_pos_ppm - want)[3:]) < 1.0  # from 16 deg/s: noise < 1 ppm
    assert np.max(np.abs(st.sf_pos_ppm - want)) < 4.0


def test_a_log_that_starts_with_its_table_command_settles_its_first_plateau() -> None:
    """A rig that starts logging with the table command spins up from rest (docs/simulate.md);
    a table already turning when the log starts reads the same from the first sample."""
    n, dt = 3000, 0.1
    cmd = np.full(n, 10.0)
    spin = np.minimum(np.arange(n) * dt * 15.0, 10.0)  # 15 deg/s^2: 0.67 s to 10 deg/s
    for actual, first in ((spin, 20), (cmd, 0)):
        gyro = actual * (1 + 100e-6) + EARTH_DPS
        log = ChamberLog(np.arange(n) * dt, np.full(n, 20.0), cmd, gyro, np.full(n, EARTH_DPS))
        w = sf_windows(log)
        assert w.start[0] == first and list(w.stop) == [1000, 2000, 3000]
        np.testing.assert_allclose(w.sf_ratio, 1 + 100e-6, atol=1e-9)


def test_windows_on_model_steps_and_their_rms() -> None:
    res = reversal_run(7)
    log = res.log
    spans = sf_spans(log, 50.0)
    # 60 s plateaus: one 50 s window each from the commanded start, the 2 s settle margin
    # trimmed off (the log's first plateau follows no change)
    assert spans[0].tolist() == [0, 500]
    assert np.all(spans[1:, 1] - spans[1:, 0] == 480) and np.all(spans[1:, 0] % 600 == 20)
    win = step_windows(log, 50, 50.0)
    assert win.shape == spans.shape and np.all(win[:, 1] - win[:, 0] == 10)
    err = np.zeros((len(log) - 1) // 50 + 1)
    err[win[0, 0]:win[0, 1]] = 3.0  # one window at 3 ppm, the others at 0
    assert windows_rms(err, win) == pytest.approx(3.0 / np.sqrt(len(win)))
    # constant-rate logs: the settle margin changes nothing (no change of rate)
    const = paper(1.0, 3)
    const.profile.start_c, const.profile.stop_c = 0.0, 30.0
    clog = simulate(const).log
    a, b = sf_windows(clog), sf_windows(clog, settle_s=0.0)
    assert np.array_equal(a.sf_ratio, b.sf_ratio) and np.array_equal(a.start, b.start)
    assert find_pairs(clog) is None and rate_steps(clog) is None


def _run(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fogsf", *argv], capture_output=True,
                          text=True)


@pytest.mark.slow
def test_train_test_on_reversal_logs_honours_window_s(tmp_path: Path) -> None:
    for name, seed in (("a", 11), ("b", 12)):
        write_log(tmp_path / f"{name}.csv", reversal_run(seed, ramp_c_per_min=2.0).log)
    out = _run("train", "--train", str(tmp_path / "a.csv"), "--test", str(tmp_path / "b.csv"),
               "--model", "poly", "--window-s", "50", "--out", str(tmp_path / "m"))
    assert out.returncode == 0, out.stderr
    saved = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert saved["window_s"] == 50.0 and saved["settle_s"] == 2.0
    assert saved["test"]["after"]["window_s"] == 50.0
    assert saved["rate_transfer"]["noise_floor_ppm"] > 0
    assert saved["test"]["after"]["rms_ppm"] < 0.5 * saved["test"]["before"]["rms_ppm"]
    # a window the plateaus cannot hold is refused naming the options
    bad = _run("inspect", str(tmp_path / "a.csv"), "--settle-s", "56", "--skip-s", "58")
    assert bad.returncode != 0 and "--settle-s" in bad.stderr and "--window-s" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_inspect_reports_pairs_rate_steps_and_a_moving_start(tmp_path: Path) -> None:
    log, _ = staircase()
    write_log(tmp_path / "stairs.csv", log)
    out = _run("inspect", str(tmp_path / "stairs.csv"), "--json", "--ref-sf", "1.00015")
    assert out.returncode == 0, out.stderr
    s = json.loads(out.stdout)
    assert s["rate_steps"]["sf_asymmetry_ppm"] == pytest.approx(20.0, abs=0.1)
    assert s["rate_steps"]["sf_nonlinearity_ppm_fs"] > 0
    assert s["pairs"]["count"] == 25 and s["settle_s"] == 2.0
    assert s["pairs"]["without_neighbours"] == 25  # +r, -r, then +(r + 4): no neighbours
    assert "starts while" not in out.stderr  # 20 C throughout
    text = _run("inspect", str(tmp_path / "stairs.csv"), "--ref-sf", "1.00015").stdout
    assert "nonlinearity" in text and "asymmetry" in text and "+/- pairs" in text
    assert "25 of them have no neighbour at their own rate" in text

    res = reversal_run(8, ramp_c_per_min=2.0)
    mid = res.log.slice(int(np.searchsorted(res.log.time_s, 1500.0)), len(res.log))
    assert start_note(res.log) is None  # a 10 min soak first
    assert "starts while the board temperature moves" in start_note(mid)
    write_log(tmp_path / "mid.csv", mid)
    out = _run("inspect", str(tmp_path / "mid.csv"), "--json", "--skip-s", "600",
               "--ref-sf", "1.0")
    assert out.returncode == 0, out.stderr
    assert "starts while the board temperature moves" in out.stderr
    assert "first 600 s are left out" in out.stderr
    s = json.loads(out.stdout)
    assert s["skip_s"] == 600.0 and s["start_ramp_c_per_min"] == pytest.approx(2.0, rel=0.2)
    assert s["pairs"]["without_neighbours"] == 0  # reversals: every pair has its neighbours
    w = sf_windows(mid, skip_s=600.0)
    assert w.start[0] >= 6000


@pytest.mark.slow
def test_diagnose_runs_on_staircase_and_reversal_logs(tmp_path: Path) -> None:
    from fogsf.cli import main as cli

    log, _ = staircase()
    rng = np.random.default_rng(0)
    log.gyro_dps = log.gyro_dps + rng.normal(0.0, 0.005 / 60 / np.sqrt(0.1), len(log))
    log.temp_c = 20.0 + 0.005 * log.time_s / 60.0 * 30.0
    write_log(tmp_path / "stairs.csv", log)
    write_log(tmp_path / "rev.csv", reversal_run(13, ramp_c_per_min=2.0).log)
    for name in ("stairs.csv", "rev.csv"):
        assert cli.main(["diagnose", str(tmp_path / name), "--json",
                         str(tmp_path / f"{name}.json")]) == 0
    noiseless, _ = staircase()  # no noise to weigh windows by: no infinite weight, no traceback
    write_log(tmp_path / "quiet.csv", noiseless)
    out = _run("diagnose", str(tmp_path / "quiet.csv"))
    assert "Traceback" not in out.stderr and out.returncode in (0, 2), out.stderr


@pytest.mark.slow
def test_replay_of_a_log_that_starts_mid_ramp_says_so_and_skips(tmp_path: Path) -> None:
    from ramp_logs import short_ramp

    write_log(tmp_path / "train.csv", short_ramp(1.0, 21))
    whole = short_ramp(1.0, 22)
    i = int(np.searchsorted(whole.time_s, whole.time_s[0] + 1800.0))  # 20 min into the ramp
    write_log(tmp_path / "mid.csv", whole.slice(i, len(whole)))
    out = _run("train", "--train", str(tmp_path / "train.csv"), "--iters", "1",
               "--no-progress", "--out", str(tmp_path / "m"))
    assert out.returncode == 0, out.stderr
    rep = _run("replay", str(tmp_path / "m"), str(tmp_path / "mid.csv"), "--out",
               str(tmp_path / "c.csv"), "--json", str(tmp_path / "r.json"), "--skip-s", "1800",
               "--ref-sf", "1.0")
    assert rep.returncode == 0, rep.stderr
    assert "starts while the board temperature moves" in rep.stderr
    assert "first 1800 s are left out" in rep.stderr
    j = json.loads((tmp_path / "r.json").read_text())
    assert j["skip_s"] == 1800.0 and j["samples"] == len(whole) - i  # the kernel ran over all
    sf = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1, usecols=3)
    everything = log_metrics(whole.slice(i, len(whole)), correction_ppm=sf)["rms_ppm"]
    # the lag states catch up: the first half hour holds most of the error
    assert j["after"]["rms_ppm"] < 0.5 * everything


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_floor_of_short_plateaus_matches_true_noise(seed: int) -> None:
    """+/-10 deg/s every 30 s on a ramp: each 28 s settled plateau is one window (shorter
    than 100 s); its noise comes from ten sub-windows as in a whole window. With the pairs'
    bias taken off, a window's error is its plateau's noise less the pair's bias estimate,
    which holds part of that noise: the windows scatter less than the floor says (the floor
    is the raw window's noise: conservative there, by about a quarter here)."""
    n, dt, sigma = 72000, 0.1, 2.6e-3
    t = np.arange(n) * dt
    rate = np.where((np.arange(n) // 300) % 2 == 0, 10.0, -10.0)
    temp = np.linspace(-20.0, 50.0, n)
    sf = 4.0 * (temp - 20.0)
    clean = rate * (1 + sf * 1e-6) + EARTH_DPS
    noisy = clean + np.random.default_rng(seed).normal(0.0, sigma, n)
    logs = [ChamberLog(t, temp, rate, g, np.full(n, EARTH_DPS)) for g in (noisy, clean)]
    floor = log_metrics(logs[0])["noise_floor_ppm"]
    wn, wc = (sf_windows(lg, remove_bias=False) for lg in logs)
    assert np.all(wn.stop - wn.start <= 300) and len(wn) == 240
    assert floor == pytest.approx(np.std((wn.sf_ratio - wc.sf_ratio) * 1e6), rel=0.2)
    wn, wc = (sf_windows(lg) for lg in logs)
    scatter = np.std((wn.sf_ratio - wc.sf_ratio) * 1e6)
    assert 0.6 * floor < scatter < 1.0 * floor


def test_a_stall_inside_a_plateau_keeps_the_pair_fit() -> None:
    """A plateau cut in two by flagged rows (a stall) still has its pair fitted with its
    neighbours: the bias stays within 0.1 deg/h of the truth next to the stall (with only the
    bare pair it read the SF moving on the ramp as bias, 2 deg/h on a rig log)."""
    res = reversal_run(5)
    log = res.log
    valid = np.ones(len(log), dtype=bool)
    dt = log.sample_dt_s
    for start_s in (1219.0, 2431.0, 3017.0):  # inside + and - plateaus
        k = int(start_s / dt)
        valid[k:k + 10] = False
    log.valid = valid
    pp = plateau_pairs(log)
    true_bias_dph = np.interp(pp.t_s, log.time_s, res.bias_dps) * 3600.0
    assert np.max(np.abs(pp.bias_dps * 3600.0 - true_bias_dph)) < 0.1
