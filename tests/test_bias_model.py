"""The bias model (training/bias/model.py): the lag bank's polynomial of z fitted to the
measured bias; a Shupe term (bias ~ dT/dt of the coil) that a cubic in T cannot carry; the
bias-only model of `fogsf train` on stationary logs; mixed logs refused."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli import main as cli
from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.bias import bias_windows
from fogsf.logs.writer import write_log
from fogsf.training.bias.features import bank_feature_map
from fogsf.training.bias.fit import fit_bias
from fogsf.training.bias.model import score_bias
from fogsf.training.bias.targets import check_mixed

EARTH_DPS = 0.0025
SHUPE_DPH_PER_C_PER_MIN = 3.0  # bias per C/min of the coil's temperature change
COIL_TAU_S = 400.0


def soak_log(points: list[tuple[float, float]], seed: int, path: str = "<memory>",
             shupe: float = SHUPE_DPH_PER_C_PER_MIN, arw_dps: float = 0.002
             ) -> tuple[ChamberLog, np.ndarray]:
    """A stationary log at 10 Hz through chamber (time s, C) points (white noise arw_dps a
    sample: 0.04 deg/sqrt(h) by default); the coil lags the board
    by COIL_TAU_S; bias (deg/h) = 0.5 + 0.04 (Tc - 20) + 0.001 (Tc - 20)^2 + shupe dTc/dt
    (C/min). Returns (log, true bias per sample)."""
    dt = 0.1
    t = np.arange(0.0, points[-1][0], dt)
    board = np.interp(t, *zip(*points, strict=True))
    coil = np.empty_like(board)
    a = dt / COIL_TAU_S
    coil[0] = board[0]
    for i in range(1, t.size):
        coil[i] = coil[i - 1] + a * (board[i] - coil[i - 1])
    rate = np.gradient(coil, dt) * 60.0
    d = coil - 20.0
    bias = 0.5 + 0.04 * d + 0.001 * d * d + shupe * rate
    rng = np.random.default_rng(seed)
    gyro = EARTH_DPS + bias / 3600.0 + rng.normal(0.0, arw_dps, t.size)
    log = ChamberLog(t, board, np.zeros_like(t), gyro, np.full_like(t, EARTH_DPS), path=path)
    return log, bias


TRAIN = [(0, 10), (1200, 10), (3000, 40), (4200, 40), (6000, 10), (7200, 10)]  # 1, 1 C/min
TEST = [(0, 15), (900, 15), (2700, 35), (3900, 35), (4700, 20), (6000, 20)]  # other path


def truth_in_windows(log: ChamberLog, bias: np.ndarray) -> tuple[np.ndarray, object]:
    w = bias_windows(log, 100.0)
    assert w is not None
    return np.array([bias[a:b].mean() for a, b in zip(w.start, w.stop, strict=True)]), w


@pytest.mark.slow
def test_the_bank_carries_a_shupe_bias_a_cubic_in_t_does_not() -> None:
    train, _ = soak_log(TRAIN, 1)
    test, true_bias = soak_log(TEST, 2)
    model = fit_bias(bank_feature_map([train], 5.0), [train])
    assert model is not None and model.sources == ["stationary"]
    truth, w = truth_in_windows(test, true_bias)
    pred = model.predict(test)
    p = np.array([pred[a:b].mean() for a, b in zip(w.start, w.stop, strict=True)])
    err = np.std(p - truth)
    # the PX4 way: a cubic in board temperature fitted to the same training windows
    tw, ww = truth_in_windows(train, soak_log(TRAIN, 1)[1])
    cubic = np.polyfit(ww.temp_c, ww.bias_dph, 3)
    err_cubic = np.std(np.polyval(cubic, w.temp_c) - truth)
    assert err < max(0.1, 0.05 * np.std(truth)), (err, np.std(truth))
    assert err_cubic > 2.0 * err, (err_cubic, err)


@pytest.mark.slow
def test_before_after_metrics_and_the_noise_floor() -> None:
    train, _ = soak_log(TRAIN, 3)
    test, _ = soak_log(TEST, 4)
    model = fit_bias(bank_feature_map([train], 5.0), [train])
    s = score_bias(model, test)
    assert s is not None and s["source"] == "stationary"
    before, after = s["before"], s["after"]
    assert before["std_dph"] > 4.0 * after["std_dph"]
    # what is left is the noise: within 1.5 x the floor the windows show
    assert after["std_dph"] < 1.5 * after["noise_floor_dph"]
    assert set(after) == {"max_abs_dph", "pp_dph", "rms_dph", "std_dph", "noise_floor_dph"}


def test_a_log_without_bias_gives_no_model() -> None:
    log, _ = soak_log(TRAIN, 5)
    turning = ChamberLog(log.time_s, log.temp_c, np.full_like(log.time_s, 10.0),
                         log.gyro_dps + 10.0, log.earth_rate_dps)
    assert fit_bias(bank_feature_map([turning], 5.0), [turning]) is None


def test_mixed_stationary_and_turning_logs_are_refused() -> None:
    log, _ = soak_log(TRAIN[:3], 6, path="soak.csv")
    turning = ChamberLog(log.time_s, log.temp_c, np.full_like(log.time_s, 10.0),
                         log.gyro_dps, log.earth_rate_dps, path="ramp.csv")
    assert check_mixed([log]) is True and check_mixed([turning]) is False
    with pytest.raises(UserError, match="soak.csv: stationary.*bias-only"):
        check_mixed([log, turning])


@pytest.mark.slow
def test_train_on_stationary_logs_is_a_bias_only_model(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    for name, pts, seed in (("a.csv", TRAIN, 7), ("b.csv", TEST, 8)):
        write_log(tmp_path / name, soak_log(pts, seed)[0])
    out = tmp_path / "m"
    assert cli.main(["train", "--train", str(tmp_path / "a.csv"), "--test",
                     str(tmp_path / "b.csv"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "bias only" in text and "test after" in text
    m = json.loads((out / "metrics.json").read_text())
    assert m["model"] == "bias" and m["bias_only"] is True
    after = m["bias"]["test"]["after"]
    assert after["std_dph"] < 1.5 * after["noise_floor_dph"]
    assert m["bias"]["test"]["before"]["std_dph"] > 4.0 * after["std_dph"]
    # the interval: the chosen structure among the consistent ones (by held-out score, not
    # the most flexible fit), the test's RMS inside it, its top not far above
    rt = m["bias"]["rate_transfer"]
    assert m["bias"]["model"]["structure"]["chosen"] in rt["consistent"]
    lo, hi = rt["rms_interval_dph"]
    assert lo <= after["rms_dph"] <= hi <= 3.0 * after["rms_dph"], (lo, after, hi)
    # the test ramps (at most 1.1 C/min) within the training's 1 C/min (+15 %)
    rr = m["bias"]["rate_transfer"]["ramp_rates"]
    assert rr["train_fastest_c_per_min"] == pytest.approx(1.0, rel=0.05)
    assert not rr["rate_term_extrapolated"] and "extrapolated" not in text


@pytest.mark.slow
def test_train_says_when_the_test_ramps_faster_than_any_training_ramp(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A Shupe term fitted on 1 C/min ramps and tested on a 3 C/min ramp is extrapolated:
    `train` says so, and what would pin it."""
    fast = [(0, 15), (900, 15), (1300, 35), (2200, 35), (2600, 15), (3600, 15)]  # 3 C/min
    for name, pts, seed in (("a.csv", TRAIN, 7), ("b.csv", fast, 8)):
        write_log(tmp_path / name, soak_log(pts, seed)[0])
    out = tmp_path / "m"
    assert cli.main(["train", "--train", str(tmp_path / "a.csv"), "--test",
                     str(tmp_path / "b.csv"), "--out", str(out)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    m = json.loads((out / "metrics.json").read_text())
    assert m["bias"]["model"]["structure"]["chosen"] != "cubic"
    rr = m["bias"]["rate_transfer"]["ramp_rates"]
    assert rr["rate_term_extrapolated"]
    assert rr["test_fastest_c_per_min"] > 2.0 * rr["train_fastest_c_per_min"]
    assert "faster than any training ramp" in text and "Shupe term" in text
    region = m["bias"]["rate_transfer"]["lead_region"]  # lead's time constants left open
    assert region["tau_s"][0] <= 400.0 <= region["tau_s"][1]  # the coil's true 400 s
    assert f"lead at the coil time constants the training targets allow ({region['tau_s'][0]:.0f}" \
        in text


@pytest.mark.slow
def test_the_bias_only_artifact_replays_through_the_kernel(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    """train -> stream model (SF exactly 0, the bias head) -> replay through the C kernel:
    the kernel's float32 bias is the fit's to 1e-3 deg/h, the CSV has bias_dph, and the
    corrected rate is the raw one minus the bias."""
    import csv

    from fogsf.logs.logio import read_log
    from fogsf.models import reference
    from fogsf.models.stream import StreamModel
    from fogsf.training.bias.fit import fit_bias

    write_log(tmp_path / "a.csv", soak_log(TRAIN, 9)[0])
    test, _ = soak_log(TEST, 10)
    write_log(tmp_path / "b.csv", test)
    out = tmp_path / "m"
    assert cli.main(["train", "--train", str(tmp_path / "a.csv"), "--out", str(out)]) == 0
    sm = StreamModel.load(out)
    m = json.loads((out / "metrics.json").read_text())
    assert sm.bias_head and sm.model == "bias" and m["model_id"] == sm.model_id
    assert m["params"] == sm.params
    ref = reference.replay(sm, test.temp_c, test.gyro_dps)
    assert not ref.sf_ppm.any()
    fit = fit_bias(None, [read_log(tmp_path / "a.csv")])  # what train fitted: deterministic
    assert fit is not None
    assert m["bias"]["model"]["structure"]["chosen"] == fit.choice.name
    assert np.max(np.abs(ref.bias_dph - fit.predict(test))) < 1e-3
    # the feature map written as its diagonal where it is one (as SF models), bit for bit
    # the dense model's outputs
    w = fit.fm.feat_w
    diag = w.shape[0] == w.shape[1] and not np.any(w[~np.eye(w.shape[0], dtype=bool)])
    assert sm.feat_diag == diag
    assert np.array_equal(np.diagonal(w) if diag else w, sm.weights["feat_w"])
    if diag:
        dense = replace(sm, weights={**sm.weights, "feat_w": w}, feat_diag=False)
        assert dense.params > sm.params
        got = reference.replay(dense, test.temp_c, test.gyro_dps)
        assert np.array_equal(got.bias_dph, ref.bias_dph)
        assert np.array_equal(got.corrected_dps, ref.corrected_dps)
    capsys.readouterr()
    assert cli.main(["replay", str(out), str(tmp_path / "b.csv"), "--out",
                     str(tmp_path / "r.csv")]) == 0
    text = capsys.readouterr().out
    assert "measures the bias, not the SF" in text and "bias, " in text
    with open(tmp_path / "r.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0][-1] == "bias_dph"
    got = np.array(rows[1:], dtype=np.float64)
    assert np.array_equal(got[:, 4].astype(np.float32), ref.bias_dph)
    # the float32 correction (contract fogsf-stream-2): sf is 0 exactly, so k is 0 and the
    # corrected rate is g - bias / 3600, each in float32
    g32, b32 = got[:, 1].astype(np.float32), got[:, 4].astype(np.float32) / np.float32(3600)
    assert np.array_equal(got[:, 2], (g32 - b32).astype(np.float64))


@pytest.mark.slow
def test_train_on_reversals_gives_the_sf_model_a_bias_head(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    from fogsf.models.stream import StreamModel
    from fogsf.sim.config import BiasConfig
    from fogsf.sim.rigs import benches, chambers, rig_logs
    from fogsf.sim.rigs import protocols as rigs

    bias = BiasConfig(bias_dph=1.0, lin_dph_per_c=0.05, quad_dph_per_c2=0.002)
    logs = []
    for name, seed in (("train", 21), ("test", 22)):
        (tmp_path / name).mkdir()
        p = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(10.0, 40.0, 1.0, 0.7, 300.0),
                                   bias=bias, arw_deg_per_sqrt_h=benches.QUIET_ARW)
        logs.append(rig_logs.rig_log("plain", tmp_path / name / "log.csv", p, (20002,),
                                 seed=seed).path)
    out = tmp_path / "m"
    assert cli.main(["train", "--train", str(logs[0]), "--test", str(logs[1]), "--out",
                     str(out), "--iters", "20", "--no-progress"]) == 0
    assert "bias, deg/h" in capsys.readouterr().out
    sm = StreamModel.load(out)
    m = json.loads((out / "metrics.json").read_text())
    assert sm.bias_head and sm.model == "lag-lstm" and m["model_id"] == sm.model_id
    assert m["params"] == sm.params
    b = m["bias"]["test"]
    assert b["source"] == "pairs" and b["before"]["std_dph"] > 3.0 * b["after"]["std_dph"]
    assert b["after"]["std_dph"] < 2.0 * b["after"]["noise_floor_dph"]


@pytest.mark.slow
def test_same_logs_same_bias_model_bytes(tmp_path: Path) -> None:
    from fogsf.export.onnx_step import build_step_onnx
    from fogsf.models.stream import StreamModel

    write_log(tmp_path / "a.csv", soak_log(TRAIN, 13)[0])
    for out in ("m1", "m2"):
        assert cli.main(["train", "--train", str(tmp_path / "a.csv"), "--out",
                         str(tmp_path / out)]) == 0
    a, b = (tmp_path / "m1" / "stream_weights.npz"), (tmp_path / "m2" / "stream_weights.npz")
    assert a.read_bytes() == b.read_bytes()
    model = StreamModel.load(tmp_path / "m1")
    assert model.model_id == StreamModel.load(tmp_path / "m2").model_id
    outputs = [o.name for o in build_step_onnx(model).graph.output]
    assert outputs[0] == "sf_ppm" and outputs[-1] == "bias_dph"


@pytest.mark.slow
@pytest.mark.parametrize("structure", ["cubic", "shupe", "node", "shupe2", "lead", "bank"])
def test_every_bias_structure_goes_through_the_bias_head(structure: str) -> None:
    """Each structure, forced, as a bias-only artifact: the kernel's reference (float32,
    the C kernel's order) gives the fit's bias to 1e-3 deg/h on another log; the head's
    polynomial over z is the structure's own fit, on a front end of its own and on an SF
    model's z (the lag bank's; for `lead`, which adds its coil node, also a z without a lag
    fast enough for the board's rate, to which it adds that too)."""
    from fogsf.models import reference
    from fogsf.training.bias.artifact import bias_only_stream_model
    from fogsf.training.bias.features import node_feature_map

    train, _ = soak_log(TRAIN, 31)
    test, _ = soak_log(TEST, 32)
    shared = [bank_feature_map([train], 5.0)]
    if structure == "lead":  # and z standardised (gsa-lstm's): T and its lags scaled, shifted
        shared.append(node_feature_map([train], 5.0, (500.0, 3000.0)))
        fm0 = shared[0]
        shared.append(replace(fm0, feat_w=(fm0.feat_w * 2.0).astype(np.float32),
                              feat_b=(fm0.feat_b + 0.3).astype(np.float32)))
    for fm in [None, *shared]:
        model = fit_bias(fm, [train], candidates=(structure,))
        assert model is not None and model.choice.name == structure
        if fm is not None and structure == "lead":  # its own filters after z's
            added = model.fm.fe.filter_tau_s[len(fm.fe.filter_tau_s):]
            assert len(added) == (1 if 60.0 in fm.fe.filter_tau_s else 2), added
        sm = bias_only_stream_model(model) if fm is None else None
        if sm is not None:
            ref = reference.replay(sm, test.temp_c, test.gyro_dps)
            assert np.max(np.abs(ref.bias_dph - model.predict(test))) < 1e-3, structure
        # the head's polynomial over z is the structure's own fit (its columns, float64)
        own = model.family.fits[structure].predict(model.family.columns_of(test))
        head = model.predict_steps(model.fm.z(test))
        assert np.max(np.abs(own - head)) < 0.01, structure


@pytest.mark.slow
@pytest.mark.parametrize("shupe", [0.0, SHUPE_DPH_PER_C_PER_MIN])
def test_a_shupe_bias_takes_the_coils_own_rate(shupe: float) -> None:
    """On a front end of its own, a bias the cubic in T misses by far (a Shupe term) takes
    `lead`, the coil's cubic and its own rate of change; without one the rule's choice."""
    from fogsf.training.bias.choice import SHUPE_EVIDENT

    train, _ = soak_log(TRAIN, 41, shupe=shupe)
    test, true_bias = soak_log(TEST, 42, shupe=shupe)
    model = fit_bias(None, [train])
    assert model is not None
    scores = model.choice.scores
    evident = scores["cubic"] > SHUPE_EVIDENT * min(scores.values())
    assert evident == (shupe > 0), scores
    assert (model.choice.name == "lead") == evident
    truth, w = truth_in_windows(test, true_bias)
    pred = model.predict(test)
    p = np.array([pred[a:b].mean() for a, b in zip(w.start, w.stop, strict=True)])
    assert np.std(p - truth) < max(0.2, 0.1 * np.std(truth)), (model.choice.name, scores)


@pytest.mark.slow
@pytest.mark.parametrize("poly, diag, n_in", [(True, True, 1), (True, False, None),
                                              (False, False, None)])
def test_bias_rows_of_their_own_leave_the_sf_model_as_it_was(poly: bool, diag: bool,
                                                             n_in: int | None) -> None:
    """An SF artifact widened by a bias structure's filters and features (`with_rows`): the
    same sf_ppm bit for bit (with plays, a full or diagonal quadratic, an LSTM reading all
    of z or part), the widened z's first rows the old z, the new rows the own map's z."""
    from fogsf.models import reference, samples
    from fogsf.models.features import FeatureSpec, filter_alpha, physical_normaliser
    from fogsf.models.front_end import FrontEnd
    from fogsf.training.bias.artifact import _widened
    from fogsf.training.bias.features import FeatureMap, with_rows

    sm = samples.random_model(3, 5, 1, 6, 10, seed=7, taus_s=[100.0, 400.0, 1600.0],
                              poly_head=poly, quad_diag=diag, lstm_inputs=n_in,
                              plays=(((0.5, 0.2, 0.3, 0.0), 4.0),))
    w = sm.weights
    fm = FeatureMap(sm.front_end, w["feat_w"], w["feat_b"], 5)
    spec = FeatureSpec((20.0, 300.0), ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.6, 0.0, 0.4)),
                       ("T", "lag(T,20s)", "node(T,300s,w=0.600)"))
    norm = physical_normaliser(spec)
    own_fe = FrontEnd(sm.t_ref_c, sm.t_min_c, sm.t_max_c, sm.decimation, sm.stuck_samples,
                      filter_alpha([20.0, 300.0], sm.decimation, sm.sample_dt_s),
                      sm.sample_dt_s, (20.0, 300.0))
    own = FeatureMap(own_fe, norm.feat_w, norm.feat_b, 3, spec.names)
    wide_fm = with_rows(fm, own)
    wide = _widened(sm, wide_fm)
    assert (wide.n_filters, wide.n_features, wide.n_lstm_inputs) == (5, 8, sm.n_lstm_inputs)
    rng = np.random.default_rng(3)
    temp = (20.0 + np.cumsum(rng.normal(0.0, 0.05, 20000))).astype(np.float32)
    gyro = rng.normal(0.0, 1.0, temp.size)
    a, b = reference.replay(sm, temp, gyro), reference.replay(wide, temp, gyro)
    assert np.array_equal(a.sf_ppm, b.sf_ppm)
    log = ChamberLog(np.arange(temp.size) * sm.sample_dt_s, temp.astype(np.float64),
                     np.zeros(temp.size), gyro, np.ones(temp.size))
    z_old, z_new = fm.z(log), wide_fm.z(log)
    assert np.array_equal(z_new[:, :5], z_old)
    assert np.array_equal(z_new[:, 5:], own.z(log))


# chamber loops (lo, hi C, up, down C/min, soak s) for the reversal logs: a training loop
# and a test loop on another path (those of `make bench-bias`)
TRAIN_LOOP = (-10.0, 50.0, 1.0, 0.7, 1200.0)
TEST_LOOP = (0.0, 40.0, 0.5, 1.5, 900.0)


def reversal_rig_log(path: Path, gyro: int, shupe: float, loop: tuple, seed: int) -> object:
    """A plain rig's reversal log (+/-100 deg/s every 60 s) through a chamber loop, the
    gyro's bias with a Shupe term on its coil: the population gyro's own offset and slope,
    a quadratic of 0.001 deg/h/C^2 and `shupe` deg/h per C/min, on its first coil* node (else
    the population's bias node)."""
    from dataclasses import asdict

    from fogsf.sim.config import BiasConfig
    from fogsf.sim.population import gyro_for_seed
    from fogsf.sim.rigs import chambers, rig_logs
    from fogsf.sim.rigs import protocols as rigs

    cfg = gyro_for_seed(gyro)
    coils = [n.name for n in cfg.thermal.nodes if n.name.startswith("coil")]
    bias = BiasConfig(**{**asdict(cfg.bias), "quad_dph_per_c2": 0.001,
                         "node": coils[0] if coils else cfg.bias.node,
                         "shupe_dph_per_c_per_min": shupe})
    protocol = rigs.reversal_protocol(100.0, 60.0, chamber=chambers.loop(*loop), bias=bias)
    return rig_logs.rig_log("plain", path, protocol, (gyro,), seed=seed)


@pytest.mark.slow
def test_a_shupe_bias_on_reversals_adds_the_coils_filters_to_the_sf_model(
        tmp_path: Path) -> None:
    """Reversal logs (the bias head on the SF model's z): a Shupe term the cubic in T misses
    takes `lead`, its coil node on a filter of its own added after the SF model's; the SF
    the artifact gives is the SF model's bit for bit, the kernel's bias the fit's, and the
    test loop's bias nearer the truth than the same SF model's z alone gives."""
    from fogsf.logs.logio import read_log, with_mapping_beside
    from fogsf.logs.read.dialect import Dialect
    from fogsf.models import reference
    from fogsf.models.stream import StreamModel
    from fogsf.models.structures.lag_bank import bank_spec
    from fogsf.training.bias.features import bank_feature_map

    rl = [reversal_rig_log(tmp_path / n / "log.csv", 3, 2.0, loop, seed)
          for n, loop, seed in (("a", TRAIN_LOOP, 1), ("b", TEST_LOOP, 2))]
    # the SF model the bank (what the filters below count); the rule may take physics nodes
    assert cli.main(["train", "--train", str(rl[0].path), "--structure", "bank",
                     "--out", str(tmp_path / "m")]) == 0
    m = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert m["bias"]["model"]["structure"]["chosen"] == "lead"
    # T and the board's rate (the bank's 60 s lag) from the SF model's z: one filter more
    assert [n.split("(")[0] for n in m["bias"]["model"]["own_features"]] == ["node"]
    assert m["bias"]["model"]["structure"]["node_taus_s"][0] == 60.0
    sm = StreamModel.load(tmp_path / "m")
    taus = list(bank_spec().taus_s)
    assert sm.filter_tau_s[:len(taus)] == taus and len(sm.filter_tau_s) == len(taus) + 1
    assert len(sm.extra["feature_names"]) == sm.n_features == len(taus) + 1 + 1
    # metrics.json and train_info.json describe what the artifact runs
    info = json.loads((tmp_path / "m" / "train_info.json").read_text())
    for d in (m, info):
        assert d["features"] == sm.extra["feature_names"]
        assert d["filter_tau_s"] == sm.filter_tau_s
    test = read_log(rl[1].path, with_mapping_beside(rl[1].path, Dialect()))
    wide = reference.replay(sm, test.temp_c, test.gyro_dps)
    # the SF model alone: the widened rows, filters and bias head taken off again
    k, f = len(taus), len(taus) + 1
    w = {n: a for n, a in sm.weights.items() if not n.startswith("bias_")}
    w["filter_alpha"] = w["filter_alpha"][:k]
    w["feat_w"], w["feat_b"] = w["feat_w"][:f, :1 + k], w["feat_b"][:f]
    for n in ("skip_w", "quad_w", "cube_w"):
        w[n] = w[n][:f]
    alone = replace(sm, weights=w, filter_tau_s=taus, n_features=f, bias_head=False,
                    lstm_inputs=None if sm.n_lstm_inputs == f else sm.n_lstm_inputs,
                    extra={})
    assert np.array_equal(reference.replay(alone, test.temp_c, test.gyro_dps).sf_ppm,
                          wide.sf_ppm)
    # the C kernel (host, through cffi) gives the widened artifact's bias and SF bit for bit
    from kernel_helpers import kernel_for

    n = 20000
    corrected, sf, bias, _ = kernel_for(sm, tmp_path / "k").run_bias(
        test.temp_c[:n].astype(np.float32), test.gyro_dps[:n])
    assert bias.tobytes() == wide.bias_dph[:n].tobytes() and np.ptp(bias) > 0.5
    assert sf.tobytes() == wide.sf_ppm[:n].tobytes()
    train = read_log(rl[0].path, with_mapping_beside(rl[0].path, Dialect()))
    fm = bank_feature_map([train], 5.0)
    ws = bias_windows(test, 100.0)
    assert ws is not None
    truth = rl[1].truth[""].bias_dph

    def err(pred: np.ndarray) -> float:
        return float(np.std([pred[a:b].mean() - truth[a:b].mean()
                             for a, b in zip(ws.start, ws.stop, strict=True)]))

    def sf_of(lg: ChamberLog) -> np.ndarray:  # `train` takes the SF model's off the pairs
        return reference.replay(alone, lg.temp_c, lg.gyro_dps).sf_ppm.astype(np.float64)

    lead = fit_bias(fm, [train], sf_of=sf_of)
    shared = fit_bias(fm, [train], candidates=("cubic", "shupe", "node", "shupe2", "bank"),
                      sf_of=sf_of)
    assert lead is not None and shared is not None and lead.choice.name == "lead"
    assert np.max(np.abs(lead.predict(test) - wide.bias_dph)) < 1e-3
    e_lead, e_shared = err(lead.predict(test)), err(shared.predict(test))
    assert e_lead < 0.8 * e_shared, (e_lead, e_shared)


@pytest.mark.slow
def test_a_model_with_a_play_leaves_lead_out(tmp_path: Path) -> None:
    """The same reversal log with the hysteresis term forced: the bias head does not take
    `lead` (its filter and feature beside the play would overflow the three-model M4F
    image), says so, and the artifact carries the play and no filter of the bias's own."""
    from fogsf.models.stream import StreamModel
    from fogsf.models.structures.lag_bank import bank_spec
    from fogsf.training.bias.fit import LEAD_LEFT_OUT

    log = reversal_rig_log(tmp_path / "a" / "log.csv", 3, 2.0, TRAIN_LOOP, 1)
    assert cli.main(["train", "--train", str(log.path), "--structure", "bank",
                     "--hysteresis", "on", "--out", str(tmp_path / "m")]) == 0
    m = json.loads((tmp_path / "m" / "metrics.json").read_text())
    structure = m["bias"]["model"]["structure"]
    assert structure["chosen"] != "lead" and "lead" not in structure["heldout_rms_dph"]
    assert structure["left_out"] == LEAD_LEFT_OUT
    sm = StreamModel.load(tmp_path / "m")
    assert sm.n_plays == 1 and list(sm.filter_tau_s) == list(bank_spec().taus_s)
    # the bias head reads the play's feature linearly, as the SF model does: the play's row
    # moves to its own state and the feature map is stored as its diagonal
    assert sm.feat_diag and sm.bias_head
    assert not sm.weights["bias_quad_w"][-1] and not sm.weights["bias_cube_w"][-1]


def test_a_bank_with_cross_terms_leaves_lead_out(tmp_path: Path) -> None:
    """Beside the bank's cross terms (a full quadratic) the bias head does not take `lead`
    either (three such models would overflow the M4F image), and says why."""
    from fogsf.logs.logio import read_log, with_mapping_beside
    from fogsf.logs.read.dialect import Dialect
    from fogsf.training.bias.fit import LEAD_LEFT_OUT_CROSS

    rig = reversal_rig_log(tmp_path / "a" / "log.csv", 3, 2.0, TRAIN_LOOP, 1)
    log = read_log(rig.path, with_mapping_beside(rig.path, Dialect()))
    fm = bank_feature_map([log], 5.0)
    kept = fit_bias(fm, [log])
    out = fit_bias(fm, [log], full_quad=True)
    assert kept is not None and "lead" in kept.choice.scores
    assert out is not None and "lead" not in out.choice.scores
    assert out.choice.left_out == LEAD_LEFT_OUT_CROSS


def test_the_choice_message_says_why_lead_was_taken() -> None:
    """`fogsf train`'s line on the bias structure: the rule's reason, and for `lead` taken
    because the cubic in T misses by far, that reason, not 'within 10 %'."""
    from fogsf.training.bias.choice import BiasChoice, choice_message

    scores = {"cubic": 0.805, "shupe": 0.243, "node": 0.216, "lead": 0.343, "bank": 0.336}
    msg = choice_message(BiasChoice("lead", scores, 5, (60.0, 1044.0)).as_dict())
    assert "misses them by 3.7 x the best" in msg and "within" not in msg
    assert "60, 1044 s (the coil's by a grid)" in msg
    flat = {"cubic": 0.101, "shupe": 0.100, "node": 0.099, "lead": 0.1, "bank": 0.12}
    msg = choice_message(BiasChoice("cubic", flat, 5, ()).as_dict())
    assert "the smallest within 10 % of the best" in msg and "misses" not in msg


@pytest.mark.slow
def test_train_takes_the_sf_models_prediction_off_a_staircases_pairs(tmp_path: Path) -> None:
    """A rate staircase through a ramp: the SF (linear in T here) moves between the two
    plateaus of each pair, and a staircase pair has no neighbour at its own rate to cancel
    it, so the pairs alone read up to ~0.5 deg/h of it as bias. `train` takes the SF model's
    prediction off the plateaus first: the constant bias it then measures (metrics.json,
    before) is flat, and the bias model has little to model."""
    from fogsf.logs.measure.pairs import find_pairs

    dt, per = 0.1, 160
    stair = [s * 4.0 * k for k in range(1, 26) for s in (1.0, -1.0)]
    cmd = np.repeat(stair * 6, per)
    n = cmd.size
    t = np.arange(n) * dt
    temp = 0.0 + 40.0 * np.abs(((t / (n * dt)) * 2.0) % 2.0 - 1.0)  # 0 -> 40 -> 0 C, 1 C/min
    temp = 40.0 - temp
    sf = 150.0 + 10.0 * (temp - 20.0)  # ppm: 10 ppm/C x 1 C/min is 2.7 ppm in 16 s
    rng = np.random.default_rng(5)
    gyro = (cmd * (1 + sf * 1e-6) + 1.0 / 3600.0 + EARTH_DPS
            + rng.normal(0.0, 1e-5, n))
    log = ChamberLog(t, temp, cmd, gyro, np.full(n, EARTH_DPS))
    path = tmp_path / "stair.csv"
    write_log(path, log)
    pp = find_pairs(log)
    assert pp is not None and np.std(pp.bias_dps * 3600.0) > 0.1  # the drift, read as bias
    assert cli.main(["train", "--train", str(path), "--out", str(tmp_path / "m")]) == 0
    m = json.loads((tmp_path / "m" / "metrics.json").read_text())
    before, after = m["bias"]["train"]["log0"]["before"], m["bias"]["train"]["log0"]["after"]
    assert before["std_dph"] < 0.03, before
    assert abs(before["rms_dph"] - 1.0) < 0.03  # the constant bias, 1 deg/h
    assert after["std_dph"] < 0.03 and after["rms_dph"] < 0.03, after  # the model fitted it


@pytest.mark.slow
def test_a_stationary_logs_partial_last_step_is_no_target() -> None:
    """A log one sample longer than whole steps: that sample's step is no target (a mean of
    one sample holds its noise alone; it set every held-out score before)."""
    log, _ = soak_log(TRAIN, 7)
    n = len(log)
    assert n % 50 == 0  # whole 5 s steps at 10 Hz
    longer = ChamberLog(np.append(log.time_s, log.time_s[-1] + 0.1),
                        np.append(log.temp_c, log.temp_c[-1]), np.zeros(n + 1),
                        np.append(log.gyro_dps, log.gyro_dps[-1] + 15.0 / 3600.0),
                        np.full(n + 1, EARTH_DPS))
    a, b = fit_bias(None, [log]), fit_bias(None, [longer])
    assert a is not None and b is not None and b.n_targets == a.n_targets
    for name, score in a.choice.scores.items():
        assert b.choice.scores[name] == pytest.approx(score, rel=1e-6), name


def test_train_knows_before_the_fit_whether_the_logs_measure_the_bias() -> None:
    """`train.measures_bias` (what leaves the bank's cross terms out beside a play and a
    bias head): a stationary log measures the bias, a turning log without pairs does not."""
    from fogsf.training.options import TrainOptions
    from fogsf.training.sf.fit import measures_bias

    log, _ = soak_log(TRAIN, 5)
    turning = ChamberLog(log.time_s, log.temp_c, np.full_like(log.time_s, 10.0),
                         log.gyro_dps + 10.0, log.earth_rate_dps)
    opts = TrainOptions(model="lag-lstm")
    assert measures_bias(opts, [log]) and measures_bias(opts, [turning, log])
    assert not measures_bias(opts, [turning])


@pytest.mark.slow
def test_the_bias_interval_spans_the_coil_time_constants_the_pairs_leave_open() -> None:
    """With `lead` chosen, the interval refits it at the grid points of its time constants
    that the training targets cannot tell from the best (`bias_structure.lead_set`): the
    chosen fit first; their spread from the model larger on a log that ramps three times
    faster than training (the Shupe term extrapolated) than on one at the training's rate,
    and the interval's top wider for it there."""
    from dataclasses import replace as dc_replace

    from fogsf.training.bias.interval import bias_interval
    from fogsf.training.bias.structure import LEAD_SET_MOST

    train, _ = soak_log(TRAIN, 41)
    model = fit_bias(None, [train])
    assert model is not None and model.choice.name == "lead"
    fam = model.family
    chosen, first = fam.fits["lead"], fam.lead_set[0]
    assert (first.taus_s, first.w) == (chosen.taus_s, chosen.w)
    assert np.array_equal(first.coef, chosen.coef)
    assert 2 <= len(fam.lead_set) <= LEAD_SET_MOST
    slow, _ = soak_log(TEST, 42)
    fast, _ = soak_log([(0, 15), (900, 15), (1300, 35), (2500, 35), (2800, 20), (4000, 20)],
                       43)
    spreads, tops = [], []
    for lg in (slow, fast):
        pred = model.predict(lg)
        iv = bias_interval(fam, lg, pred)
        bare = bias_interval(dc_replace(fam, lead_set=[]), lg, pred)
        assert iv is not None and bare is not None and bare["lead_region"] is None
        region = iv["lead_region"]
        assert region["points"] == len(fam.lead_set)
        assert region["tau_s"][0] <= chosen.taus_s[1] <= region["tau_s"][1]
        spreads.append(region["spread_dph"])
        tops.append((bare["rms_interval_dph"][1], iv["rms_interval_dph"][1]))
    assert spreads[1] > 1.5 * spreads[0], spreads
    assert tops[1][1] > tops[1][0], tops  # the fast log's top takes the set's spread


def test_the_lead_set_holds_the_points_within_the_allowance() -> None:
    """`lead_set` on a lead-law bias with noise: its first fit is the profile's minimum (as
    the lead candidate fits it), each fit's training SSE lies within LEAD_SET_CHI2 x sigma2
    of that minimum, and a larger sigma2 admits at least as many points."""
    from fogsf.models.structures.physics_nodes import NodeTemperatures
    from fogsf.training.bias import structure as bs

    step = 5.0
    t = np.concatenate([np.linspace(-0.6, 0.6, 1500), np.full(300, 0.6),
                        np.linspace(0.6, -0.6, 700), np.full(300, -0.6)]) * 50.0
    nodes = NodeTemperatures([t], step)
    cols = bs.Columns(nodes.z(())[:, 0], nodes.lag, None, nodes.z((60.0,)), 1)
    c = bs.lead_node(cols.t, cols.lag(600.0), 0.3)
    rate = bs.lead_rate(cols.t, cols.lag(bs.LEAD_FAST_S), c, (bs.LEAD_FAST_S, 600.0), 0.3)
    rng = np.random.default_rng(5)
    y = 0.5 + 0.4 * c + 3.0 * rate + rng.normal(0.0, 0.05, t.size)
    sse_min = float(np.min(bs.lead_profile(cols, np.arange(y.size), y)))
    fits = bs.lead_set(cols, y, 0.05 ** 2)
    best = bs.fit_candidate("lead", cols, np.arange(y.size), y)
    assert (fits[0].taus_s, fits[0].w) == (best.taus_s, best.w)
    for f in fits:
        sse = float(np.sum((y - f.predict(cols)) ** 2))
        assert sse <= sse_min + bs.LEAD_SET_CHI2 * 0.05 ** 2 + 1e-9 * sse_min, (f.taus_s, f.w)
    wide = bs.lead_set(cols, y, 0.5 ** 2, most=10_000)
    narrow = bs.lead_set(cols, y, 0.05 ** 2, most=10_000)
    assert len(wide) > len(narrow) >= 1
