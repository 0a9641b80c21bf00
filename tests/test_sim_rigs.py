"""Rig protocols and log conventions (sim/rigs/): schedules, the slewing and stalling
table, the chamber's bang-bang set points, the writers, and the truth behind them."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.logs.logio import read_log
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.config import BiasConfig, ProfileConfig, SimConfig
from fogsf.sim.gyro import simulate
from fogsf.sim.profiles import chamber_series, table_series
from fogsf.sim.rigs import benches, chambers, plateau_truth, rig_logs, schedules
from fogsf.sim.rigs import protocols as rigs


def small_staircase(rate_hz: float = 10.0, **kw: object) -> rigs.RigProtocol:
    """Two set points, one staircase 0..20 deg/s (11 steps of 16 s) each, 60 s settles."""
    steps = schedules.staircase(4.0, 20.0, 16.0)
    chamber = chambers.bang_bang((20.0, 30.0), hold_s=schedules.schedule_s(steps), settle_s=60.0,
                             ramp_c_per_min=5.0, swing_c=0.75, period_s=120.0)
    return rigs.staircase_protocol(4.0, 20.0, 16.0, chamber=chamber, rate_hz=rate_hz, **kw)


def small_reversals(**kw: object) -> rigs.RigProtocol:
    """+/-100 deg/s, 60 s plateaus, a 10 C ramp at 1 C/min between 2 min soaks."""
    return rigs.reversal_protocol(100.0, 60.0, chamber=chambers.ramp(20.0, 30.0, 1.0, 120.0), **kw)


def plateau_runs(x: np.ndarray) -> list[tuple[int, int, float]]:
    """[start, stop, value] of each run of equal values."""
    edges = np.concatenate([[0], np.flatnonzero(np.diff(x)) + 1, [x.shape[0]]])
    return [(int(a), int(b), float(x[a])) for a, b in zip(edges[:-1], edges[1:], strict=True)]


# --- schedules -------------------------------------------------------------------------------

def test_staircase_both_directions_adjacent() -> None:
    steps = schedules.staircase(4.0, 100.0, 16.0)
    rates = [s.rate_dps for s in steps]
    assert rates[:5] == [0.0, 4.0, -4.0, 8.0, -8.0] and rates[-2:] == [100.0, -100.0]
    assert len(steps) == 51 and all(s.dwell_s == 16.0 for s in steps)


def test_staircase_timing_restarts_after_each_stop() -> None:
    run = rigs.run_rig(small_staircase(accel_dps2=0.0), gyro_seed=0, seed=1)
    dt = run.protocol.dt_s
    for a, b in schedules._runs(run.enabled):
        plats = plateau_runs(run.command_dps[a:b])
        if plats[-1][1] - plats[-1][0] < 160:  # the log's last sample starts a new one
            plats = plats[:-1]
        assert [p[2] for p in plats[:3]] == [0.0, 4.0, -4.0]  # each hold starts a staircase
        assert all((q - p) * dt == pytest.approx(16.0) for p, q, _ in plats[:-1])
        assert [p[2] for p in plats[-2:]] == [20.0, -20.0]
    assert np.all(run.command_dps[~run.enabled] == 0.0)


def test_reversal_timing() -> None:
    run = rigs.run_rig(small_reversals(rate_hz=20.0), gyro_seed=0, seed=1)
    plats = plateau_runs(run.command_dps)
    assert [p[2] for p in plats[:4]] == [100.0, -100.0, 100.0, -100.0]
    assert all((b - a) == 1200 for a, b, _ in plats[:-1])  # 60 s at 20 Hz
    assert run.enabled.all() and not run.stalled.any()


def test_slew_lags_the_command() -> None:
    accel = 200.0
    run = rigs.run_rig(small_reversals(accel_dps2=accel), gyro_seed=0, seed=1)
    dt = run.protocol.dt_s
    assert np.max(np.abs(np.diff(run.table_dps))) <= accel * dt + 1e-9
    lag = run.table_dps != run.command_dps
    starts = schedules._runs(lag)
    assert starts[0] == (0, 5)  # spinning up from rest to 100 deg/s in 0.5 s
    for a, b in starts[1:]:
        if b == lag.shape[0]:  # the log ends while slewing
            continue
        assert (b - a) * dt == pytest.approx(200.0 / accel, abs=dt)  # 1 s to slew 200 deg/s
    a = plateau_runs(run.command_dps)[1][0]
    assert run.table_dps[a] == 100.0 and run.table_dps[a + 5] == pytest.approx(0.0)
    assert run.table_dps[a + 10] == -100.0
    instant = schedules.slew(run.command_dps, dt, 0.0)
    np.testing.assert_array_equal(instant, run.command_dps)


def test_stalls_flagged_and_slower_than_commanded() -> None:
    run = rigs.run_rig(small_reversals(stalls_per_h=60.0), gyro_seed=0, seed=3)
    assert 3 <= len(schedules._runs(run.stalled)) <= 60
    clean = schedules.slew(run.command_dps, run.protocol.dt_s, run.protocol.accel_dps2)
    off = run.table_dps != clean
    assert np.all(run.stalled[off])  # every row the stall touched is flagged
    assert np.all(np.abs(run.table_dps[off]) < np.abs(clean[off]))
    assert not np.any(run.measures & off)


def test_bang_bang_set_points_and_stopped_table() -> None:
    p = small_staircase()
    run = rigs.run_rig(p, gyro_seed=0, seed=1)
    t, chamber = chamber_series(
        ProfileConfig(kind="program", points=p.chamber.points), p.dt_s)
    for (a0, _), centre in zip(p.chamber.stopped, (20.0, 30.0), strict=True):
        hold = (t >= a0) & (t < a0 + 60.0 + schedules.schedule_s(p.schedule))
        if centre == 30.0:
            hold &= t >= p.chamber.stopped[1][1] - 60.0
        assert np.max(np.abs(chamber[hold] - centre)) == pytest.approx(0.75, abs=1e-6)
    ramp = (chamber > 20.8) & (chamber < 29.2)
    assert ramp.any() and not run.enabled[ramp].any()  # the table stops between set points
    assert np.all(run.heating[ramp])
    assert 0.3 < run.heating[run.enabled].mean() < 0.5  # the heater on 40 % of a period
    assert not run.stalled.any()


# --- the truth ------------------------------------------------------------------------------

def test_truth_is_the_output_formula() -> None:
    run = rigs.run_rig(small_staircase(), gyro_seed=7, seed=2)
    tr = run.truth("")
    expect = (tr.axis_rate_dps + tr.earth_dps) * (1.0 + tr.sf_ppm * 1e-6) + tr.bias_dph / 3600
    np.testing.assert_allclose(tr.ideal_dps, expect, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(tr.table_dps, run.table_dps)
    # noise about the ideal: ARW and pulses, zero on average
    resid = run.axes[""].gyro_dps - tr.ideal_dps
    assert abs(resid.mean()) < 1e-4 and resid.std() < 0.01


def test_pairs_give_true_sf_and_bias_at_one_temperature() -> None:
    chamber = chambers.Chamber([[0.0, 25.0], [1200.0, 25.0]])
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chamber, arw_deg_per_sqrt_h=0.0,
                               bias=BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05))
    run = rigs.run_rig(p, gyro_seed=11, seed=0)
    tr = run.truth("")
    settle = int(2.0 / p.dt_s)
    plats = plateau_runs(run.command_dps)[:-1]
    for (a1, b1, r), (a2, b2, _) in zip(plats[::2], plats[1::2], strict=True):
        gp, gm = tr.ideal_dps[a1 + settle:b1].mean(), tr.ideal_dps[a2 + settle:b2].mean()
        sf = ((gp - gm) / (2 * r) - 1.0) * 1e6
        s_true = tr.sf_ppm[a1:b2].mean()
        bias = ((gp + gm) / 2 - tr.earth_dps[0] * (1 + s_true * 1e-6)) * 3600
        assert sf == pytest.approx(s_true, abs=0.01)
        assert bias == pytest.approx(tr.bias_dph[a1:b2].mean(), abs=1e-3)
    board = run.axes[""].result.nodes["board"]
    np.testing.assert_allclose(tr.bias_dph, 1.0 + 0.05 * (board - 20.0))


def test_earth_rate_per_axis() -> None:
    run = rigs.run_imu3(small_reversals(rotating_earth=True), gyro_seeds=(1, 2, 3), seed=0)
    vertical = rigs.earth_map_dps(rigs.LATITUDE_DEG, rigs.SKEW_COSINE)
    assert vertical == pytest.approx(rigs.earth_map_dps(rigs.LATITUDE_DEG) / math.sqrt(3))
    for a in rigs.AXES:
        e = run.truth(a).earth_dps
        turns = np.cumsum(run.table_dps) * run.protocol.dt_s / 360.0
        whole = np.abs(turns) < np.floor(np.abs(turns).max())  # whole turns from the start
        assert e.min() < vertical < e.max()
        assert e[whole][: np.flatnonzero(np.diff(np.floor(turns[whole])))[0] + 1].mean() \
            == pytest.approx(vertical, abs=2e-4)
    still = rigs.run_imu3(small_reversals(), seed=0)
    assert np.all(still.truth("y").earth_dps == vertical)


# --- the writers ------------------------------------------------------------------------------

def test_ros_log_columns_and_mapping(tmp_path: Path) -> None:
    run = rigs.run_rig(small_staircase(stalls_per_h=60.0), gyro_seed=4, seed=5)
    lg = rig_logs.write_ros(tmp_path / "ros.csv", run)
    header = lg.path.read_text().split("\n", 1)[0]
    assert header == "sec,nanosec,gyro_raw,gyro_temp,rig_rate,rig_heating,rig_enabled,rig_stalled"
    raw = np.loadtxt(lg.path, delimiter=",", skiprows=1, dtype=np.float64)
    sec, nsec = raw[:, 0].astype(np.int64), raw[:, 1].astype(np.int64)
    assert np.all(sec >= 1_700_000_000) and np.all((nsec >= 0) & (nsec < 1_000_000_000))
    t = sec - sec[0] + nsec * 1e-9
    np.testing.assert_allclose(np.diff(t), 0.1, atol=1e-6)
    np.testing.assert_allclose(raw[:, 2] * 57.29577951308232, run.axes[""].gyro_dps,
                               rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(raw[:, 4] * 360 / rig_logs.STEPS_PER_REV, run.command_dps,
                               rtol=1e-11, atol=1e-12)
    np.testing.assert_array_equal(raw[:, 6:8].astype(bool), np.column_stack(
        [run.enabled, run.stalled]))
    assert raw[:, 7].any() and not raw[:, 6].all()
    assert set(np.unique(raw[:, 5:8])) == {0.0, 1.0}
    m = tomllib.loads((tmp_path / "fogsf-columns.toml").read_text())
    assert m == lg.columns
    assert m["time_s"] == "sec + nanosec * 1e-9"
    assert m["table_rate_dps"] == "rig_rate * 360 / 577803.965671"
    assert m["valid"] == "rig_enabled == 1 and rig_stalled == 0"
    assert m["earth_rate_dps"] == pytest.approx(0.00235, abs=1e-5)


def test_ros_log_through_the_reader(tmp_path: Path) -> None:
    run = rigs.run_rig(small_staircase(stalls_per_h=60.0), gyro_seed=4, seed=5)
    lg = rig_logs.write_ros(tmp_path / "ros.csv", run)
    log = read_log(lg.path)
    np.testing.assert_allclose(log.time_s, lg.truth[""].time_s, atol=1e-6)
    np.testing.assert_allclose(log.table_rate_dps, run.command_dps, atol=1e-9)
    np.testing.assert_allclose(log.gyro_dps, run.axes[""].gyro_dps, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(log.measures, run.measures & (run.command_dps != 0))


@pytest.mark.parametrize("lsb", [1.0, 0.25, 0.0625])
def test_plain_log_reads_back_with_quantised_thermometer(tmp_path: Path, lsb: float) -> None:
    run = rigs.run_rig(small_staircase(temp_lsb_c=lsb, stalls_per_h=30.0), gyro_seed=3,
                       seed=0)
    lg = rig_logs.write_plain(tmp_path / "plain.csv", run, gyro_unit="deg/s")
    assert lg.columns == {}
    log = read_log(lg.path)
    assert log.time_s[0] == pytest.approx(rig_logs.EPOCH_S) and log.sample_rate_hz == 10.0
    np.testing.assert_allclose(log.time_s - rig_logs.EPOCH_S, run.time_s, atol=2e-6)
    np.testing.assert_array_equal(log.temp_c / lsb, np.round(log.temp_c / lsb))
    np.testing.assert_allclose(log.temp_c, run.axes[""].temp_c, atol=1e-9)
    np.testing.assert_array_equal(log.table_rate_dps, run.command_dps)
    np.testing.assert_allclose(log.gyro_dps, run.axes[""].gyro_dps, rtol=1e-11, atol=1e-12)
    np.testing.assert_array_equal(log.measures, run.measures & (run.command_dps != 0))
    assert not log.measures[~run.enabled].any()


@pytest.mark.parametrize("hz", [10.0, 50.0, 100.0])
def test_plain_log_at_sample_rates(tmp_path: Path, hz: float) -> None:
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.ramp(20.0, 22.0, 2.0, 60.0),
                               rate_hz=hz)
    run = rigs.run_rig(p, gyro_seed=9, seed=0)
    log = read_log(rig_logs.write_plain(tmp_path / "plain.csv", run, gyro_unit="deg/s").path)
    assert log.sample_rate_hz == pytest.approx(hz) and len(log) == run.time_s.shape[0]
    np.testing.assert_allclose(np.diff(log.time_s), 1.0 / hz, atol=2e-6)
    np.testing.assert_allclose(log.gyro_dps, run.axes[""].gyro_dps, rtol=1e-11, atol=1e-12)


def test_plain_log_in_rad_s(tmp_path: Path) -> None:
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.ramp(20.0, 22.0, 2.0, 60.0),
                               rate_hz=50.0)
    run = rigs.run_rig(p, gyro_seed=9, seed=0)
    lg = rig_logs.write_plain(tmp_path / "plain.csv", run, mapping=True)
    header = lg.path.read_text().split("\n", 1)[0]
    assert header == "time_s,temp_c,table_rate_dps,gyro_rad_s,earth_rate_dps,valid"
    assert lg.columns == {"gyro_dps": "gyro_rad_s * 57.29577951308232"}
    raw = np.loadtxt(lg.path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(raw[:, 3] * 57.29577951308232, run.axes[""].gyro_dps,
                               rtol=1e-10, atol=1e-12)
    log = read_log(lg.path)
    np.testing.assert_allclose(log.gyro_dps, run.axes[""].gyro_dps, rtol=1e-10, atol=1e-12)


def test_imu3_log(tmp_path: Path) -> None:
    run = rigs.run_imu3(small_reversals(), gyro_seeds=(1, 2, 3), seed=4)
    lg = rig_logs.write_imu3(tmp_path / "imu.csv", run)
    header = lg.path.read_text().split("\n", 1)[0].split(",")
    assert header == ["time_s", "temp_c", "table_rate_dps", "gyro_x_dps", "gyro_y_dps",
                      "gyro_z_dps", "temp_x_c", "temp_y_c", "temp_z_c", "valid"]
    assert lg.columns["table_rate_y_dps"] == "table_rate_dps * 0.5773502691896258"
    assert lg.columns["earth_rate_z_dps"] == pytest.approx(0.00235 / math.sqrt(3), abs=1e-5)
    assert tomllib.loads((tmp_path / "fogsf-columns.toml").read_text()) == lg.columns
    sfs = [lg.truth[a].sf_ppm for a in rigs.AXES]
    assert not np.allclose(sfs[0], sfs[1]) and not np.allclose(sfs[1], sfs[2])
    for a in rigs.AXES:
        tr = lg.truth[a]
        np.testing.assert_allclose(tr.axis_rate_dps, run.table_dps * rigs.SKEW_COSINE)
        expect = (tr.axis_rate_dps + tr.earth_dps) * (1 + tr.sf_ppm * 1e-6) \
            + tr.bias_dph / 3600
        np.testing.assert_allclose(tr.ideal_dps, expect, atol=1e-12)
    bare = rig_logs.write_imu3(tmp_path / "bare" / "imu.csv", run, mapping=False)
    log = read_log(bare.path, Dialect(axis="z"))  # no map: no per-axis table
    np.testing.assert_allclose(log.gyro_dps, run.axes["z"].gyro_dps, rtol=1e-11)
    np.testing.assert_allclose(log.temp_c, run.axes["z"].temp_c, atol=1e-9)  # temp_z_c
    log = read_log(lg.path, Dialect(axis="y"))
    np.testing.assert_allclose(log.gyro_dps, run.axes["y"].gyro_dps, rtol=1e-11)


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    def ros(folder: str, seed: int) -> bytes:
        p = small_staircase(stalls_per_h=60.0)
        lg = rig_logs.write_ros(tmp_path / folder / "ros.csv", rigs.run_rig(p, 4, seed))
        return lg.path.read_bytes()

    assert ros("a", 5) == ros("b", 5)
    assert ros("c", 6) != ros("a", 5)


def test_simulate_with_the_schedule_given_as_a_series_is_unchanged() -> None:
    cfg = SimConfig(dt_s=0.1)
    cfg.profile.kind, cfg.profile.duration_s, cfg.profile.start_c = "soak", 300.0, 10.0
    cfg.table.kind, cfg.table.rate_dps, cfg.table.dwell_s = "alternating", 50.0, 30.0
    a = simulate(cfg)
    t, _ = chamber_series(cfg.profile, cfg.dt_s)
    b = simulate(cfg, table_dps=table_series(cfg.table, t), earth_dps=a.log.earth_rate_dps[0])
    for k, v in a.log.columns().items():
        np.testing.assert_array_equal(v, b.log.columns()[k])
    with pytest.raises(ValueError, match="table_dps"):
        simulate(cfg, table_dps=t[:-1])


def test_plateaus_and_pairs_carry_the_truth() -> None:
    run = rigs.run_rig(small_staircase(arw_deg_per_sqrt_h=0.0), gyro_seed=2, seed=0)
    plats = plateau_truth.plateaus(run, settle_s=2.0)
    assert len(plats) == 20 and all(p.stop - p.start == 140 for p in plats)
    prs = plateau_truth.pairs(plats)
    assert [q.rate_dps for q in prs] == [4.0, 8.0, 12.0, 16.0, 20.0] * 2
    r = run.axes[""].result
    for q in prs:
        gp = r.ideal_dps[q.plus.start:q.plus.stop].mean()
        gm = r.ideal_dps[q.minus.start:q.minus.stop].mean()
        assert ((gp - gm) / (2 * q.rate_dps) - 1) * 1e6 == pytest.approx(q.sf_ppm, abs=0.5)
        assert q.plus.rate_dps > 0 > q.minus.rate_dps
    stalled = rigs.run_rig(small_staircase(stalls_per_h=120.0), gyro_seed=2, seed=0)
    for p in plateau_truth.plateaus(stalled):
        assert stalled.measures[p.start:p.stop].all()


@pytest.mark.parametrize("kind", rig_logs.RIG_KINDS)
def test_rig_log_in_one_call(tmp_path: Path, kind: str) -> None:
    seeds = (20001, 20002, 20003) if kind == "imu3" else (20001,)
    chamber = chambers.ramp(20.0, 21.0, 1.0, 30.0)
    lg = rig_logs.rig_log(kind, tmp_path / f"{kind}.csv", "reversals", seeds, seed=1,
                      chamber=chamber, rate_hz=20.0)
    assert lg.path.is_file() and lg.mapping_path is not None
    assert set(lg.truth) == ({"x", "y", "z"} if kind == "imu3" else {""})
    with pytest.raises(UserError, match="gyro seed"):
        rig_logs.rig_log(kind, tmp_path / "no.csv", "reversals", (1, 2), chamber=chamber)


def test_simulate_rig_cli(tmp_path: Path) -> None:
    from fogsf.cli.main import main

    out = tmp_path / "ros" / "ros.csv"
    assert main(["simulate", "--rig", "ros", "--random-gyro", "3", "--out", str(out),
                 "--truth", str(tmp_path / "truth.csv"), "--stalls-per-h", "10"]) == 0
    assert (out.parent / "fogsf-columns.toml").is_file() and (tmp_path / "truth.csv").is_file()
    head = out.read_text().split("\n", 2)
    assert head[0].startswith("sec,nanosec,gyro_raw") and head[1].startswith("1700000000,0,")
    assert main(["simulate", "--rig", "imu3", "--scenario", "paper", "--out", str(out)]) == 2
    assert main(["simulate", "--rig", "imu3", "--gyro-seeds", "1,2", "--out", str(out)]) == 2
    assert main(["simulate", "--rig", "plain", "--effect", "nosuch=1", "--out", str(out)]) == 2
    assert main(["simulate", "--rig", "plain", "--protocol", "staircase", "--rate-dps", "8",
                 "--effect", "asymmetry=30", "--out", str(tmp_path / "p" / "p.csv")]) == 0


def test_rate_effects_see_the_axis_rate() -> None:
    from fogsf.sim.effects import EffectConfig

    fx = [EffectConfig("asymmetry", 20.0), EffectConfig("rate_nonlinearity", 10.0)]
    base = rigs.run_rig(small_staircase(), gyro_seed=2, seed=0)
    run = rigs.run_rig(small_staircase(effects=fx), gyro_seed=2, seed=0)
    extra = run.truth("").sf_ppm - base.truth("").sf_ppm
    rate = run.table_dps
    np.testing.assert_allclose(extra, 10.0 * np.sign(rate) + 10.0 * np.abs(rate) / 100.0,
                               atol=1e-6)
    imu = rigs.run_imu3(small_reversals(effects=fx[1:]), seed=0)
    np.testing.assert_allclose(
        imu.truth("x").sf_ppm - rigs.run_imu3(small_reversals(), seed=0).truth("x").sf_ppm,
        10.0 * np.abs(imu.table_dps) * rigs.SKEW_COSINE / 100.0, atol=1e-6)


def test_bench_cases_write_train_and_test(tmp_path: Path) -> None:
    cases = benches.bench_cases()
    assert set(cases) >= {"ros-staircase", "ros-bias", "plain-reversals", "imu3-reversals",
                          "thermometer-1c", "thermometer-0.25c"}
    short = chambers.ramp(20.0, 21.0, 1.0, 30.0)
    case = replace(cases["thermometer-1c"], train=replace(cases["thermometer-1c"].train,
                                                          chamber=short),
                   test=replace(cases["thermometer-1c"].test, chamber=short))
    train, test = benches.write_case(tmp_path, case, (20005,), seed=3)
    assert train.path.parent.name == "train" and test.path.parent.name == "test"
    assert (tmp_path / "test" / "fogsf-columns.toml").is_file()
    assert train.path.read_bytes() != test.path.read_bytes()  # another noise seed
    temps = np.loadtxt(test.path, delimiter=",", skiprows=1)[:, 1]
    np.testing.assert_array_equal(temps, np.round(temps))


@pytest.mark.parametrize("change,word", [
    ({"rate_hz": 0.5}, "rate_hz"), ({"accel_dps2": -1.0}, "accel_dps2"),
    ({"stalls_per_h": 1e9}, "stalls_per_h"), ({"stall_share": (0.5, 1.5)}, "stall_share"),
    ({"temp_lsb_c": float("nan")}, "temp_lsb_c"), ({"schedule": []}, "schedule"),
    ({"schedule": [schedules.Step(10.0, 0.0)]}, "dwell_s"), ({"latitude_deg": 95.0}, "latitude"),
    ({"thermal_bias": True}, "thermal_bias"),
])
def test_bad_protocols_refused(change: dict[str, object], word: str) -> None:
    with pytest.raises(UserError, match=word):
        rigs.run_rig(replace(small_reversals(), **change))


def test_thermal_bias_is_each_gyros_own() -> None:
    """thermal_bias: each gyro's bias law from the population (its coil, a Shupe term, a
    quadratic, a cubic); the bench cases use it."""
    from fogsf.sim.population import gyro_for_seed

    p = small_reversals(bias=None, thermal_bias=True)
    run = rigs.run_rig(p, gyro_seed=20003, seed=1)
    law = gyro_for_seed(20003, thermal_bias=True).bias
    assert law.shupe_dph_per_c_per_min != 0.0 and law.node.startswith("coil")
    assert run.axes[""].result.config.bias == law
    plain = rigs.run_rig(small_reversals(bias=None), gyro_seed=20003, seed=1)
    assert plain.axes[""].result.config.bias == gyro_for_seed(20003).bias
    assert not np.allclose(run.truth("").bias_dph, plain.truth("").bias_dph)
    for case in benches.bench_cases().values():
        assert case.train.thermal_bias and case.test.thermal_bias and case.train.bias is None


def test_bad_chambers_refused() -> None:
    with pytest.raises(UserError, match="period_s"):
        chambers.bang_bang((20.0,), period_s=0.0)
    with pytest.raises(UserError, match="ramp_c_per_min"):
        chambers.bang_bang((20.0, 30.0), ramp_c_per_min=0.0)
    with pytest.raises(UserError, match="rate_c_per_min"):
        chambers.ramp(20.0, 30.0, 0.0)
    with pytest.raises(UserError, match="leave -60..100"):
        rigs.run_rig(rigs.reversal_protocol(chamber=chambers.ramp(20.0, 130.0, 10.0, 10.0)))


def test_stamp_jitter(tmp_path: Path) -> None:
    p = replace(small_reversals(), rate_hz=100.0, stamp_jitter_s=0.0005)
    run = rigs.run_rig(p, gyro_seed=1, seed=2)
    jitter = run.stamp_s - run.time_s
    assert 0.0003 < np.abs(jitter).max() <= 0.0005 and abs(jitter.mean()) < 2e-5
    lg = rig_logs.write_ros(tmp_path / "ros.csv", run)
    raw = np.loadtxt(lg.path, delimiter=",", skiprows=1, dtype=np.int64, usecols=(0, 1))
    ns = (raw[:, 0] - raw[0, 0]) * 1_000_000_000 + raw[:, 1]
    np.testing.assert_allclose(ns * 1e-9, run.stamp_s, atol=1e-9)
    np.testing.assert_allclose(lg.truth[""].time_s - rig_logs.EPOCH_S, run.stamp_s, atol=1e-6)
    log = read_log(rig_logs.write_plain(tmp_path / "p" / "plain.csv", run, gyro_unit="deg/s").path)
    assert log.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    with pytest.raises(UserError, match="stamp_jitter_s"):
        rigs.run_rig(replace(p, stamp_jitter_s=0.001))
