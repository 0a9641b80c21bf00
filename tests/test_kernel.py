"""The C kernel (firmware/c) through cffi: against the numpy reference (bit for bit), against
onnxruntime and onnx.reference (tolerances of the issue), totality, determinism."""

from __future__ import annotations

import shutil
from dataclasses import replace

import numpy as np
import pytest
from kernel_helpers import FLAGS, init, kernel_for, seal
from onnx.reference import ReferenceEvaluator

from fogsf.bindings.firmware import golden_inputs
from fogsf.bindings.kernel import trace_steps
from fogsf.export.onnx_step import OrtStepper, build_step_onnx, state_names
from fogsf.models import f32, reference, samples
from fogsf.models import stream as st
from fogsf.models.stream_flags import (
    FLAG_GYRO_INVALID,
    FLAG_TEMP_CLAMPED,
    FLAG_TEMP_INVALID,
    FLAG_TEMP_STUCK,
)
from fogsf.models.stream_forms import diagonal_features

F32 = np.float32

# (K filters, F features, L layers, H hidden, D decimation, stuck_samples, seed)
SIZES = [(3, 4, 1, 16, 10, 600, 0), (0, 3, 2, 5, 1, 0, 1), (2, 5, 2, 12, 7, 30, 2),
         (1, 1, 1, 1, 50, 5, 3)]
# the same with the polynomial head (a 7-tuple is without it)
POLY_SIZES = [(3, 4, 1, 16, 10, 600, 4, True), (0, 3, 2, 5, 2, 0, 5, True),
              (1, 1, 1, 1, 50, 5, 6, True)]
# the narrowed forms: (..., poly, lstm_inputs N, quad_diag[, feat_diag]); the first is the
# lag bank's shape (the default model's form)
FORM_SIZES = [(11, 12, 1, 16, 50, 600, 7, True, 1, True, True),
              (3, 4, 2, 6, 3, 20, 8, True, 2, False), (2, 5, 1, 8, 1, 0, 9, True, None, True),
              (0, 3, 2, 5, 4, 5, 10, False, 1, False), (2, 3, 2, 6, 3, 20, 11, False, None, False,
                                                        True)]


@pytest.fixture(scope="session")
def kroot(tmp_path_factory):
    return tmp_path_factory.mktemp("kernels")


def model_of(size: tuple) -> st.StreamModel:
    k, f, layers, hidden, d, stuck, seed, *rest = size
    poly, n_in, diag, fdiag = (*rest, None, False, False, False)[:4] if rest else (
        False, None, False, False)
    return samples.random_model(k, f, layers, hidden, d, seed=seed, stuck_samples=stuck,
                                poly_head=bool(poly), lstm_inputs=n_in, quad_diag=bool(diag),
                                feat_diag=bool(fdiag))


@pytest.mark.slow
@pytest.mark.parametrize("size", SIZES + POLY_SIZES + FORM_SIZES)
def test_kernel_equals_numpy_reference_bit_for_bit(size, kroot) -> None:
    model = model_of(size)
    kernel = kernel_for(model, kroot)
    seed = size[6]
    temp, gyro = golden_inputs(model, n=2500, seed=seed)
    corrected, sf, flags = kernel.run(temp, gyro)
    ref = reference.replay(model, temp, gyro)
    bad = np.flatnonzero(sf.view(np.uint32) != ref.sf_ppm.view(np.uint32))
    assert bad.size == 0, f"seed {seed}: sf differs at samples {bad[:20].tolist()}"
    np.testing.assert_array_equal(corrected.view(np.uint64), ref.corrected_dps.view(np.uint64),
                                  err_msg=f"seed {seed}")
    np.testing.assert_array_equal(flags, ref.flags, err_msg=f"seed {seed}")


def simulated_ramp(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The simulator's paper run at 1 C/min (54,001 samples), else a numpy ramp."""
    try:
        from fogsf.sim.gyro import simulate
        from fogsf.sim.scenarios import paper
    except ImportError:  # the simulator is another branch's work
        return samples.chamber_ramp(hours=1.6, seed=seed)
    log = simulate(paper(1.0, seed=seed)).log
    return log.temp_c, log.gyro_dps


def compare_with_ort(model: st.StreamModel, kernel, temp: np.ndarray, gyro: np.ndarray,  # noqa: ANN001
                     what: str) -> None:
    z, h_c, sf_c = trace_steps(kernel, temp, gyro)
    sf_o, h_o = OrtStepper(build_step_onnx(model), model.layers, model.hidden).run(z)
    h_range = float(np.ptp(h_o))
    dh = np.abs(h_c - h_o)
    worst = np.unravel_index(np.argmax(dh), dh.shape)
    assert h_range > 0.1, f"{what}: the LSTM barely moves, the comparison would be empty"
    assert dh.max() <= 1e-6 * h_range, (
        f"{what}: LSTM output differs by {dh.max():.3g} (> 1e-6 of its range {h_range:.3g}) "
        f"at step {worst[0]}, unit {worst[1]}")
    dsf = np.abs(sf_c.astype(np.float64) - sf_o)
    assert dsf.max() <= 0.01, f"{what}: SF error differs by {dsf.max():.3g} ppm at step " \
                              f"{int(np.argmax(dsf))}"


@pytest.mark.slow
def test_kernel_vs_onnxruntime_over_a_simulated_ramp(kroot) -> None:
    model = samples.random_model(3, 4, 1, 16, decimation=1, seed=11)
    temp, gyro = simulated_ramp(seed=11)
    assert len(temp) >= 50_000
    compare_with_ort(model, kernel_for(model, kroot), temp, gyro, "simulated 1 C/min ramp")


@pytest.mark.slow
@pytest.mark.parametrize("seed, poly", [(21, False), (22, False), (23, True)])
def test_kernel_vs_onnxruntime_on_random_inputs(seed, poly, kroot) -> None:
    rng = np.random.default_rng(seed)
    layers, hidden = int(rng.integers(1, 3)), int(rng.integers(4, 40))
    model = samples.random_model(int(rng.integers(0, 4)), int(rng.integers(1, 7)), layers, hidden,
                            decimation=int(rng.integers(1, 4)), seed=seed, poly_head=poly)
    n = 12_000
    # a random walk across the range with jumps, so the filters and the LSTM see everything
    temp = np.clip(np.cumsum(rng.normal(0, 0.8, n)) % 140 - 55, -60, 70)
    temp[rng.integers(0, n, 50)] = rng.uniform(-60, 70, 50)
    gyro = rng.normal(10, 5, n)
    compare_with_ort(model, kernel_for(model, kroot), temp, gyro, f"random inputs, seed {seed}")


@pytest.mark.parametrize("size", FORM_SIZES)
def test_narrowed_forms_kernel_vs_onnxruntime(size, kroot) -> None:
    """lstm_inputs, quad_diag and feat_diag: the ONNX step (Slice before the first LSTM, the
    diagonal quadratic; z from the kernel's diagonal feature map) against the kernel within
    the tolerances of the other models."""
    model = model_of(size)
    temp, gyro = golden_inputs(model, n=400 * model.decimation, seed=size[6])
    compare_with_ort(model, kernel_for(model, kroot), temp, gyro, f"form {size}")


@pytest.mark.parametrize("poly", [False, True])
def test_kernel_vs_onnx_reference(poly, kroot) -> None:
    model = samples.random_model(2, 4, 2, 6, decimation=3, seed=31, poly_head=poly)
    temp, gyro = golden_inputs(model, n=900, seed=31)
    z, h_c, sf_c = trace_steps(kernel_for(model, kroot), temp, gyro)
    ref = ReferenceEvaluator(build_step_onnx(model))
    in_names, _ = state_names(model.layers)
    state = [np.zeros((1, model.hidden), np.float32) for _ in in_names]
    for m in range(z.shape[0]):
        outs = ref.run(None, {"z": z[m:m + 1], **dict(zip(in_names, state, strict=True))})
        state = outs[1:1 + 2 * model.layers]
        np.testing.assert_allclose(state[-2][0], h_c[m], atol=2e-6, err_msg=f"step {m}")
        assert abs(float(outs[0][0, 0]) - float(sf_c[m])) <= 0.01, f"step {m}"
        # the graph's correction factor is the kernel's float32 ops on its own sf_ppm
        k_want, _ = reference.correction_terms(outs[0][0])
        assert outs[-1][0].tobytes() == k_want.tobytes(), f"step {m}"


def test_streaming_equals_whole_log_and_runs_repeat_bit_for_bit(kroot) -> None:
    model = model_of(SIZES[2])
    kernel = kernel_for(model, kroot)
    temp, gyro = golden_inputs(model, n=3000, seed=5)
    a = kernel.stream(temp, gyro)
    b = kernel.run(temp, gyro)
    state = kernel.new_state()
    kernel.run(temp[:777], gyro[:777], st=state)
    kernel.lib.fogsf_reset(kernel.m, state, kernel.ffi.sizeof("fogsf_state"))
    c = kernel.run(temp, gyro, st=state)  # reset really starts over
    for x, y in ((a, b), (b, c), (b, kernel.run(temp, gyro))):
        for u, v in zip(x, y, strict=True):
            assert u.tobytes() == v.tobytes()
    # the Python per-sample helper is the same step
    state = kernel.new_state()
    for i in range(200):
        got = kernel.step(state, temp[i], gyro[i])
        assert got == (b[0][i], b[1][i], b[2][i]), f"sample {i}"
    # split into two calls on one state = one call
    state = kernel.new_state()
    first = kernel.run(temp[:1234], gyro[:1234], st=state)
    second = kernel.run(temp[1234:], gyro[1234:], st=state)
    for u, v, w in zip(first, second, b, strict=True):
        assert np.concatenate([u, v]).tobytes() == w.tobytes()


@pytest.mark.parametrize("seed", [41, 42, 43])
def test_bad_inputs_give_finite_outputs_and_the_right_flags(seed, kroot) -> None:
    rng = np.random.default_rng(seed)
    stuck = int(rng.integers(3, 40))
    model = samples.random_model(2, 4, 1, 8, decimation=int(rng.integers(1, 6)), seed=seed,
                            stuck_samples=stuck)
    kernel = kernel_for(model, kroot)
    n = 2000
    temp = np.linspace(-30.0, 40.0, n) + rng.normal(0, 0.05, n)
    gyro = 10.0 + rng.normal(0, 0.01, n)
    idx = rng.permutation(np.arange(1, n - 200))
    nan_t, inf_t, hot, cold = idx[:5], idx[5:10], idx[10:15], idx[15:20]
    temp[nan_t] = np.nan
    temp[inf_t] = rng.choice([np.inf, -np.inf, 1e300, -1e300], 5)  # 1e300 -> float32 inf
    temp[hot] = rng.uniform(model.t_max_c + 0.5, 1e30, 5)
    temp[cold] = rng.uniform(-1e30, model.t_min_c - 0.5, 5)
    s0 = n - 150
    temp[s0:s0 + stuck + 10] = 12.25
    bad_g = idx[20:30]
    gyro[bad_g] = rng.choice([np.nan, np.inf, -np.inf, 1.7e308], 10)
    corrected, sf, flags = kernel.stream(temp, gyro)
    assert np.all(np.isfinite(corrected)) and np.all(np.isfinite(sf)), f"seed {seed}"
    assert np.all(flags[nan_t] & FLAG_TEMP_INVALID), f"seed {seed}"
    assert np.all(flags[inf_t] & FLAG_TEMP_INVALID), f"seed {seed}"
    assert np.all(flags[np.concatenate([hot, cold])] & FLAG_TEMP_CLAMPED), f"seed {seed}"
    stuck_flagged = np.flatnonzero(flags & FLAG_TEMP_STUCK)
    assert stuck_flagged.tolist() == list(range(s0 + stuck, s0 + stuck + 10)), f"seed {seed}"
    huge_ok = gyro[bad_g] == 1.7e308  # finite but the correction may overflow
    assert np.all(flags[bad_g[~huge_ok]] & FLAG_GYRO_INVALID), f"seed {seed}"
    assert np.all(corrected[bad_g[~huge_ok]] == 0.0), f"seed {seed}"
    good = np.setdiff1d(np.arange(n), np.concatenate([idx[:30], np.arange(s0, n)]))
    assert not np.any(flags[good]), f"seed {seed}: flags on good samples"
    assert np.all(np.abs(sf) < 1e4)


def test_activations_equal_reference_bits_and_are_accurate(kroot) -> None:
    kernel = kernel_for(model_of(SIZES[0]), kroot)
    rng = np.random.default_rng(7)
    x = np.concatenate([np.linspace(-100, 100, 20001), rng.normal(0, 4, 20000),
                        [0.0, -0.0, 0.625, -0.625, 10.0, -10.0, 87.9, -87.1, 1e30, -1e30,
                         np.inf, -np.inf, np.nan, 1e-40]]).astype(np.float32)
    for name, ref in (("exp", f32.exp_f32), ("sigmoid", f32.sigmoid_f32), ("tanh", f32.tanh_f32)):
        got = kernel.activation(name, x)
        bad = np.flatnonzero(got.view(np.uint32) != ref(x).view(np.uint32))
        assert bad.size == 0, f"{name}: C and numpy differ at x = {x[bad[:10]].tolist()}"
        assert np.all(np.isfinite(got)), name
    xs = np.linspace(-20, 20, 40001).astype(np.float32)
    xd = xs.astype(np.float64)
    assert np.max(np.abs(kernel.activation("tanh", xs) - np.tanh(xd))) < 1.2e-7
    assert np.max(np.abs(kernel.activation("sigmoid", xs) - 1 / (1 + np.exp(-xd)))) < 1.2e-7


@pytest.mark.skipif(shutil.which("clang") is None, reason="clang not installed")
def test_gcc_and_clang_builds_give_the_same_bits(kroot) -> None:
    model = model_of(SIZES[1])
    temp, gyro = golden_inputs(model, n=1500, seed=9)
    a = kernel_for(model, kroot, "gcc").run(temp, gyro)
    b = kernel_for(model, kroot, "clang").run(temp, gyro)
    for u, v in zip(a, b, strict=True):
        assert u.tobytes() == v.tobytes()


def test_an_unusable_model_gives_zero_and_only_the_model_flag(kroot) -> None:
    """A model larger than the state (or NULL, or with D = 0) is refused by init and gives
    corrected = 0, sf = 0 and MODEL_INVALID from step, without touching the state. A model the
    state was started with that changes that way afterwards (a model in RAM) is flagged
    MODEL_CHANGED from its next model step on, and the verified correction is held (none yet
    right after init: the gyro as it is), until a reset."""
    model = samples.random_model(2, 4, 1, 8, 10, seed=21)
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    assert lib.fogsf_model_check(kernel.m) == 0
    state = kernel.new_state()
    out = ffi.new("fogsf_output *")

    changed = FLAGS["MODEL_CHANGED"]

    def refused_by_step(field: str, value: int) -> None:
        live = ffi.new("fogsf_model *", kernel.m[0])
        st2 = ffi.new("fogsf_state *")
        assert init(kernel, live, st2) == 0
        lib.fogsf_step(live, st2, 20.0, 10.0, out)
        assert out.flags == 0, field
        setattr(live, field, value)
        # the sizes are checked again on the next sample that reads the arrays (the next
        # model step, at most D samples on); the samples before it read scalars only
        for _ in range(model.decimation):
            lib.fogsf_step(live, st2, 20.0, 10.0, out)
            if out.flags & changed:
                break
        assert (out.corrected_dps, out.sf_ppm, out.flags) == (10.0, 0.0, changed), field
        lib.fogsf_step(live, st2, 25.0, 10.0, out)  # held until a reset
        assert (out.corrected_dps, out.flags) == (10.0, changed), field

    # sealed (CRCs recomputed) where the change cannot lengthen a table the CRC reads, so
    # the size checks themselves refuse it
    for field, value, reseal in (("hidden", model.hidden + 1, False), ("layers", 0, True),
                                 ("decimation", 0, True),
                                 ("n_features", model.n_features + 1, False)):
        bad = ffi.new("fogsf_model *", kernel.m[0])
        setattr(bad, field, value)
        if reseal:
            seal(lib, bad)
        assert lib.fogsf_model_check(bad) == 32, field
        assert init(kernel, bad, ffi.new("fogsf_state *")) == 32, field
        before = bytes(ffi.buffer(state))
        lib.fogsf_step(bad, state, 20.0, 10.0, out)
        assert (out.corrected_dps, out.sf_ppm, out.flags) == (0.0, 0.0, 32), field
        assert bytes(ffi.buffer(state)) == before, field
        refused_by_step(field, value)
    lib.fogsf_step(ffi.NULL, state, 20.0, 10.0, out)
    assert out.flags == 32 | FLAGS["CALL_INVALID"] and out.corrected_dps == 0.0
    # format 3's fields: lstm_inputs beyond F, quad_diag other than 0/1 or without the head
    for field, value in (("lstm_inputs", model.n_features + 1), ("quad_diag", 2),
                         ("quad_diag", 1)):
        bad = ffi.new("fogsf_model *", kernel.m[0])
        setattr(bad, field, value)
        if field == "quad_diag":
            seal(lib, bad)
        assert lib.fogsf_model_check(bad) == 32, (field, value)
        before = bytes(ffi.buffer(state))
        lib.fogsf_step(bad, state, 20.0, 10.0, out)
        assert (out.corrected_dps, out.sf_ppm, out.flags) == (0.0, 0.0, 32), field
        assert bytes(ffi.buffer(state)) == before, field
        refused_by_step(field, value)
    for value in (0, 1, model.n_features):  # 0 = all features (a model generated before)
        ok = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), lstm_inputs=value)
        assert lib.fogsf_model_check(ok) == 0, value
    # a model struct from before format 3 (both fields 0) computes what it did
    old = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), lstm_inputs=0, quad_diag=0)
    a, b = ffi.new("fogsf_state *"), ffi.new("fogsf_state *")
    assert init(kernel, kernel.m, a) == init(kernel, old, b) == 0
    out_b = ffi.new("fogsf_output *")
    for i, t in enumerate(np.linspace(-40.0, 50.0, 60).tolist()):
        lib.fogsf_step(kernel.m, a, t, 10.0, out)
        lib.fogsf_step(old, b, t, 10.0, out_b)
        assert (out.sf_ppm, out.flags) == (out_b.sf_ppm, out_b.flags), i
    lib.fogsf_step(kernel.m, state, 20.0, 10.0, out)  # the good model still runs on it
    assert out.flags == 0 and out.corrected_dps != 0.0
    # feat_diag other than 0/1, or 1 with F != 1+K+P (here F = 4, 1+K = 3)
    for value in (1, 2):
        bad = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), feat_diag=value)
        assert lib.fogsf_model_check(bad) == 32, value
        lib.fogsf_step(bad, state, 20.0, 10.0, out)
        assert (out.corrected_dps, out.sf_ppm, out.flags) == (0.0, 0.0, 32), value
        refused_by_step("feat_diag", value)
    # F = 1+K (only checked, never stepped)
    square = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), n_features=3, lstm_inputs=0,
                  feat_diag=1)
    assert lib.fogsf_model_check(square) == 0
    square = seal(lib, square, feat_diag=2)
    assert lib.fogsf_model_check(square) == 32


# (K, F, D, seed, bias head, plays): the default model's shape with a bias head (format 4),
# a small one with a play and a bias head (format 5)
DIAG_SIZES = [(11, 12, 5, 51, True, ()), (2, 4, 3, 52, True, (((0.4, 0.6, 0.0), 5.0),))]


@pytest.mark.slow
@pytest.mark.parametrize("size", DIAG_SIZES, ids=["default-form-bias-head", "play-bias-head"])
def test_diagonal_features_keep_every_kernel_bit(size, kroot) -> None:
    """A trained-like model whose feat_w is diagonal (the lag bank's: zeros off the diagonal,
    some of them -0.0, feat_b +0.0 as the bank's normalisation writes it), in the kernel
    before and after `diagonal_features`: z, the SF, the bias, the corrected rate and the
    flags the same bits, and both the numpy reference's."""
    k, f, d, seed, bias, plays = size
    diag = samples.random_model(k, f, 1, 16, d, seed=seed, poly_head=True,
                                lstm_inputs=1, quad_diag=True, bias_head=bias, plays=plays,
                                feat_diag=True)
    diag.weights["feat_b"][:] = 0.0
    diag.weights["feat_b"][1] = F32(0.125)
    diag.weights["feat_w"][2] = F32(0.0)
    w = np.diag(diag.weights["feat_w"]).astype(np.float32)
    w[np.arange(f) % 2 == 1, 0] = F32(-0.0)
    full = replace(diag, weights={**diag.weights, "feat_w": w}, feat_diag=False)
    full.validate()
    conv = diagonal_features(full)
    assert conv.feat_diag and conv.model_id == diag.model_id
    temp, gyro = golden_inputs(full, n=3000, seed=seed)
    temp[::53] = full.t_ref_c  # s_0 = 0 exactly at some steps
    ka, kb = kernel_for(full, kroot), kernel_for(conv, kroot)
    assert kb.m.feat_diag == 1 and ka.m.feat_diag == 0
    za, _, _ = trace_steps(ka, temp, gyro)
    zb, _, _ = trace_steps(kb, temp, gyro)
    assert np.any(za == 0.0) and za.tobytes() == zb.tobytes()
    a, b = ka.run_bias(temp, gyro), kb.run_bias(temp, gyro)
    for x, y in zip(a, b, strict=True):
        assert x.tobytes() == y.tobytes()
    ref = reference.replay(conv, temp, gyro)
    assert np.ptp(ref.sf_ppm) > 1.0 and np.ptp(ref.bias_dph) > 0.1
    assert a[0].tobytes() == ref.corrected_dps.tobytes()
    assert a[1].tobytes() == ref.sf_ppm.tobytes() and a[2].tobytes() == ref.bias_dph.tobytes()
    assert np.array_equal(a[3], ref.flags)
