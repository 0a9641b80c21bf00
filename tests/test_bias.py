"""The measured bias (logs/measure/bias.py): a stationary log (table stopped throughout) and the
+/- pairs; inspect's bias block; the SF figures refusing a stationary log."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli import main as cli
from fogsf.errors import UserError
from fogsf.logs.logio import read_log, with_mapping_beside
from fogsf.logs.measure.bias import bias_windows, is_stationary
from fogsf.logs.measure.metrics import log_metrics
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.config import BiasConfig
from fogsf.sim.rigs import chambers, rig_logs
from fogsf.sim.rigs import protocols as rigs

BIAS = BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05, quad_dph_per_c2=0.002)
CHAMBER = (10.0, 40.0, 1.0, 0.7, 300.0)  # loop: lo, hi, up, down C/min, soak s


def write(folder: Path, protocol: rigs.RigProtocol, gyro: int, seed: int) -> rig_logs.RigLog:
    folder.mkdir(parents=True, exist_ok=True)
    return rig_logs.rig_log("plain", folder / "log.csv", protocol, (gyro,), seed=seed)


@pytest.fixture(scope="module")
def stationary(tmp_path_factory: pytest.TempPathFactory) -> rig_logs.RigLog:
    p = rigs.stationary_protocol(chambers.loop(*CHAMBER), bias=BIAS)
    return write(tmp_path_factory.mktemp("stat"), p, 20001, 1)


@pytest.fixture(scope="module")
def reversals(tmp_path_factory: pytest.TempPathFactory) -> rig_logs.RigLog:
    p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(*CHAMBER), bias=BIAS)
    return write(tmp_path_factory.mktemp("rev"), p, 20001, 2)


def read(rl: rig_logs.RigLog):  # noqa: ANN201 - a ChamberLog
    return read_log(rl.path, with_mapping_beside(rl.path, Dialect()))


def window_truth(rl: rig_logs.RigLog, w) -> np.ndarray:  # noqa: ANN001
    truth = rl.truth[""].bias_dph
    return np.array([truth[a:b].mean() for a, b in zip(w.start, w.stop, strict=True)])


def test_a_stationary_log_is_read_and_gives_the_bias(stationary: rig_logs.RigLog) -> None:
    log = read(stationary)
    assert is_stationary(log) and not log.measures.any()
    w = bias_windows(log, 100.0)
    assert w is not None and w.source == "stationary" and len(w) > 40
    err = w.bias_dph - window_truth(stationary, w)
    # each window within 4 noise floors of the truth, and the floor is the spread it shows
    assert np.max(np.abs(err)) < 4.0 * w.noise_floor_dph
    assert 0.5 < np.std(err) / w.noise_floor_dph < 1.5
    assert np.ptp(w.bias_dph) > 2.0  # the thermal drift is there, well above the noise


def test_pairs_give_the_bias_beside_the_sf(reversals: rig_logs.RigLog) -> None:
    log = read(reversals)
    assert not is_stationary(log)
    w = bias_windows(log, 100.0)
    assert w is not None and w.source == "pairs"
    err = w.bias_dph - window_truth(reversals, w)
    assert np.std(err) < 2.0 * w.noise_floor_dph and abs(np.mean(err)) < 0.1


def test_sf_figures_refuse_a_stationary_log_naming_what_it_gives(
        stationary: rig_logs.RigLog) -> None:
    with pytest.raises(UserError, match="measures the bias, not the SF.*bias-only"):
        log_metrics(read(stationary))


def test_all_rows_invalid_is_still_refused(tmp_path: Path) -> None:
    p = tmp_path / "x.csv"
    p.write_text("time_s,temp_c,table_rate_dps,gyro_dps,valid\n"
                 + "".join(f"{0.1 * i:.1f},20,0,0,0\n" for i in range(30)))
    with pytest.raises(UserError, match="no row measures"):
        read_log(p)


def test_inspect_shows_the_stationary_bias(stationary: rig_logs.RigLog,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    png = stationary.path.parent / "b.png"
    assert cli.main(["inspect", str(stationary.path), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "the table stopped throughout" in out and "bias (stationary log" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert cli.main(["inspect", str(stationary.path), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["stationary"] is True and s["metrics"] is None
    b = s["bias"]
    assert b["source"] == "stationary" and b["count"] > 40 and len(b["series"]) == 8
    assert b["series"][0]["t_s"] < 100.0  # times from the log's first sample
    assert 0.04 < b["drift_dph_per_c"] < 0.15


def test_inspect_shows_the_pairs_bias_series(reversals: rig_logs.RigLog,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["inspect", str(reversals.path), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["stationary"] is False and s["metrics"] is not None
    assert s["bias"]["source"] == "pairs" and s["bias"]["count"] == s["pairs"]["count"]


def test_the_simulated_bias_has_a_coil_polynomial_and_a_shupe_term() -> None:
    from fogsf.sim.gyro import simulate
    from fogsf.sim.scenarios import paper

    cfg = paper(1.0, seed=3)
    cfg.bias = BiasConfig(bias_dph=0.5, lin_dph_per_c=0.03, quad_dph_per_c2=0.001,
                          cube_dph_per_c3=2e-5, node="coil_inner",
                          shupe_dph_per_c_per_min=2.0)
    r = simulate(cfg)
    coil = r.nodes["coil_inner"]
    d = coil - 20.0
    rate = np.gradient(coil, cfg.dt_s) * 60.0
    want = 0.5 + 0.03 * d + 0.001 * d**2 + 2e-5 * d**3 + 2.0 * rate
    assert np.allclose(r.bias_dps * 3600.0, want, rtol=0, atol=1e-9)
    assert np.ptp(2.0 * rate) > 0.5  # the Shupe term moves the bias while the coil ramps
    cfg.bias.shupe_dph_per_c_per_min = 0.0
    assert np.allclose(simulate(cfg).bias_dps * 3600.0, want - 2.0 * rate, rtol=0, atol=1e-9)


def test_simulate_writes_a_stationary_rig_log(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s" / "log.csv"
    assert cli.main(["simulate", "--rig", "plain", "--protocol", "stationary",
                     "--random-gyro", "20003", "--out", str(out)]) == 0
    log = read_log(out, with_mapping_beside(out, Dialect()))
    assert is_stationary(log) and log.duration_s > 13000
    capsys.readouterr()
    assert cli.main(["simulate", "--rig", "plain", "--protocol", "stationary", "--rate-dps",
                     "10", "--out", str(out)]) != 0
    assert "keeps the table stopped: --rate-dps and --dwell-s do not apply" in \
        capsys.readouterr().err
