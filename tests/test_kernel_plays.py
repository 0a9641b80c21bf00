"""Play (backlash) operators in the front end: the C kernel equals the numpy reference bit
for bit, the operator does what the contract says, and a model without plays keeps its
bytes and id."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from kernel_helpers import kernel_for

from fogsf.bindings.firmware import golden_inputs, state_bytes
from fogsf.errors import UserError
from fogsf.export.header import render_model
from fogsf.models import reference, samples
from fogsf.models import stream as st
from fogsf.models.stream_format import CONFIG_FILE, PLAY_SOURCE_KEY, PLAY_WIDTH_KEY
from fogsf.models.stream_forms import diagonal_features, pure_play_rows

# (K filters, F features, D decimation, seed, plays ((source weights, width_c), ...), poly
# [, feat_diag])
PLAY_SIZES = [(3, 4, 10, 20, (((1.0, 0.0, 0.0, 0.0), 6.0),), True),
              (2, 5, 7, 21, (((0.0, 0.0, 1.0), 3.5), ((0.3, 0.45, 0.25), 9.25)), False),
              (1, 2, 1, 22, (((0.0, 1.0), 0.0),), True), (0, 2, 50, 23, (((1.0,), 12.0),), False),
              (2, 5, 5, 25, (((0.0, 1.0, 0.0), 4.0), ((0.5, 0.0, 0.5), 2.0)), True, True)]


@pytest.fixture(scope="session")
def kroot(tmp_path_factory):
    return tmp_path_factory.mktemp("kernels-plays")


def model_of(size: tuple) -> st.StreamModel:
    k, f, d, seed, plays, poly, *fdiag = size
    return samples.random_model(k, f, 1, 8, d, seed=seed, poly_head=poly, plays=plays,
                                feat_diag=bool(fdiag and fdiag[0]))


@pytest.mark.slow
@pytest.mark.parametrize("size", PLAY_SIZES)
def test_kernel_with_plays_equals_reference_bit_for_bit(size, kroot) -> None:
    model = model_of(size)
    kernel = kernel_for(model, kroot)
    temp, gyro = golden_inputs(model, n=3000, seed=size[3])
    # a slow triangle on top, so the plays stick and slide many times
    temp = temp + 15.0 * np.abs(((np.arange(temp.size) / 400.0) % 2.0) - 1.0)
    corrected, sf, flags = kernel.run(temp, gyro)
    ref = reference.replay(model, temp, gyro)
    bad = np.flatnonzero(sf.view(np.uint32) != ref.sf_ppm.view(np.uint32))
    assert bad.size == 0, f"seed {size[3]}: sf differs at samples {bad[:20].tolist()}"
    np.testing.assert_array_equal(corrected.view(np.uint64), ref.corrected_dps.view(np.uint64))
    np.testing.assert_array_equal(flags, ref.flags)


def test_play_column_is_the_backlash_of_its_source() -> None:
    model = model_of(PLAY_SIZES[0])
    fe = model.front_end
    temp = np.concatenate([np.linspace(0, 20, 2001), np.linspace(20, 15, 501)[1:],
                           np.full(500, 15.0), np.linspace(15, 30, 1501)[1:]])
    out = reference.frontend(temp, fe)
    tm = out.s[:, 0].astype(np.float64)
    p = out.s[:, 1 + model.n_filters].astype(np.float64)
    assert np.all(np.abs(p - tm) <= 3.0 + 1e-5)  # width 6: within +-3 of its source
    top = int(np.argmax(tm[:tm.size // 2]))  # the first turn, at 20 C
    assert abs((tm[top] - p[top]) - 3.0) < 1e-4  # trailing by half the width going up
    # back down by 5 C (less than the width) and a soak: the play holds its value
    held = p[top:top + 100]
    assert held.size == 100 and np.ptp(held) == 0.0 and np.ptp(tm[top:top + 100]) >= 4.9


def test_plays_enter_config_and_id_only_when_present(tmp_path) -> None:
    plain = samples.random_model(2, 3, 1, 8, 10, seed=5)
    played = model_of(PLAY_SIZES[1])
    assert PLAY_WIDTH_KEY not in plain.config()
    assert played.config()[PLAY_WIDTH_KEY] == [3.5, 9.25]
    assert played.config()[PLAY_SOURCE_KEY] == [[0.0, 0.0, 1.0], [0.3, 0.45, 0.25]]
    played.save(tmp_path / "m")
    back = st.StreamModel.load(tmp_path / "m")
    assert back.model_id == played.model_id and back.play_source_w == played.play_source_w
    files = render_model(played, "imu_p")
    assert "#define IMU_P_N_PLAYS 2" in files["imu_p.h"]
    assert "play_half_c, play_source_w" in files["imu_p.c"]
    plain_files = render_model(plain, "imu_q")
    assert "PLAYS" not in plain_files["imu_q.h"] and "play" not in plain_files["imu_q.c"]
    assert state_bytes(played) == state_bytes([plain, played])


@pytest.mark.parametrize("bad", [{"play_width_c": [-1.0], "play_source_w": [[1, 0, 0]]},
                                 {"play_width_c": [2.0], "play_source_w": [[1, 0]]},
                                 {"play_width_c": [2.0], "play_source_w": [[1, "x", 0]]},
                                 {"play_width_c": [2.0, 3.0], "play_source_w": [[1, 0, 0]]}])
def test_bad_plays_are_refused(tmp_path, bad) -> None:
    model = samples.random_model(2, 3, 1, 8, 10, seed=5)
    model.save(tmp_path / "m")
    cfg = json.loads((tmp_path / "m" / CONFIG_FILE).read_text())
    cfg.update(bad)
    (tmp_path / "m" / CONFIG_FILE).write_text(json.dumps(cfg))
    with pytest.raises(UserError):
        st.StreamModel.load(tmp_path / "m")


@pytest.mark.parametrize("feat_diag", [False, True], ids=["full-feat-w", "feat-diag"])
def test_plays_with_a_bias_head_bit_for_bit(feat_diag, kroot) -> None:
    model = samples.random_model(2, 3 + feat_diag, 1, 8, 10, seed=24, poly_head=True,
                                 bias_head=True, plays=(((0.5, 0.5, 0.0), 5.0),),
                                 feat_diag=feat_diag)
    kernel = kernel_for(model, kroot)
    temp, gyro = golden_inputs(model, n=3000, seed=24)
    temp = temp + 15.0 * np.abs(((np.arange(temp.size) / 400.0) % 2.0) - 1.0)
    out = kernel.run_bias(temp, gyro)
    ref = reference.replay(model, temp, gyro)
    np.testing.assert_array_equal(out[0].view(np.uint64), ref.corrected_dps.view(np.uint64))
    np.testing.assert_array_equal(out[1].view(np.uint32), ref.sf_ppm.view(np.uint32))
    np.testing.assert_array_equal(out[2].view(np.uint32), ref.bias_dph.view(np.uint32))


def _hysteresis_term_model(seed: int = 26, quad_diag: bool = False, n_plays: int = 1
                           ) -> st.StreamModel:
    """A model shaped as the trainer's bank with play terms: T and two lags on their own
    rows, each play's row play(x) - x (x a mix of the lags), the play features linear only
    (no quadratic, cube or LSTM input), a bias head."""
    plays = (((0.0, 0.5, 0.5), 5.0), ((0.0, 0.3, 0.7), 3.0))[:n_plays]
    m = samples.random_model(2, 3 + n_plays, 1, 8, 10, seed=seed, poly_head=True,
                             lstm_inputs=1, quad_diag=quad_diag, bias_head=True, plays=plays)
    w = dict(m.weights)
    f = 3 + n_plays
    fw = np.diag([0.02, 0.021, 0.019, 0.3, 0.25][:f]).astype(np.float32)
    for i, (src, _) in enumerate(plays):
        fw[3 + i, 1:3] = [-fw[3 + i, 3 + i] * v for v in src[1:]]
    w["feat_w"], w["feat_b"] = fw, np.array([-0.4, 0.1, -0.3, 0.05, -0.02][:f], np.float32)
    pl = slice(3, f)
    for name in ("cube_w", "bias_quad_w", "bias_cube_w"):
        w[name] = w[name].copy()
        w[name][pl] = 0.0
    w["quad_w"] = w["quad_w"].copy()
    if quad_diag:
        w["quad_w"][pl] = 0.0
    else:
        w["quad_w"][pl, :] = 0.0
        w["quad_w"][:, pl] = 0.0
    return replace(m, weights=w)


@pytest.mark.slow
@pytest.mark.parametrize("quad_diag, n_plays", [(False, 1), (True, 1), (False, 2)],
                         ids=["full-quad", "quad-diag", "two-plays"])
def test_a_play_terms_sources_move_to_the_linear_weights(quad_diag, n_plays, kroot) -> None:
    """`pure_play_rows` puts the play's row on its own state (its sources' part in skip_w,
    bias_w, head_b, bias_b), so the map is diagonal: the outputs stay within float32
    rounding of the model's and the C kernel runs the result bit for bit."""
    model = _hysteresis_term_model(quad_diag=quad_diag, n_plays=n_plays)
    model.validate()
    pure = pure_play_rows(model)
    assert pure is not model and not np.any(pure.weights["feat_w"][3:, :3])
    diag = diagonal_features(pure)
    assert diag.feat_diag and diagonal_features(model) is model  # the mixed row: dense
    temp, gyro = golden_inputs(model, n=3000, seed=26)
    temp = temp + 15.0 * np.abs(((np.arange(temp.size) / 400.0) % 2.0) - 1.0)
    a, b = reference.replay(model, temp, gyro), reference.replay(diag, temp, gyro)
    assert np.max(np.abs(a.sf_ppm - b.sf_ppm)) < 5e-6 * np.max(np.abs(a.sf_ppm))  # rounding
    assert np.max(np.abs(a.bias_dph - b.bias_dph)) < 5e-6 * np.max(np.abs(a.bias_dph))
    out = kernel_for(diag, kroot).run_bias(temp, gyro)
    np.testing.assert_array_equal(out[1].view(np.uint32), b.sf_ppm.view(np.uint32))
    np.testing.assert_array_equal(out[2].view(np.uint32), b.bias_dph.view(np.uint32))


def test_a_play_that_is_not_linear_keeps_its_row() -> None:
    """A play feature with a cube (or read by the LSTM) cannot move its sources: unchanged."""
    model = _hysteresis_term_model()
    w = dict(model.weights)
    w["cube_w"] = w["cube_w"].copy()
    w["cube_w"][3] = 0.1
    cubed = replace(model, weights=w)
    assert pure_play_rows(cubed) is cubed
    no_play = samples.random_model(2, 3, 1, 8, 10, seed=3, poly_head=True)
    assert pure_play_rows(no_play) is no_play
