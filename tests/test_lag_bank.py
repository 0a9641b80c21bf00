"""The lag bank (the default model's structure)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from ramp_logs import short_ramp

from fogsf.models.stream import StreamModel
from fogsf.models.structures.lag_bank import BANK_LSTM_INPUTS, CURVED_MAX_TAU_S, bank_spec, fit_bank
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.training.options import TrainOptions
from fogsf.training.train import run_training

FAST = {"iters": 30, "hidden": 8, "layers": 1, "batch_size": 8}


def test_bank_spec_is_t_and_every_grid_lag() -> None:
    spec = bank_spec()
    assert spec.taus_s == TAU_GRID_S and spec.n_features == 1 + len(TAU_GRID_S)
    assert np.array_equal(spec.matrix(), np.eye(1 + len(TAU_GRID_S)))


def test_ridge_recovers_an_additive_cubic() -> None:
    rng = np.random.default_rng(0)
    z = rng.uniform(-1, 1, (4000, 3))
    truth = 0.3 + z @ [1.0, -0.5, 0.0] + (z * z) @ [0.0, 0.4, 0.0] + z[:, 2] ** 3 * 0.7
    fit = fit_bank(z, truth + rng.normal(0, 0.01, z.shape[0]), lam=1e-6)
    assert np.allclose(fit.predict(z), truth, atol=0.01)
    assert np.allclose(fit.lin, [1.0, -0.5, 0.0], atol=0.03)
    assert fit.cube[2] == pytest.approx(0.7, abs=0.05)
    strong = fit_bank(z, truth, lam=10.0)  # a heavy prior shrinks towards the mean
    assert strong.dof < fit.dof and np.abs(strong.lin).sum() < np.abs(fit.lin).sum()


@pytest.fixture(scope="module")
def two_rates_gyro() -> dict:
    # population gyro 2 (development range): a chain whose single effective node left 6 x
    # the floor at 1 C/min after 0.5 + 2 C/min training on the full bench
    return {"slow": short_ramp(0.6, 31, gyro_seed=2), "fast": short_ramp(2.4, 32, gyro_seed=2),
            "mid": short_ramp(1.2, 33, gyro_seed=2)}


@pytest.mark.slow
def test_bank_transfers_between_two_rates_where_one_node_does_not(two_rates_gyro,
                                                                  tmp_path: Path) -> None:
    logs = two_rates_gyro
    res = {}
    for structure in ("bank", "node"):
        opts = TrainOptions(model="lag-lstm", structure=structure, progress=False, **FAST)
        m, _ = run_training(opts, [logs["slow"], logs["fast"]], logs["mid"],
                            tmp_path / structure)
        res[structure] = m["test"]["after"]["rms_ppm"] / m["noise_floor_ppm"]
    assert res["bank"] < 1.5, res
    assert res["bank"] < 0.7 * res["node"], res


def test_bank_artifact_carries_the_fixed_bank(two_rates_gyro, tmp_path: Path) -> None:
    logs = two_rates_gyro
    opts = TrainOptions(model="lag-lstm", structure="bank", progress=False, **FAST)
    m, fitted = run_training(opts, [logs["slow"], logs["fast"]], logs["mid"], tmp_path / "b")
    sm = StreamModel.load(tmp_path / "b")
    f = 1 + len(TAU_GRID_S)
    assert sm.poly_head and sm.n_features == f and m["features"][0] == "T"
    # no cross terms (an additive bank): the head holds the diagonal only, quad_w [F]
    assert sm.quad_diag and sm.weights["quad_w"].shape == (f,)
    quad = sm.weights["quad_w"]
    # the LSTM reads the first BANK_LSTM_INPUTS features (T first): 4H x N input weights
    assert sm.n_lstm_inputs == BANK_LSTM_INPUTS < f
    assert sm.weights["lstm0_w"].shape == (4 * FAST["hidden"], BANK_LSTM_INPUTS)
    slow = 1 + np.flatnonzero(np.asarray(TAU_GRID_S) > CURVED_MAX_TAU_S)
    assert slow.size and not sm.weights["cube_w"][slow].any() and not quad[slow].any()
    assert quad[0] != 0  # T's square
    assert sm.weights["cube_w"][0] != 0  # T itself is curved
    # the feature map (T and the lags over 50 C) is diagonal: stored as its diagonal
    assert sm.feat_diag and np.allclose(sm.weights["feat_w"], np.full(f, 1 / 50.0))
    assert fitted.info["lag_bank"]["dof"] > 2
    lo, hi = m["rate_transfer"]["rms_interval_ppm"]
    assert lo < m["rate_transfer"]["noise_floor_ppm"] < hi


def test_lstm_inputs_option(two_rates_gyro, tmp_path: Path) -> None:
    """--lstm-inputs N narrows the bank's LSTM to z[0:N] (N = F: every feature); outside
    1..F, or for another structure, it is refused."""
    from fogsf.errors import UserError
    from fogsf.training.sf.fit import fit_sf

    logs = [two_rates_gyro["slow"], two_rates_gyro["fast"]]
    f = 1 + len(TAU_GRID_S)
    for n_in in (3, f):
        opts = TrainOptions(model="lag-lstm", structure="bank", progress=False,
                            lstm_inputs=n_in, **FAST)
        run_training(opts, logs, None, tmp_path / str(n_in))
        sm = StreamModel.load(tmp_path / str(n_in))
        assert sm.n_lstm_inputs == n_in and sm.weights["lstm0_w"].shape[1] == n_in
        assert sm.lstm_inputs_narrowed == (n_in < f) and sm.quad_diag
    for bad in (0, f + 1):
        with pytest.raises(UserError, match="--lstm-inputs must lie in 1..12"):
            fit_sf(TrainOptions(model="lag-lstm", structure="bank", lstm_inputs=bad, **FAST),
                      logs)
    with pytest.raises(UserError, match="--lstm-inputs narrows the LSTM"):
        fit_sf(TrainOptions(model="lag-lstm", structure="node", lstm_inputs=1), logs)


@pytest.mark.slow
def test_train_cli_structure_option(two_rates_gyro, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    import json

    from fogsf.cli.main import main
    from fogsf.logs.writer import write_log

    paths = {}
    for k, lg in two_rates_gyro.items():
        paths[k] = tmp_path / f"{k}.csv"
        write_log(paths[k], lg)
    common = ["train", "--train", str(paths["slow"]), "--train", str(paths["fast"]),
              "--test", str(paths["mid"]), "--iters", "5", "--hidden", "4", "--no-progress"]
    assert main([*common, "--structure", "bank", "--out", str(tmp_path / "bank")]) == 0
    assert main([*common, "--structure", "node", "--out", str(tmp_path / "node")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "Expected RMS error on the target" in out
    assert "held-out prediction" not in out  # a structure given is not chosen
    assert main([*common, "--out", str(tmp_path / "auto")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    auto = json.loads((tmp_path / "auto" / "metrics.json").read_text())
    choice = auto["structure_choice"]
    # two ramps, and one: the default scores every candidate on held-out parts and says
    # which it chose and why
    assert choice["segments"] == 2 and not choice["one_segment"]
    assert set(choice["heldout_rms_ppm"]) == {"physics1", "physics2", "physics3", "bank"}
    assert f"structure {choice['chosen']}, chosen by held-out prediction" in out
    assert "(2 ramps, each in 3 parts;" in out
    if choice["chosen"] == "bank":
        assert len(auto["features"]) == 1 + len(TAU_GRID_S)
    else:  # T and one lag per physics node
        assert len(auto["features"]) == 1 + int(choice["chosen"].removeprefix("physics"))
    assert main([*common[:3], *common[5:], "--out", str(tmp_path / "one")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    one = json.loads((tmp_path / "one" / "metrics.json").read_text())["structure_choice"]
    assert f"structure {one['chosen']}, chosen by held-out prediction" in out
    assert set(one["heldout_rms_ppm"]) == {"physics1", "physics2", "physics3", "bank"}
    assert one["segments"] == 3 and one["one_segment"]
    bank = json.loads((tmp_path / "bank" / "metrics.json").read_text())
    node = json.loads((tmp_path / "node" / "metrics.json").read_text())
    assert bank["features"][0] == "T" and len(bank["features"]) == 1 + len(TAU_GRID_S)
    assert len(node["features"]) == 1 and node["features"][0].startswith("T_eff")
    # the board's rate: this gyro's board lags ~10 min, so on a 25 min ramp at 2.4 C/min
    # it never reaches the chamber's rate
    assert bank["train_ramp_rates_c_per_min"] == [pytest.approx(0.6, rel=0.05),
                                                  pytest.approx(2.2, rel=0.15)]


@pytest.mark.slow
def test_default_model_same_seed_same_header_bytes(two_rates_gyro, tmp_path: Path) -> None:
    """The default model (its structure chosen by the logs, its LSTM narrowed): the same seed
    gives the same artifact and the same generated C, byte for byte; another seed another
    model."""
    from fogsf.export.header import render_model

    logs = [two_rates_gyro["slow"], two_rates_gyro["fast"]]
    texts, ids = [], []
    for run, seed in (("a", 4), ("b", 4), ("c", 5)):
        run_training(TrainOptions(model="lag-lstm", progress=False, seed=seed, **FAST), logs,
                     None, tmp_path / run)
        sm = StreamModel.load(tmp_path / run)
        assert sm.lstm_inputs_narrowed
        texts.append(render_model(sm, "imu_x"))
        ids.append(sm.model_id)
    assert texts[0] == texts[1] and ids[0] == ids[1]
    assert ids[2] != ids[0] and texts[2] != texts[0]


def test_cross_terms_are_fitted_and_predicted_as_the_firmware_quadratic() -> None:
    """With `cross`, the bank's quadratic is the upper-triangular [F, F] of z^T quad z over the
    curved features: a planted cross term is recovered and the prediction is the design's."""
    from fogsf.models.structures.lag_bank import bank_design, n_curved

    rng = np.random.default_rng(3)
    k, c = 12, n_curved()
    z = rng.normal(size=(3000, k)) * 0.5
    truth = 0.5 * z[:, 0] - 0.7 * z[:, 2] * z[:, 5] + 0.3 * z[:, 1] ** 2
    fit = fit_bank(z, truth + rng.normal(0, 0.01, z.shape[0]), lam=1e-6, curved=c, cross=True)
    assert fit.quad.shape == (k, k) and np.allclose(np.tril(fit.quad, -1), 0.0)
    assert fit.quad[2, 5] == pytest.approx(-0.7, abs=0.02)
    assert fit.quad[1, 1] == pytest.approx(0.3, abs=0.02)
    q32 = fit.quad.astype(np.float32)
    assert np.allclose(fit.predict(z), fit.intercept + z @ fit.lin
                       + np.einsum("ni,ij,nj->n", z, q32.astype(np.float64), z)
                       + (z ** 3) @ fit.cube, atol=1e-5)
    assert bank_design(z, c, cross=True).shape[1] == k + 2 * c + c * (c - 1) // 2
    plain = fit_bank(z, truth, lam=1e-6, curved=c)
    assert plain.quad.shape == (k,)
