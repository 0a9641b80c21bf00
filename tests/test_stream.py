"""The numpy reference of the streaming contract (trainer/stream.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from trainer import stream as st
from trainer.errors import UserError

F32 = np.float32


def scalar_frontend(temp: np.ndarray, fe: st.FrontEnd) -> tuple[list[int], np.ndarray, np.ndarray]:
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
            fl |= st.FLAG_TEMP_INVALID
        else:
            tc = t
            if t < t_min:
                tc, fl = t_min, fl | st.FLAG_TEMP_CLAMPED
            elif t > t_max:
                tc, fl = t_max, fl | st.FLAG_TEMP_CLAMPED
            last_good = tc
        if fe.stuck_samples > 0 and run >= fe.stuck_samples:
            fl |= st.FLAG_TEMP_STUCK
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
    model = st.random_model(filters=k, decimation=decimation, seed=seed,
                            stuck_samples=int(rng.integers(0, 60)))
    n = int(rng.integers(500, 3000))
    temp = bad_temperature_log(seed, n)
    fe = model.front_end
    out = st.frontend(temp, fe)
    steps, rows, flags = scalar_frontend(temp, fe)
    assert out.step_index.tolist() == steps, f"seed {seed}"
    np.testing.assert_array_equal(out.s.view(np.uint32), rows.view(np.uint32),
                                  err_msg=f"seed {seed} D={decimation} K={k}")
    np.testing.assert_array_equal(out.flags, flags, err_msg=f"seed {seed}")
    assert np.all(np.isfinite(out.s))
    for bit in (st.FLAG_TEMP_INVALID, st.FLAG_TEMP_CLAMPED):
        assert np.any(out.flags & bit), f"seed {seed}: flag {bit} never raised"
    if fe.stuck_samples:
        assert np.any(out.flags & st.FLAG_TEMP_STUCK), f"seed {seed}"


def test_invalid_first_samples_use_t_ref_and_stuck_counts_repeats() -> None:
    model = st.random_model(filters=1, decimation=1, stuck_samples=3, t_ref_c=20.0)
    temp = np.array([np.nan, 25.0, 25.0, 25.0, 25.0, 25.0, 26.0])
    out = st.frontend(temp, model.front_end)
    assert out.s[0, 0] == 0.0  # Tm = t_ref
    assert out.flags.tolist() == [1, 0, 0, 0, 4, 4, 0]


def test_activations_close_to_exact() -> None:
    x = np.linspace(-30, 30, 400001).astype(np.float32)
    xd = x.astype(np.float64)
    assert np.max(np.abs(st.sigmoid_f32(x) - 1 / (1 + np.exp(-xd)))) < 1.2e-7
    assert np.max(np.abs(st.tanh_f32(x) - np.tanh(xd))) < 1.2e-7
    e = st.exp_f32(x).astype(np.float64)
    assert np.max(np.abs(e / np.exp(xd) - 1)) < 2.5e-7
    # total: NaN and huge inputs give finite, saturated values
    odd = np.array([np.nan, np.inf, -np.inf, 1e30, -1e30], np.float32)
    assert np.all(np.isfinite(st.sigmoid_f32(odd))) and np.all(np.isfinite(st.tanh_f32(odd)))


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
    w, r, b = st.torch_to_onnx_lstm(p["weight_ih_l0"], p["weight_hh_l0"], p["bias_ih_l0"],
                                    p["bias_hh_l0"])
    h, c = h0[0, 0].numpy(), c0[0, 0].numpy()
    for t in range(6):
        h, c = st.lstm_cell(w, r, b, x[t, 0].numpy(), h, c)
        np.testing.assert_allclose(h, y_t[t, 0].numpy(), atol=2e-6)
    np.testing.assert_allclose(c, c_t[0, 0].numpy(), atol=2e-6)
    back = st.onnx_to_torch_lstm(w, r, b)
    for got, name in zip(back, ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0"),
                         strict=True):
        np.testing.assert_array_equal(got, p[name])


def test_save_load_roundtrip_and_model_id(tmp_path) -> None:
    model = st.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9)
    model.save(tmp_path / "m")
    again = st.StreamModel.load(tmp_path / "m")
    assert again.model_id == model.model_id
    assert again.params == model.params
    other = st.random_model(filters=2, n_features=3, layers=2, hidden=4, decimation=5, seed=9)
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
    st.random_model(seed=1).save(tmp_path / "m")
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
    model = st.random_model(filters=2, decimation=3, seed=4, stuck_samples=10)
    n = 400
    temp = bad_temperature_log(4, n)
    gyro = np.full(n, 10.0)
    gyro[[5, 50, 300]] = [np.nan, np.inf, 1.7e308]
    out = st.replay(model, temp, gyro)
    assert np.all(np.isfinite(out.corrected_dps)) and np.all(np.isfinite(out.sf_ppm))
    assert np.all(out.flags[[5, 50]] & st.FLAG_GYRO_INVALID)
    assert out.corrected_dps[5] == 0.0
    ok = np.isfinite(gyro) & (np.abs(gyro) < 1e300)
    expect = gyro[ok] / (1.0 + out.sf_ppm[ok].astype(np.float64) * 1e-6)
    np.testing.assert_array_equal(out.corrected_dps[ok], expect)


def test_sf_clamp_flags_a_broken_model() -> None:
    model = st.random_model(seed=2)
    model.weights["out_scale"][0] = F32(1e30)
    out = st.replay(model, np.full(30, 30.0), np.full(30, 10.0))
    assert np.all(np.abs(out.sf_ppm) <= st.SF_LIMIT_PPM)
    assert np.all(out.flags & st.FLAG_SF_CLAMPED)
    assert np.all(np.isfinite(out.corrected_dps))


def test_random_model_is_seeded_and_not_saturated() -> None:
    a = st.random_model(filters=2, n_features=4, layers=2, hidden=16, decimation=10, seed=5)
    b = st.random_model(filters=2, n_features=4, layers=2, hidden=16, decimation=10, seed=5)
    assert a.model_id == b.model_id
    temp, _ = st.chamber_ramp(hours=2.0, seed=5)
    steps = st.run_steps(a, st.frontend(temp, a.front_end).s)
    frac_saturated = np.mean(np.abs(steps.h_last) > 0.95)
    assert frac_saturated < 0.05
    assert np.ptp(steps.h_last) > 0.2  # the LSTM does move
