"""The trainer's hysteresis term: the play column, its choice, the held-out check, and a
trained model with a play carried by the C kernel bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_helpers import kernel_for

from fogsf.models import reference
from fogsf.models.features import front_end_for, physical_normaliser
from fogsf.models.structures.hysteresis import (
    HystTerm,
    _sse_batch,
    choose_term,
    column,
    ridge_fit_free,
    spec_with_play,
    term_column,
)
from fogsf.models.structures.lag_bank import bank_penalty, bank_spec
from fogsf.models.structures.node_fit import discrete_lag, lag_alpha
from fogsf.sim import simulate
from fogsf.sim.config import EffectConfig
from fogsf.sim.effects import play_operator
from fogsf.sim.partial_cycles import PartialCycle
from fogsf.sim.population import gyro_for_seed, run_on_gyro
from fogsf.training.options import TrainOptions
from fogsf.training.structure.hysteresis import decide, has_reversal
from fogsf.training.train import run_training

STEP_S = 5.0


def _path() -> np.ndarray:
    """A partial-cycle board temperature at 5 s steps (C, relative to 20 C)."""
    legs = [(-30.0, 0.0), (20.0, 1.5), (0.0, 1.0), (30.0, 2.0), (5.0, 0.75), (-30.0, 1.5)]
    out = [np.full(120, legs[0][0])]
    for (a, _), (b, rate) in zip(legs[:-1], legs[1:], strict=True):
        n = int(abs(b - a) / rate * 60.0 / STEP_S)
        out += [np.linspace(a, b, n + 1)[1:], np.full(180, b)]
    return np.concatenate(out)


def test_sse_batch_equals_the_single_fits() -> None:
    rng = np.random.default_rng(0)
    x, y, hs = rng.normal(size=(400, 7)), rng.normal(size=400), rng.normal(size=(400, 5))
    got = _sse_batch(x, hs, y, 1e-3, 3)
    for m in range(5):
        xx = x.copy()
        xx[:, 3] = hs[:, m]
        assert abs(got[m] - ridge_fit_free(xx, y, 1e-3, [3]).sse) < 1e-8 * got[m]


def test_choose_term_finds_a_planted_play_of_a_lag() -> None:
    t = _path()
    rng = np.random.default_rng(1)
    taus = (60.0, 600.0, 2000.0)
    lags = {0.0: [t]} | {tau: [discrete_lag(t, lag_alpha(tau, STEP_S))] for tau in taus}
    k_true, w_true = 6.0, 7.0
    x = lags[600.0][0]
    y = 3.0 * t + 0.02 * t * t + k_true * (play_operator(x, w_true) - x) \
        + rng.normal(0.0, 2.0, t.size)
    z = np.column_stack([t] + [lags[tau][0] for tau in taus]) / 50.0

    def design(h: np.ndarray) -> np.ndarray:
        return np.column_stack([z, z[:, :1] ** 2, h])

    rows = np.arange(t.size)
    term, fit = choose_term(design, y, rows, lags, 1e-4, 5)
    assert abs(term.width_c - w_true) <= 1.0, term
    assert abs(fit.coef[5] / 50.0 - k_true) <= 0.15 * k_true, term
    # the column of the chosen term is what term_column gives
    np.testing.assert_allclose(design(term_column(lags, term))[:, 5],
                               term_column(lags, term))


def test_spec_with_play_feature_is_the_play_minus_its_source() -> None:
    """Through the float32 front end, the appended feature is (play(x) - x) / 50 C."""
    log = simulate(_partial_run(0)).log
    term = HystTerm(0.0, 407.0, 0.5, 6.0)
    spec = spec_with_play(bank_spec(), term)
    fe = front_end_for([log], STEP_S, spec.taus_s, plays=spec.plays)
    s = reference.frontend(log.temp_c, fe).s
    feat = (s.astype(np.float64) @ physical_normaliser(spec).feat_w.T.astype(np.float64))[:, -1]
    tm = s[:, 0].astype(np.float64)
    src = 0.5 * tm + 0.5 * s[:, 1 + spec.taus_s.index(407.0)].astype(np.float64)
    np.testing.assert_allclose(feat, column([src], 6.0), atol=2e-5)


def _partial_run(seed: int, hyst: bool = True, gyro_seed: int = 17):  # noqa: ANN202
    prog = PartialCycle("short", (-30.0, 20.0, 0.0, 35.0, 5.0, -30.0), (2.0, 1.0), 900.0,
                        900.0)
    gyro = gyro_for_seed(gyro_seed, hysteresis=False)
    if hyst:
        gyro.effects = [EffectConfig("hysteresis", 8.0, {"width_c": 8.0})]
    cfg = run_on_gyro(gyro, prog.profile(), seed, "short")
    cfg.dt_s = 1.0
    return cfg


def test_reversals_and_the_check() -> None:
    t = _path()
    assert has_reversal([t]) and not has_reversal([np.linspace(-30, 30, 500)])
    ramp = simulate(run_on_gyro(gyro_for_seed(5), _ramp(), 1, "ramp")).log
    d = decide([ramp], "bank", STEP_S)
    assert d["used"] is False and d["reason"] == "no reversal in the training logs"
    assert decide([ramp], "bank", STEP_S, mode="on")["used"] is True


def _ramp():  # noqa: ANN202
    from fogsf.sim.config import ProfileConfig

    return ProfileConfig(kind="ramp", start_c=-20.0, stop_c=40.0, rate_c_per_min=2.0)


# The model step of the trained play model: 10 s, not the default 5, halves the steps of
# every held-out fit of the choice, the penalty walk and the cross terms' second look
# (20 s -> 7 s); on seeds 1/2, 3/4 and 5/6 each takes the penalty, the cross terms and their
# verdict that 5 s steps take (here: the cross terms better on 12, then 13, of the 15 parts,
# 10 needed; with the play in, on 8), and the play cuts the bank's test RMS by the same
# 23-27 % (20 % needed).
PLAY_MODEL_STEP_S = 10.0


@pytest.mark.slow
def test_trained_play_model_runs_bit_for_bit_in_c(tmp_path) -> None:
    train = simulate(_partial_run(1)).log
    test = simulate(_partial_run(2)).log
    opts = TrainOptions(model="lag-lstm", seed=0, progress=False, workers=1, iters=5,
                        transfer_check=False, hysteresis="on", model_step_s=PLAY_MODEL_STEP_S)
    m, fitted = run_training(opts, [train], test, tmp_path / "m")
    sm = fitted.stream_model
    assert sm is not None and sm.n_plays == 1 and m["hysteresis_choice"]["used"]
    assert m["hysteresis_choice"]["term"]["width_c"] > 0
    kern = kernel_for(sm, tmp_path)
    _, sf, _ = kern.run(test.temp_c, test.gyro_dps)
    ref = reference.replay(sm, test.temp_c, test.gyro_dps)
    assert np.array_equal(sf.view(np.uint32), ref.sf_ppm.view(np.uint32))
    # its 15 held-out parts took the bank's cross terms; judged again with the play in, they
    # predicted too few parts better: the bank the penalty walk reached, and train says so
    c = m["structure_choice"]
    assert c["bank_penalty"]["cross_terms"] and not c["cross_with_term"]["kept"]
    assert c["cross_left_out"].startswith("with the hysteresis term they predicted")
    assert sm.quad_diag and fitted.info["lag_bank"]["ridge_lambda"] == bank_penalty(
        c["bank_penalty"]["without_cross_terms"])
    assert sm.feat_diag  # the bank's feature map, stored as its diagonal

    def bank_at_prior(mode: str) -> float:
        o = TrainOptions(model="lag-lstm", seed=0, progress=False, workers=1, iters=5,
                         transfer_check=False, hysteresis=mode, structure="bank",
                         model_step_s=PLAY_MODEL_STEP_S)
        return run_training(o, [train], test, tmp_path / mode)[0]["test"]["after"]["rms_ppm"]

    # an 8 ppm/C, 8 C play: the term takes most of what the bank without it leaves (the
    # bank at its prior: the cross terms mimic part of a play inside one program)
    on, off = bank_at_prior("on"), bank_at_prior("off")
    assert on < 0.8 * off
    assert m["test"]["after"]["rms_ppm"] < off


@pytest.mark.slow
def test_the_check_is_the_default(tmp_path) -> None:
    """`fogsf train` without --hysteresis on the docs' example (development gyro 17, 5.7
    ppm/C, 9 C wide, on the partial-cycle program): the check runs and keeps the term."""
    import json

    from fogsf.cli.main import main

    assert TrainOptions(model="lag-lstm").hysteresis == "auto"
    log = tmp_path / "train.csv"
    # at 1 Hz, not the docs' 10 Hz: the choice and the check score 5 s model steps either
    # way, a tenth of the samples to write, read and replay, and the penalty walk keeps the
    # prior here, so no second look at cross terms (a sixth of the time): the check keeps the
    # term by a margin (held-out RMS 10.2 ppm with it, 14.7 without; the 10 Hz log's 10.0 and
    # 17.9; seeds 4-7 at 1 Hz 23-45 % lower, where 10 % is needed)
    assert main(["simulate", "--scenario", "partial", "--random-gyro", "17", "--seed", "3",
                 "--sample-rate-hz", "1", "--out", str(log)]) == 0
    assert main(["train", "--train", str(log), "--out", str(tmp_path / "m"), "--iters", "5",
                 "--no-progress"]) == 0
    choice = json.loads((tmp_path / "m" / "metrics.json").read_text())["hysteresis_choice"]
    assert choice["mode"] == "auto" and choice["used"], choice
    assert json.loads((tmp_path / "m" / "stream.json").read_text()).get("play_width_c"), \
        "the artifact carries no play"


def test_long_logs_are_checked_at_the_choice_step(monkeypatch) -> None:
    from fogsf.training.sf import fit as sf_fit
    from fogsf.training.structure import heldout as structure_heldout
    from fogsf.training.structure import hysteresis as hysteresis_choice

    seen: list[float] = []
    monkeypatch.setattr(structure_heldout, "MAX_CHOICE_STEPS", 100)
    monkeypatch.setattr(hysteresis_choice, "decide",
                        lambda logs, base, step_s, lat, mode: seen.append(step_s) or {})
    log = simulate(_partial_run(1)).log
    sf_fit.hysteresis_choice(TrainOptions(model="lag-lstm"), [log], "bank")
    want = structure_heldout.choice_step_s([log], TrainOptions(model="lag-lstm").model_step_s)
    assert want > 5.0 and seen == [want]


@pytest.mark.slow
def test_cross_terms_are_left_out_beside_a_play_and_a_bias_head(tmp_path, monkeypatch) -> None:  # noqa: ANN001
    """Logs that measure the bias give the model a bias head: with a play as well, the bank
    keeps its diagonal quadratic (three such models with the full one would not fit 24 KB),
    and `fogsf train` says so."""
    from fogsf.cli.train import format_metrics
    from fogsf.training.sf import fit as sf_fit

    monkeypatch.setattr(sf_fit, "measures_bias", lambda opts, logs: True)
    train = simulate(_partial_run(1)).log
    opts = TrainOptions(model="lag-lstm", seed=0, progress=False, workers=1, iters=5,
                        transfer_check=False, hysteresis="on")
    m, fitted = run_training(opts, [train], None, tmp_path / "m")
    c = m["structure_choice"]
    assert c["bank_penalty"]["cross_terms"] and "24 KB" in c["cross_left_out"]
    # trained as the bank the penalty walk reached without the cross terms
    plain = c["bank_penalty"]["without_cross_terms"]
    assert fitted.info["lag_bank"]["ridge_lambda"] == bank_penalty(plain)
    assert not fitted.info["lag_bank"]["cross_terms"]
    sm = fitted.stream_model
    assert sm is not None and sm.n_plays == 1 and sm.quad_diag and sm.feat_diag
    assert "the cross terms left out: with a play and a bias head" in \
        format_metrics(m).replace("\n", " ")
