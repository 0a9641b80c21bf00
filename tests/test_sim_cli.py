"""`fogsf simulate` end to end (short runs)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.logs.logio import read_log
from fogsf.sim import SimConfig

SHORT = ["--scenario", "paper", "--start-c", "15", "--stop-c", "25", "--ramp-rate", "1"]


def test_writes_a_log_the_reader_accepts_with_truth_columns(tmp_path, capsys) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", *SHORT, "--seed", "7", "--out", str(out), "--summary"]) == 0
    log = read_log(out)
    assert len(log) == 6001
    for name in ("chamber_c", "temp_preamp_c", "temp_coil_inner_c", "temp_coil_outer_c",
                 "temp_source_c", "true_sf_ppm", "true_bias_dph"):
        assert name in log.extra
    assert log.earth_rate_dps is not None
    # The board thermometer reads in DS18B20 steps of 0.0625 C.
    assert np.allclose(log.temp_c / 0.0625, np.round(log.temp_c / 0.0625))
    s = json.loads(capsys.readouterr().out)
    assert s["samples"] == 6001 and s["table_rates_dps"] == [10.0]
    assert set(s["metrics"]) == {"max_abs_ppm", "pp_ppm", "rms_ppm", "std_ppm", "window_s",
                                 "noise_floor_ppm"}


def test_same_seed_same_bytes_through_the_cli(tmp_path) -> None:
    a, b, c = (tmp_path / f"{x}.csv" for x in "abc")
    for path, seed in ((a, "3"), (b, "3"), (c, "4")):
        assert main(["simulate", *SHORT, "--seed", seed, "--effect", "temp_rate=20",
                     "--out", str(path)]) == 0
    assert a.read_bytes() == b.read_bytes() != c.read_bytes()


def test_write_config_then_config_reproduces_the_run(tmp_path) -> None:
    cfg_path, a, b = tmp_path / "sim.json", tmp_path / "a.csv", tmp_path / "b.csv"
    args = [*SHORT, "--seed", "9", "--effect", "extra_lag=1200,sens_ppm_per_c=6",
            "--table", "alternating", "--dwell-s", "60", "--latitude-deg", "45"]
    assert main(["simulate", *args, "--write-config", str(cfg_path), "--out", str(a)]) == 0
    cfg = SimConfig.load(cfg_path)
    assert cfg.effects[0].params == {"sens_ppm_per_c": 6.0}
    assert cfg.table.kind == "alternating" and cfg.latitude_deg == 45.0
    assert main(["simulate", "--config", str(cfg_path), "--out", str(b)]) == 0
    assert a.read_bytes() == b.read_bytes()


def test_program_profile_and_levels_table(tmp_path) -> None:
    prog = tmp_path / "chamber.csv"
    prog.write_text("time_s,temp_c\n0,20\n300,20\n900,30\n")
    out = tmp_path / "p.csv"
    assert main(["simulate", "--program", str(prog), "--rates-dps", "10,-50,100",
                 "--dwell-s", "100", "--out", str(out)]) == 0
    log = read_log(out)
    assert log.duration_s == pytest.approx(900.0)
    assert log.extra["chamber_c"][-1] == 30.0
    assert sorted(set(log.table_rate_dps.tolist())) == [-50.0, 10.0, 100.0]


def test_list_effects_and_refusals(capsys) -> None:
    assert main(["simulate", "--list-effects"]) == 0
    text = capsys.readouterr().out
    for name in ("warmup", "extra_lag", "temp_rate", "rate_nonlinearity", "asymmetry",
                 "bias_drift", "aging"):
        assert name in text
    assert main(["simulate", *SHORT, "--effect", "bogus=1", "--summary"]) == 2
    assert "unknown effect" in capsys.readouterr().err
    assert main(["simulate", *SHORT]) == 2
    assert "nothing to do" in capsys.readouterr().err
    assert main(["simulate", "--config", "/nonexistent.json", "--summary"]) == 2


def test_plot_writes_a_png(tmp_path) -> None:
    png = tmp_path / "fig.png"
    assert main(["simulate", *SHORT, "--no-noise", "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_thermal_bias_of_the_population(tmp_path, capsys) -> None:
    """--thermal-bias gives a population gyro the thermal bias make bench-bias draws for
    it (a Shupe term on its coil); refused without --random-gyro and for three gyros."""
    from dataclasses import asdict

    from fogsf.sim.population import gyro_for_seed

    plain, shupe = tmp_path / "plain.json", tmp_path / "shupe.json"
    for path, flag in ((plain, []), (shupe, ["--thermal-bias"])):
        assert main(["simulate", *SHORT, "--random-gyro", "5", *flag, "--write-config",
                     str(path), "--out", str(tmp_path / "x.csv")]) == 0
    want = asdict(gyro_for_seed(5, thermal_bias=True).bias)
    assert SimConfig.load(str(shupe)).bias.__dict__ == want
    assert want["shupe_dph_per_c_per_min"] != 0.0
    assert SimConfig.load(str(plain)).bias.shupe_dph_per_c_per_min == 0.0
    assert main(["simulate", *SHORT, "--thermal-bias", "--out", str(tmp_path / "y.csv")]) == 2
    assert "--random-gyro" in capsys.readouterr().err
    assert main(["simulate", "--rig", "imu3", "--random-gyro", "5", "--thermal-bias",
                 "--out", str(tmp_path / "imu.csv")]) == 2
    assert "one gyro" in capsys.readouterr().err
    rigs = [tmp_path / name / "log.csv" for name in ("rig", "rig-tb")]
    for rig, flag in zip(rigs, ([], ["--thermal-bias"]), strict=True):
        assert main(["simulate", "--rig", "plain", "--protocol", "stationary",
                     "--random-gyro", "5", *flag, "--out", str(rig)]) == 0
    assert rigs[0].read_bytes() != rigs[1].read_bytes()  # the rig's gyro has it too
