"""The rate part in the kernel (docs/stream-contract.md, "Optional rate part"): host C through
cffi equals `reference.replay` bit for bit (sizes R, Q from 1 up to the bounds, bias heads,
plays, D = 1 and D > 1, the even-time build, bad temperatures and gyros, rates beyond full
scale); a model without the part keeps its generated C (but for the struct's trailing rate
fields), its ONNX graph and its outputs; fogsf_model_check refuses rate fields out of bounds;
a bit flipped in rate_w after init raises MODEL_CHANGED; onnxruntime agrees to a tolerance."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import FLAGS, init, kernel_for, seal

from fogsf.bindings.firmware import golden_inputs
from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.export.header import render_model
from fogsf.export.onnx_step import OrtStepper, build_step_onnx
from fogsf.models import reference, samples
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_RATE_CLAMPED

INVALID, CHANGED = FLAGS["MODEL_INVALID"], FLAGS["MODEL_CHANGED"]


@pytest.fixture(scope="module")
def kroot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("rate-kernels")


def rate_model(r: int, q: int, decimation: int = 5, seed: int = 91, fs: float = 20.0,
               **extra) -> StreamModel:
    return samples.random_model(2, 4, 1, 6, decimation=decimation, seed=seed,
                                stuck_samples=8, rate_part=(r, q), rate_fs_dps=fs, **extra)


def rate_inputs(model, n: int = 1500, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """golden_inputs (NaN/Inf/huge temperatures and gyros, a stuck run) with the gyro swept
    across +-2 full scales (RATE_CLAMPED beyond one), exact zeros and -0.0 planted, and a
    power-on start (NaN, then a DS18B20's 85 C) before the first plausible temperature."""
    temp, gyro = golden_inputs(model, n=n, seed=seed)
    fs = np.float32(model.rate_fs_dps)
    sweep = np.linspace(-2.0 * fs, 2.0 * fs, n).astype(np.float32)
    ok = np.isfinite(gyro) & (np.abs(gyro) < 1e30)
    gyro = np.where(ok, sweep, gyro).astype(np.float32)
    gyro[7::97], gyro[11::89] = np.float32(0.0), np.float32(-0.0)
    temp[0], temp[1] = np.float32(np.nan), np.float32(85.0)
    return temp, gyro


def assert_bits(kernel: Kernel, model, temp, gyro, even: bool) -> np.ndarray:  # noqa: ANN001
    corrected, sf, flags = kernel.run(temp, gyro)
    want = reference.replay(model, temp, gyro, even_time=even)
    assert corrected.astype(np.float32).tobytes() == \
        want.corrected_dps.astype(np.float32).tobytes()
    assert sf.tobytes() == want.sf_ppm.tobytes()
    assert np.array_equal(flags, want.flags)
    return flags


CASES = [((1, 1), 5, {}), ((1, 3), 1, {}), ((2, 1), 3, {"bias_head": True}),
         ((4, 2), 7, {"plays": (((0.5, 0.5, 0.0), 2.0),)}),
         ((8, 3), 5, {"poly_head": True, "bias_head": True,
                      "plays": (((0.2, 0.5, 0.3), 2.0),)}),
         ((9, 3), 1, {"poly_head": True, "bias_head": True})]


@pytest.mark.slow
@pytest.mark.parametrize("even", [False, True], ids=["default", "even-time"])
@pytest.mark.parametrize("case", CASES, ids=[f"R{c[0][0]}Q{c[0][1]}-D{c[1]}" for c in CASES])
def test_host_kernel_equals_the_reference_bit_for_bit(case, even: bool, kroot: Path) -> None:
    (r, q), d, extra = case
    model = rate_model(r, q, decimation=d, **extra)
    kernel = Kernel(model, build_kernel(model, root=kroot, even_time=even))
    temp, gyro = rate_inputs(model)
    flags = assert_bits(kernel, model, temp, gyro, even)
    assert (flags & FLAG_RATE_CLAMPED).any() and (flags & FLAGS["GYRO_INVALID"]).any()
    # never both: a sample whose corrected rate is not finite is GYRO_INVALID alone
    both = ((flags & FLAG_RATE_CLAMPED) != 0) & ((flags & FLAGS["GYRO_INVALID"]) != 0)
    assert not both.any()
    # the part corrects: a model without it gives other outputs on the same samples
    plain = reference.replay(model_without_rate(model), temp, gyro, even_time=even)
    assert not np.array_equal(plain.corrected_dps, kernel.run(temp, gyro)[0])


def test_two_layers_and_one_step_a_sample_in_the_default_build(kroot: Path) -> None:
    model = samples.random_model(2, 3, 2, 4, decimation=1, seed=17, rate_part=(3, 2),
                                 rate_fs_dps=50.0)
    temp, gyro = rate_inputs(model, n=400)
    assert_bits(kernel_for(model, kroot), model, temp, gyro, even=False)


def model_without_rate(model):  # noqa: ANN001, ANN201
    """The same model with its rate part taken off (rate_w and the key)."""
    from dataclasses import replace

    weights = {k: v for k, v in model.weights.items() if k != "rate_w"}
    return replace(model, weights=weights, rate_fs_dps=0.0)


def test_a_model_without_the_part_keeps_its_c_ids_and_graph() -> None:
    """Generated NAME.h and ONNX graph byte for byte as before the part existed (the hashes
    pinned from that code), NAME.c too but for the struct's trailing rate fields, NULL and 0;
    the CRCs in it, the model_id and format 6 unchanged."""
    pins = [((3, 4, 1, 16), {"decimation": 10, "seed": 2026},
             "0b2dac94ba9001c1", "cb1dcc1d7e34d794", "3bb260da5d2b3616", "6ed2f70bbca60f36"),
            ((2, 4, 1, 6), {"decimation": 5, "seed": 83, "poly_head": True, "bias_head": True,
                            "plays": (((0.2, 0.5, 0.3), 2.0),)},
             "cdbeaa83a68115b3", "2e46857d390d08b3", "5892848609158883", "98081f5de65d6051")]
    for args, kw, model_id, h_pin, c_pin, onnx_pin in pins:
        model = samples.random_model(*args, **kw)
        stripped = model_without_rate(samples.random_model(*args, **kw, rate_part=(3, 2)))
        assert model.model_id == stripped.model_id == model_id
        files = render_model(model, "pin_model")
        assert files == render_model(stripped, "pin_model")
        digest = {k: hashlib.sha256(v.encode()).hexdigest()[:16] for k, v in files.items()}
        assert digest["pin_model.h"] == h_pin
        tail = " /* CRC-32 of the sizes and scalars; of those and every table */\n"
        before = files["pin_model.c"].replace(
            "," + tail + "    NULL, 0u, 0u, 0.0f /* no rate part */\n", tail)
        assert hashlib.sha256(before.encode()).hexdigest()[:16] == c_pin
        assert "#define PIN_MODEL_FORMAT_VERSION 6\n" in files["pin_model.h"]
        onnx = hashlib.sha256(build_step_onnx(model).SerializeToString()).hexdigest()[:16]
        assert onnx == onnx_pin


@pytest.mark.slow
def test_a_model_without_the_part_runs_as_before(kroot: Path) -> None:
    model = samples.random_model(2, 4, 1, 6, decimation=5, seed=91, stuck_samples=8,
                                 bias_head=True)
    kernel = kernel_for(model, kroot)
    temp, gyro = rate_inputs(rate_model(1, 1), n=600)
    flags = assert_bits(kernel, model, temp, gyro, even=False)
    assert not (flags & FLAG_RATE_CLAMPED).any()
    assert kernel.m.format_version == 6 and kernel.m.rate_w == kernel.ffi.NULL


def test_the_generated_c_of_a_rate_model() -> None:
    model = rate_model(3, 2, fs=150.0)
    files = render_model(model, "rm")
    h, c = files["rm.h"], files["rm.c"]
    assert "#define RM_FORMAT_VERSION 7\n" in h and "#define RM_RATE_ROWS 3 " in h
    assert "#define RM_RATE_COEFS 2 " in h and "RM_RATE_ROWS <= FOGSF_MAX_RATE_ROWS" in c
    # 1/FS rounded once from double to float32, printed to read back to its bits
    inv = np.float32(1.0 / 150.0)
    assert f"rate_w, 3u, 2u, {float(inv):.9g}f /* rate part" in c
    assert np.float32(float(f"{float(inv):.9g}")) == inv


@pytest.mark.slow
def test_model_check_refuses_rate_fields_out_of_bounds(kroot: Path) -> None:
    model = rate_model(3, 2, seed=93)
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    assert lib.fogsf_model_check(kernel.m) == 0
    bad_w = ffi.new("float[]", [0.0, float("nan"), 0.0, 0.0, 0.0, 0.0])
    inf = float(np.float32(np.inf))
    keep = []
    # sizes beyond the bounds (or the state's R) are refused before any table is read: not
    # sealed, since the CRC would read rate_w at those sizes
    for name, fields in {"R=10": {"rate_rows": 10}, "R above the state": {"rate_rows": 4},
                         "Q=4": {"rate_coefs": 4}}.items():
        m = ffi.new("fogsf_model *", kernel.m[0])
        keep.append(m)
        for key, value in fields.items():
            setattr(m, key, value)
        assert lib.fogsf_model_check(m) == INVALID, name
    cases = {"R=0": {"rate_rows": 0}, "Q=0": {"rate_coefs": 0},
        "NULL rate_w": {"rate_w": ffi.NULL}, "1/FS 0": {"rate_inv_fs": 0.0},
        "1/FS Inf": {"rate_inv_fs": inf}, "1/FS < 0": {"rate_inv_fs": -0.05},
        "NaN weight": {"rate_w": bad_w},
        "format 6 with the part": {"format_version": 6},
        "format 7 without it": {"rate_w": ffi.NULL, "rate_rows": 0, "rate_coefs": 0,
                                "rate_inv_fs": 0.0}}
    for name, fields in cases.items():
        m = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), **fields)
        keep.append(m)
        assert lib.fogsf_model_check(m) == INVALID, name
        st = ffi.new("fogsf_state *")
        assert init(kernel, m, st) == INVALID, name
    plain = kernel_for(samples.random_model(2, 4, 1, 6, decimation=5, seed=91), kroot)
    for name, fields in {"rows without rate_w": {"rate_rows": 2, "rate_coefs": 1},
                         "1/FS without rate_w": {"rate_inv_fs": 0.05}}.items():
        m = seal(plain.lib, plain.ffi.new("fogsf_model *", plain.m[0]), **fields)
        assert plain.lib.fogsf_model_check(m) == INVALID, name


def test_a_bit_flipped_in_rate_w_after_init_is_found(kroot: Path) -> None:
    """The pass covers the rate part's three head words and rate_w (24 head slots and
    13 + 3L tables), so a flipped bit raises MODEL_CHANGED within two periods, latched."""
    model = rate_model(4, 3, seed=95)
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    d, floats = model.decimation, 4 * 3
    tables = [model.n_filters, model.n_features * (1 + model.n_filters), model.n_features,
              4 * 6 * 4, 4 * 6 * 6, 8 * 6, 6, model.n_features, floats]
    period = (24 + 13 + 3 + 1) * d + 2 * sum(tables)
    assert lib.fogsf_check_period(kernel.m) == period
    m = ffi.new("fogsf_model *", kernel.m[0])
    arr = ffi.new("float[]", [kernel.m.rate_w[i] for i in range(floats)])
    m.rate_w = arr
    temp, gyro = rate_inputs(model, n=4 * period)
    st = ffi.new("fogsf_state *")
    assert init(kernel, m, st) == 0
    out = ffi.new("fogsf_output *")
    flip_at, flagged = period + 13, []
    for i in range(temp.size):
        if i == flip_at:
            raw = ffi.buffer(arr)
            raw[5] = bytes([raw[5][0] ^ 0x10])
        lib.fogsf_step(m, st, float(temp[i]), float(gyro[i]), out)
        if out.flags & CHANGED:
            flagged.append(i)
    assert flagged and flip_at < flagged[0] < flip_at + 2 * period
    assert flagged == list(range(flagged[0], temp.size))
    assert init(kernel, m, ffi.new("fogsf_state *")) == INVALID


@pytest.mark.slow
@pytest.mark.parametrize("rq", [(1, 1), (8, 3)])
def test_onnx_step_and_its_stepper_agree_with_the_reference(rq: tuple[int, int]) -> None:
    model = rate_model(*rq, decimation=5, seed=97, bias_head=True)
    temp, gyro = samples.chamber_ramp(hours=0.5, seed=4)
    gyro = np.linspace(-1.5, 1.5, temp.size) * model.rate_fs_dps
    fe = reference.frontend(temp, model.front_end)
    steps = reference.run_steps(model, fe.s)
    z = (fe.s @ model.weights["feat_w"].T + model.weights["feat_b"]).astype(np.float32)
    ort = OrtStepper(build_step_onnx(model), model.layers, model.hidden)
    ort.run(z, fe.s[:, 0])
    corrected, flags = ort.correct(gyro, model.decimation)
    want = reference.replay(model, temp, gyro)
    assert ort.rate_seq.shape == (steps.sf_ppm.shape[0], rq[0])
    assert np.max(np.abs(corrected - want.corrected_dps)) <= 1e-5 * model.rate_fs_dps
    assert np.array_equal(flags & FLAG_RATE_CLAMPED, want.flags & FLAG_RATE_CLAMPED)
