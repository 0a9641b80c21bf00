"""The numpy reference of the streaming contract (fogsf/models/: stream, reference, f32)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.models import f32, reference, samples
from fogsf.models import stream as st
from fogsf.models.front_end import FrontEnd
from fogsf.models.gate_order import onnx_to_torch_lstm, torch_to_onnx_lstm
from fogsf.models.stream_flags import (
    FLAG_GYRO_INVALID,
    FLAG_SF_CLAMPED,
    FLAG_TEMP_CLAMPED,
    FLAG_TEMP_INVALID,
    FLAG_TEMP_STUCK,
    SF_LIMIT_PPM,
)
from fogsf.models.stream_forms import diagonal_features

F32 = np.float32


def scalar_frontend(temp: np.ndarray, fe: FrontEnd) -> tuple[list[int], np.ndarray, np.ndarray]:
    """The contract's steps 1-4 as a per-sample state machine (what C does), written apart
    from the vectorised reference so that the two check each other."""
    t_min, t_max, t_ref = F32(fe.t_min_c), F32(fe.t_max_c), F32(fe.t_ref_c)
    alpha = [F32(a) for a in fe.filter_alpha]
    with np.errstate(over="ignore"):
        raw = np.asarray(temp, dtype=np.float32)
    last_good = t_ref
    prev_bits = None
    run = 0
    acc = F32(0)
    n_acc = 0
    y: list[F32] = []
    steps, rows, flags = [], [], np.zeros(len(raw), np.uint32)
    for i, t in enumerate(raw):
        fl = 0
        bits = int(np.array(t).view(np.uint32))
        run = run + 1 if bits == prev_bits else 0
        prev_bits = bits
        if not np.isfinite(t):
            tc = last_good
            fl |= FLAG_TEMP_INVALID
        else:
            tc = t
            if t < t_min:
                tc, fl = t_min, fl | FLAG_TEMP_CLAMPED
            elif t > t_max:
                tc, fl = t_max, fl | FLAG_TEMP_CLAMPED
            last_good = tc
        if fe.stuck_samples > 0 and run >= fe.stuck_samples:
            fl |= FLAG_TEMP_STUCK
        flags[i] = fl
        tm = None
        if i == 0:
            tm = tc
            y = [tc for _ in alpha]
        else:
            acc = F32(acc + tc)
            n_acc += 1
            if n_acc == fe.decimation:
                tm = F32(acc / F32(fe.decimation))
                acc, n_acc = F32(0), 0
        if tm is not None:
            y = [F32(yk + a * F32(tm - yk)) for yk, a in zip(y, alpha, strict=True)]
            steps.append(i)
            rows.append([F32(tm - t_ref)] + [F32(yk - t_ref) for yk in y])
    return steps, np.array(rows, np.float32).reshape(len(rows), 1 + len(alpha)), flags


def bad_temperature_log(seed: int, n: int) -> np.ndarray:
    """A ramp with NaN, +-Inf, huge and out-of-range values and stuck stretches planted."""
    rng = np.random.default_rng(seed)
    temp = np.linspace(-50.0, 60.0, n) + rng.normal(0, 0.05, n)
    for value in (np.nan, np.inf, -np.inf, 1e300, -1e40, 1e30, 120.0, -80.0):
        temp[rng.integers(0, n, 3)] = value
    start = int(rng.integers(0, n - 300))
    temp[start:start + int(rng.integers(20, 250))] = temp[start]
    temp[:2] = np.nan  # no good value yet: t_ref is used
    return temp


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_frontend_matches_per_sample_state_machine_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    decimation = int(rng.integers(1, 13))
    k = int(rng.integers(0, 4))
    model = samples.random_model(filters=k, decimation=decimation, seed=seed,
                            stuck_samples=int(rng.integers(0, 60)))
    n = int(rng.integers(500, 3000))
    temp = bad_temperature_log(seed, n)
    fe = model.front_end
    out = reference.frontend(temp, fe)
    steps, rows, flags = scalar_frontend(temp, fe)
    assert out.step_index.tolist() == steps, f"seed {seed}"
    np.testing.assert_array_equal(out.s.view(np.uint32), rows.view(np.uint32),
                                  err_msg=f"seed {seed} D={decimation} K={k}")
    np.testing.assert_array_equal(out.flags, flags, err_msg=f"seed {seed}")
    assert np.all(np.isfinite(out.s))
    for bit in (FLAG_TEMP_INVALID, FLAG_TEMP_CLAMPED):
        assert np.any(out.flags & bit), f"seed {seed}: flag {bit} never raised"
    if fe.stuck_samples:
        assert np.any(out.flags & FLAG_TEMP_STUCK), f"seed {seed}"


def test_invalid_first_samples_use_t_ref_and_stuck_counts_repeats() -> None:
    model = samples.random_model(filters=1, decimation=1, stuck_samples=3, t_ref_c=20.0)
    temp = np.array([np.nan, 25.0, 25.0, 25.0, 25.0, 25.0, 26.0])
    out = reference.frontend(temp, model.front_end)
    assert out.s[0, 0] == 0.0  # Tm = t_ref
    assert out.flags.tolist() == [1, 0, 0, 0, 4, 4, 0]


def test_activations_close_to_exact() -> None:
    x = np.linspace(-30, 30, 400001).astype(np.float32)
    xd = x.astype(np.float64)
    assert np.max(np.abs(f32.sigmoid_f32(x) - 1 / (1 + np.exp(-xd)))) < 1.2e-7
    assert np.max(np.abs(f32.tanh_f32(x) - np.tanh(xd))) < 1.2e-7
    e = f32.exp_f32(x).astype(np.float64)
    assert np.max(np.abs(e / np.exp(xd) - 1)) < 2.5e-7
    # total: NaN and huge inputs give finite, saturated values
    odd = np.array([np.nan, np.inf, -np.inf, 1e30, -1e30], np.float32)
    assert np.all(np.isfinite(f32.sigmoid_f32(odd))) and np.all(np.isfinite(f32.tanh_f32(odd)))


def test_gate_order_converters_match_torch() -> None:
    torch = pytest.importorskip("torch")
    torch.manual_seed(3)
    n_in, hid = 5, 7
    lstm = torch.nn.LSTM(n_in, hid)
    x = torch.randn(6, 1, n_in)
    h0, c0 = torch.randn(1, 1, hid) * 0.5, torch.randn(1, 1, hid) * 0.5
    with torch.no_grad():
        y_t, (h_t, c_t) = lstm(x, (h0, c0))
    p = {k: v.detach().numpy() for k, v in lstm.named_parameters()}
    w, r, b = torch_to_onnx_lstm(p["weight_ih_l0"], p["weight_hh_l0"], p["bias_ih_l0"],
                                    p["bias_hh_l0"])
    h, c = h0[0, 0].numpy(), c0[0, 0].numpy()
    for t in range(6):
        h, c = reference.lstm_cell(w, r, b, x[t, 0].numpy(), h, c)
        np.testing.assert_allclose(h, y_t[t, 0].numpy(), atol=2e-6)
    np.testing.assert_allclose(c, c_t[0, 0].numpy(), atol=2e-6)
    back = onnx_to_torch_lstm(w, r, b)
    for got, name in zip(back, ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0"),
                         strict=True):
        np.testing.assert_array_equal(got, p[name])


def test_save_load_roundtrip_and_model_id(tmp_path) -> None:
    model = samples.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9)
    model.save(tmp_path / "m")
    again = st.StreamModel.load(tmp_path / "m")
    assert again.model_id == model.model_id
    assert again.params == model.params
    other = samples.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9)
    other.weights["lstm1_r"][0, 0] = np.nextafter(other.weights["lstm1_r"][0, 0], F32(9))
    assert other.model_id != model.model_id


@pytest.mark.parametrize("breakage, message", [
    (lambda d: (d / "stream_weights.npz").unlink(), "missing"),
    (lambda d: (d / "stream.json").write_text("{"), "not valid JSON"),
    (lambda d: _edit_cfg(d, format="other"), "format"),
    (lambda d: _edit_cfg(d, hidden=5), "shape"),
    (lambda d: _edit_cfg(d, t_ref_c=80.0), "t_ref_c"),
    (lambda d: _edit_cfg(d, decimation="ten"), "decimation"),
    (lambda d: _edit_cfg(d, filter_tau_s=[100.0, 200.0]), "filter_alpha"),
    (lambda d: _edit_weights(d, "feat_b", lambda a: a.astype(np.float64)), "float32"),
    (lambda d: _edit_weights(d, "head_w", lambda a: a * np.nan), "NaN"),
])
def test_load_refuses_broken_artifacts(tmp_path, breakage, message) -> None:
    samples.random_model(seed=1).save(tmp_path / "m")
    breakage(tmp_path / "m")
    with pytest.raises(UserError, match=message):
        st.StreamModel.load(tmp_path / "m")


def _edit_cfg(d, **changes) -> None:
    cfg = json.loads((d / "stream.json").read_text())
    cfg.update(changes)
    (d / "stream.json").write_text(json.dumps(cfg))


def _edit_weights(d, name, fn) -> None:
    with np.load(d / "stream_weights.npz") as npz:
        w = {k: npz[k] for k in npz.files}
    w[name] = fn(w[name])
    np.savez(d / "stream_weights.npz", **w)


def test_replay_is_total_and_flags_bad_gyro() -> None:
    model = samples.random_model(filters=2, decimation=3, seed=4, stuck_samples=10)
    n = 400
    temp = bad_temperature_log(4, n)
    gyro = np.full(n, 10.0)
    gyro[[5, 50, 300]] = [np.nan, np.inf, 1.7e308]
    out = reference.replay(model, temp, gyro)
    assert np.all(np.isfinite(out.corrected_dps)) and np.all(np.isfinite(out.sf_ppm))
    assert np.all(out.flags[[5, 50]] & FLAG_GYRO_INVALID)
    assert out.corrected_dps[5] == 0.0
    ok = np.isfinite(gyro) & (np.abs(gyro) < 1e300)
    s = out.sf_ppm[ok] * np.float32(1e-6)  # the contract's float32 correction (no bias)
    d = gyro[ok].astype(np.float32)
    np.testing.assert_array_equal(out.corrected_dps[ok], d - d * (s / (np.float32(1) + s)))


def test_sf_clamp_flags_a_broken_model() -> None:
    model = samples.random_model(seed=2)
    model.weights["out_scale"][0] = F32(1e30)
    out = reference.replay(model, np.full(30, 30.0), np.full(30, 10.0))
    assert np.all(np.abs(out.sf_ppm) <= SF_LIMIT_PPM)
    assert np.all(out.flags & FLAG_SF_CLAMPED)
    assert np.all(np.isfinite(out.corrected_dps))


@pytest.mark.slow
def test_random_model_is_seeded_and_not_saturated() -> None:
    a = samples.random_model(filters=2, n_features=4, layers=2, hidden=16, decimation=10, seed=5)
    b = samples.random_model(filters=2, n_features=4, layers=2, hidden=16, decimation=10, seed=5)
    assert a.model_id == b.model_id
    temp, _ = samples.chamber_ramp(hours=2.0, seed=5)
    steps = reference.run_steps(a, reference.frontend(temp, a.front_end).s)
    frac_saturated = np.mean(np.abs(steps.h_last) > 0.95)
    assert frac_saturated < 0.05
    assert np.ptp(steps.h_last) > 0.2  # the LSTM does move


# --- the optional polynomial head ----------------------------------------------------------

FIXTURE = "tests/fixtures/small_model"
FIXTURE_ID = "0b2dac94ba9001c1"  # its model_id on main before poly_head existed (76538e3)


def test_old_artifact_without_poly_key_loads_with_its_old_model_id(tmp_path) -> None:
    cfg = json.loads((Path(FIXTURE) / "stream.json").read_text())
    assert "poly_head" not in cfg, "the fixture must stay an artifact from before the key"
    old = st.StreamModel.load(FIXTURE)
    assert old.poly_head is False and "poly_head" not in old.extra
    assert old.model_id == FIXTURE_ID
    # a saved model now says "poly_head": false; with or without the key, one id
    model = samples.random_model(filters=2, n_features=3, layers=1, hidden=4, seed=8)
    model.save(tmp_path / "m")
    assert json.loads((tmp_path / "m" / "stream.json").read_text())["poly_head"] is False
    _edit_cfg_drop(tmp_path / "m", "poly_head")
    again = st.StreamModel.load(tmp_path / "m")
    assert again.model_id == model.model_id and not again.poly_head


def _edit_cfg_drop(d, key: str) -> None:
    cfg = json.loads((d / "stream.json").read_text())
    del cfg[key]
    (d / "stream.json").write_text(json.dumps(cfg))


def test_poly_model_roundtrips_and_keeps_the_other_draws(tmp_path) -> None:
    plain = samples.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9)
    poly = samples.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9,
                           poly_head=True)
    assert set(poly.weights) - set(plain.weights) == {"quad_w", "cube_w"}
    for name, arr in plain.weights.items():
        np.testing.assert_array_equal(poly.weights[name], arr, err_msg=name)
    assert poly.weights["quad_w"].shape == (3, 3) and poly.weights["cube_w"].shape == (3,)
    assert poly.model_id != plain.model_id
    poly.save(tmp_path / "p")
    assert json.loads((tmp_path / "p" / "stream.json").read_text())["poly_head"] is True
    again = st.StreamModel.load(tmp_path / "p")
    assert again.poly_head and again.model_id == poly.model_id
    np.testing.assert_array_equal(again.weights["quad_w"], poly.weights["quad_w"])
    # the id covers the new arrays
    again.weights["cube_w"][1] = np.nextafter(again.weights["cube_w"][1], F32(9))
    assert again.model_id != poly.model_id


@pytest.mark.parametrize("breakage, message", [
    (lambda d: _drop_weight(d, "quad_w"), r"lacks array\(s\) quad_w \(poly_head is true"),
    (lambda d: _drop_weight(d, "cube_w"), r"lacks array\(s\) cube_w"),
    (lambda d: _edit_weights(d, "quad_w", lambda a: a[:, :2].copy()), "quad_w.*shape"),
    (lambda d: _edit_cfg(d, poly_head="yes"), "poly_head.*true or false"),
    (lambda d: _edit_cfg(d, poly_head=False), "holds cube_w, quad_w but poly_head is false"),
])
def test_load_refuses_broken_poly_artifacts(tmp_path, breakage, message) -> None:
    samples.random_model(seed=1, poly_head=True).save(tmp_path / "m")
    breakage(tmp_path / "m")
    with pytest.raises(UserError, match=message):
        st.StreamModel.load(tmp_path / "m")


def _drop_weight(d, name: str) -> None:
    with np.load(d / "stream_weights.npz") as npz:
        w = {k: npz[k] for k in npz.files if k != name}
    np.savez(d / "stream_weights.npz", **w)


@pytest.mark.parametrize("seed", [0, 1])
def test_poly_head_carries_the_polynomial_in_kernel_order(seed) -> None:
    """With the LSTM's head and the skip silenced, y is exactly the float32 sum of the
    contract's order (a scalar loop written here) and within float32 rounding of the exact
    quadratic + cubic in z; with everything on, y = linear head + polynomial."""
    rng = np.random.default_rng(seed)
    model = samples.random_model(filters=int(rng.integers(0, 3)),
                                 n_features=int(rng.integers(1, 6)),
                                 decimation=int(rng.integers(1, 5)), seed=seed, poly_head=True)
    temp = np.linspace(-45.0, 55.0, 400 * model.decimation) + rng.normal(0, 0.05)
    s = reference.frontend(temp, model.front_end).s
    z = reference.features(model, s)
    q, c = model.weights["quad_w"], model.weights["cube_w"]
    exact = (np.einsum("ni,ij,nj->n", z.astype(np.float64), q.astype(np.float64),
                       z.astype(np.float64)) + (z.astype(np.float64) ** 3) @ c)
    assert np.ptp(exact) > 0.05, f"seed {seed}: the polynomial barely moves"
    full = reference.run_steps(model, s)
    linear = samples.random_model(filters=model.n_filters, n_features=model.n_features,
                             decimation=model.decimation, seed=seed)
    y_lin = reference.run_steps(linear, s).y
    np.testing.assert_allclose(full.y, y_lin + exact, atol=2e-6, err_msg=f"seed {seed}")
    for name in ("head_w", "head_b", "skip_w"):
        model.weights[name] = np.zeros_like(model.weights[name])
    y = reference.run_steps(model, s).y
    for m in range(0, z.shape[0], 7):
        acc = F32(0)
        for i in range(z.shape[1]):
            for j in range(z.shape[1]):
                acc = F32(acc + F32(q[i, j] * F32(z[m, i] * z[m, j])))
        for i in range(z.shape[1]):
            acc = F32(acc + F32(c[i] * F32(F32(z[m, i] * z[m, i]) * z[m, i])))
        assert y[m].tobytes() == acc.tobytes(), f"seed {seed} step {m}"
    np.testing.assert_allclose(y, exact, atol=1e-6, err_msg=f"seed {seed}")


# --- the narrowed LSTM input (lstm_inputs) and the diagonal quadratic (quad_diag) ---------

def test_old_artifact_saves_again_without_the_new_keys(tmp_path) -> None:
    """The fixture (written before lstm_inputs/quad_diag existed) keeps its id, and saving
    it again writes the same config (no new keys) and the same arrays."""
    old = st.StreamModel.load(FIXTURE)
    assert old.model_id == FIXTURE_ID
    assert old.lstm_inputs is None and old.n_lstm_inputs == old.n_features
    assert not old.quad_diag and not old.lstm_inputs_narrowed
    old.save(tmp_path / "again")
    cfg_old = json.loads((Path(FIXTURE) / "stream.json").read_text())
    cfg_new = json.loads((tmp_path / "again" / "stream.json").read_text())
    assert set(cfg_new) - set(cfg_old) == {"poly_head"}  # the key of the earlier extension
    assert "lstm_inputs" not in cfg_new and "quad_diag" not in cfg_new
    assert "feat_diag" not in cfg_new and not old.feat_diag
    again = st.StreamModel.load(tmp_path / "again")
    assert again.model_id == FIXTURE_ID
    with np.load(Path(FIXTURE) / "stream_weights.npz") as a, \
            np.load(tmp_path / "again" / "stream_weights.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for k in a.files:
            assert a[k].tobytes() == b[k].tobytes(), k


def test_lstm_inputs_equal_to_f_is_the_old_model(tmp_path) -> None:
    """lstm_inputs = F changes nothing: same id, not written, same outputs."""
    plain = samples.random_model(2, 4, 1, 6, 5, seed=12, poly_head=True)
    same = samples.random_model(2, 4, 1, 6, 5, seed=12, poly_head=True, lstm_inputs=4)
    assert same.model_id == plain.model_id and not same.lstm_inputs_narrowed
    same.save(tmp_path / "m")
    assert "lstm_inputs" not in json.loads((tmp_path / "m" / "stream.json").read_text())


@pytest.mark.parametrize("n_in, diag", [(1, True), (3, False), (5, True), (2, True)])
def test_new_forms_roundtrip_and_enter_the_id(n_in, diag, tmp_path) -> None:
    model = samples.random_model(3, 5, 2, 6, 4, seed=13, poly_head=True,
                            lstm_inputs=n_in, quad_diag=diag)
    assert model.weights["lstm0_w"].shape == (24, n_in)
    assert model.weights["lstm1_w"].shape == (24, 6)
    assert model.weights["quad_w"].shape == ((5,) if diag else (5, 5))
    model.save(tmp_path / "m")
    cfg = json.loads((tmp_path / "m" / "stream.json").read_text())
    assert cfg.get("lstm_inputs") == (n_in if n_in < 5 else None)
    assert cfg.get("quad_diag") == (True if diag else None)
    again = st.StreamModel.load(tmp_path / "m")
    assert again.model_id == model.model_id
    assert again.n_lstm_inputs == n_in and again.quad_diag == diag
    # the keys are part of the id: the same arrays under the other reading differ
    if n_in < 5:
        wider = replace(again, lstm_inputs=None)
        assert wider.expected_shapes()["lstm0_w"] == (24, 5)
    if diag:
        with pytest.raises(UserError, match="quad_w"):
            replace(again, quad_diag=False).validate()
    ids = {model.model_id,
           samples.random_model(3, 5, 2, 6, 4, seed=13, poly_head=True).model_id}
    assert len(ids) == 2 or (n_in == 5 and not diag)


@pytest.mark.slow
def test_new_forms_compute_the_full_model_with_zeros_bit_for_bit() -> None:
    """quad_diag = a full quad_w with that diagonal; lstm_inputs N = a full lstm0_w whose
    columns N.. are zero: adding the zero terms changes no bit, so the narrowed forms compute
    exactly the model they stand for (and their op order is the contract's)."""
    narrow = samples.random_model(4, 5, 1, 8, 3, seed=14, poly_head=True, lstm_inputs=2,
                             quad_diag=True)
    w = dict(narrow.weights)
    w["quad_w"] = np.diag(narrow.weights["quad_w"]).astype(np.float32)
    lstm_w = np.zeros((32, 5), np.float32)
    lstm_w[:, :2] = narrow.weights["lstm0_w"]
    w["lstm0_w"] = lstm_w
    full = replace(narrow, weights=w, lstm_inputs=None, quad_diag=False)
    full.validate()
    temp, gyro = samples.chamber_ramp(hours=1.0, seed=14)
    a, b = reference.replay(narrow, temp, gyro), reference.replay(full, temp, gyro)
    assert np.ptp(a.sf_ppm) > 10.0
    assert a.sf_ppm.tobytes() == b.sf_ppm.tobytes()
    assert a.corrected_dps.tobytes() == b.corrected_dps.tobytes()
    # and the LSTM input is really narrowed: changing z[2:] only through the LSTM's view
    # (columns it does not read) is what the full model with nonzero columns would see
    w2 = dict(w)
    w2["lstm0_w"] = lstm_w + np.float32(0.5) * (np.arange(5) >= 2).astype(np.float32)
    wider = replace(full, weights=w2)
    assert reference.replay(wider, temp, gyro).sf_ppm.tobytes() != a.sf_ppm.tobytes()


@pytest.mark.parametrize("breakage, message", [
    (lambda d: _edit_cfg(d, lstm_inputs=0), r"lstm_inputs.*\[1, n_features = 4\]"),
    (lambda d: _edit_cfg(d, lstm_inputs=5), r"lstm_inputs.*\[1, n_features = 4\]"),
    (lambda d: _edit_cfg(d, lstm_inputs="2"), "lstm_inputs.*must be an integer"),
    (lambda d: _edit_cfg(d, lstm_inputs=True), "lstm_inputs.*must be an integer"),
    (lambda d: _edit_cfg(d, lstm_inputs=2.0), "lstm_inputs.*must be an integer"),
    (lambda d: _edit_cfg(d, lstm_inputs=3), r"lstm0_w.*shape.*lstm_inputs=3"),
    (lambda d: _edit_cfg(d, quad_diag="yes"), "quad_diag.*true or false"),
    (lambda d: _edit_cfg(d, quad_diag=False), "quad_w.*shape"),
    (lambda d: _edit_cfg(d, poly_head=False), "quad_diag.*needs the polynomial head"),
    (lambda d: _edit_weights(d, "quad_w", lambda a: np.diag(a).copy()), "quad_w.*shape"),
])
def test_load_refuses_bad_new_keys(tmp_path, breakage, message) -> None:
    samples.random_model(2, 4, 1, 6, 5, seed=15, poly_head=True, lstm_inputs=2,
                    quad_diag=True).save(tmp_path / "m")
    breakage(tmp_path / "m")
    with pytest.raises(UserError, match=message):
        st.StreamModel.load(tmp_path / "m")


# --- the diagonal feature map (feat_diag) ---------------------------------------------------

def test_feat_diag_roundtrips_and_enters_the_id_only_when_true(tmp_path) -> None:
    plain = samples.random_model(2, 3, 1, 6, 4, seed=16, poly_head=True)
    model = samples.random_model(2, 3, 1, 6, 4, seed=16, poly_head=True, feat_diag=True)
    assert model.weights["feat_w"].shape == (3,)
    for name, arr in plain.weights.items():  # the other draws stay put
        assert name == "feat_w" or arr.tobytes() == model.weights[name].tobytes(), name
    assert "feat_diag" not in plain.config() and model.config()["feat_diag"] is True
    assert "(diagonal feat_w)" in model.summary and "diagonal" not in plain.summary
    model.save(tmp_path / "m")
    again = st.StreamModel.load(tmp_path / "m")
    assert again.feat_diag and again.model_id == model.model_id
    assert "feat_diag" not in again.extra
    # the key is part of the id: the same arrays with a full feat_w holding the diagonal
    full = replace(model, weights={**model.weights,
                                   "feat_w": np.diag(model.weights["feat_w"])}, feat_diag=False)
    assert full.model_id != model.model_id
    assert diagonal_features(full).model_id == model.model_id


def _square_diagonal(model: st.StreamModel) -> st.StreamModel:
    """The model with its diagonal feat_w written as the full [F, F] matrix."""
    w = np.diag(model.weights["feat_w"]).astype(np.float32)
    return replace(model, weights={**model.weights, "feat_w": w}, feat_diag=False)


@pytest.mark.slow
def test_diagonal_features_stores_the_diagonal_with_the_same_bits() -> None:
    diag = samples.random_model(3, 4, 1, 6, 5, seed=17, feat_diag=True, bias_head=True)
    diag.weights["feat_w"][1] = F32(0.0)
    diag.weights["feat_w"][2] = F32(-0.0)
    full = _square_diagonal(diag)
    full.weights["feat_w"][0, 3] = F32(-0.0)  # a zero of either sign off the diagonal
    full.validate()
    conv = diagonal_features(full)
    assert conv.feat_diag and conv.weights["feat_w"].flags.c_contiguous
    assert conv.weights["feat_w"].tobytes() == diag.weights["feat_w"].tobytes()
    assert conv.model_id == diag.model_id and conv.weights is not full.weights
    assert not full.feat_diag and full.weights["feat_w"].shape == (4, 4)  # left alone
    temp, gyro = samples.chamber_ramp(hours=1.0, seed=17)
    temp[::97] = F32(diag.t_ref_c)  # s_0 = 0 exactly: zero products on the diagonal too
    a, b = reference.replay(full, temp, gyro), reference.replay(conv, temp, gyro)
    assert np.ptp(a.sf_ppm) > 1.0
    for x, y in zip(a, b, strict=True):
        assert x.tobytes() == y.tobytes()
    s = reference.frontend(temp, full.front_end).s
    assert reference.features(full, s).tobytes() == reference.features(conv, s).tobytes()
    assert diagonal_features(conv) is conv


def test_diagonal_features_leaves_other_models_as_they_are() -> None:
    dense = samples.random_model(3, 4, 1, 6, 5, seed=18)  # square, not diagonal
    assert diagonal_features(dense) is dense
    wide = samples.random_model(3, 3, 1, 6, 5, seed=18)  # F = 3 != 1+K = 4
    w = np.zeros((3, 4), np.float32)
    w[[0, 1, 2], [0, 1, 2]] = 0.02
    wide = replace(wide, weights={**wide.weights, "feat_w": w})
    assert diagonal_features(wide) is wide
    diag = _square_diagonal(samples.random_model(3, 4, 1, 6, 5, seed=18, feat_diag=True))
    diag.weights["feat_w"][2, 0] = F32(1e-30)  # one nonzero entry off the diagonal
    assert diagonal_features(diag) is diag
    played = _square_diagonal(samples.random_model(2, 4, 1, 6, 5, seed=18, feat_diag=True,
                                                   plays=(((0.5, 0.5, 0.0), 4.0),)))
    assert diagonal_features(played).feat_diag  # F = 1+K+P


def test_diagonal_features_keeps_a_negative_zero_bias_dense() -> None:
    """feat_b[i] = -0.0 is the one case where the zero terms could change a bit: with
    s_0 = 0 and feat_w[0, 0] < 0 the diagonal form gives -0.0 + -0.0 = -0.0, the full
    matrix adds +0.0 * s_1 (s_1 > 0) and gives +0.0. Such a model is left dense."""
    diag = samples.random_model(1, 2, 1, 4, 5, seed=19, feat_diag=True)
    diag.weights["feat_w"][:] = [-0.5, 0.25]
    diag.weights["feat_b"][:] = [-0.0, 0.1]
    full = _square_diagonal(diag)
    assert diagonal_features(full) is full
    s = np.array([[0.0, 1.0]], np.float32)
    z_full, z_diag = reference.features(full, s), reference.features(diag, s)
    assert z_full[0, 0] == z_diag[0, 0] == 0.0
    assert np.signbit(z_diag[0, 0]) and not np.signbit(z_full[0, 0])
    diag.weights["feat_b"][0] = F32(0.0)  # +0.0: converted, and the same bits
    full = _square_diagonal(diag)
    assert diagonal_features(full).model_id == diag.model_id
    assert reference.features(full, s).tobytes() == reference.features(diag, s).tobytes()


@pytest.mark.parametrize("breakage, message", [
    (lambda d: _edit_cfg(d, feat_diag="yes"), "feat_diag.*true or false"),
    (lambda d: _edit_cfg(d, feat_diag=False), r"feat_w.*shape \(4,\), expected \(4, 4\)"),
    (lambda d: _edit_weights(d, "feat_w", lambda a: np.diag(a).copy()),
     r"feat_w.*shape \(4, 4\), expected \(4,\).*feat_diag=true"),
    (lambda d: _edit_cfg(d, filter_tau_s=[300.0, 600.0], n_features=4),
     r"feat_diag.*is true but n_features = 4 is not 1\+K\+P = 3 \(K=2 filters, P=0"),
])
def test_load_refuses_bad_feat_diag(tmp_path, breakage, message) -> None:
    samples.random_model(3, 4, 1, 6, 5, seed=20, feat_diag=True).save(tmp_path / "m")
    breakage(tmp_path / "m")
    with pytest.raises(UserError, match=message):
        st.StreamModel.load(tmp_path / "m")
