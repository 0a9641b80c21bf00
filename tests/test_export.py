"""ONNX export of the streaming step and the generated C header."""

from __future__ import annotations

import re

import numpy as np
import onnx
import pytest
import torch
from onnx.reference import ReferenceEvaluator

from fogsf.cli.main import main
from fogsf.export import export_model
from fogsf.export.header import c_float, check_name, render_model
from fogsf.export.onnx_step import OrtStepper, build_step_onnx, state_names
from fogsf.export.torch_step import TorchStep
from fogsf.models import reference, samples
from fogsf.models import stream as st

SIZES = [(2, 4, 1, 8, 10, 0), (0, 3, 2, 5, 1, 1), (3, 6, 2, 16, 4, 2)]
# with the polynomial head: (k, f, layers, hidden, d, seed, poly_head)
POLY_SIZES = [(*size, False) for size in SIZES] + [(2, 4, 1, 8, 10, 3, True),
                                                    (1, 5, 2, 6, 3, 4, True)]
# the narrowed forms: (k, f, layers, hidden, d, seed, poly_head, lstm_inputs, quad_diag
# [, feat_diag]); the first is the default model's form
FORMS = [(11, 12, 1, 16, 50, 5, True, 1, True, True), (3, 5, 2, 6, 3, 6, True, 2, False),
         (2, 4, 1, 8, 10, 7, True, None, True), (0, 3, 2, 5, 1, 8, False, 2, False),
         (2, 3, 2, 6, 4, 9, False, None, False, True)]


def form_model(k: int, f: int, layers: int, hidden: int, d: int, seed: int, poly: bool,
               n_in: int | None = None, diag: bool = False, fdiag: bool = False
               ) -> st.StreamModel:
    return samples.random_model(k, f, layers, hidden, d, seed=seed, poly_head=poly,
                                lstm_inputs=n_in, quad_diag=diag, feat_diag=fdiag)


def random_inputs(model: st.StreamModel, seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(0, 1.5, (n, model.n_features)).astype(np.float32)


@pytest.mark.slow
@pytest.mark.parametrize("params", POLY_SIZES + FORMS)
def test_onnx_step_matches_torch_and_reference(params) -> None:
    model = form_model(*params)
    layers, hidden, seed, poly = model.layers, model.hidden, params[5], model.poly_head
    proto = build_step_onnx(model)
    ops = [n.op_type for n in proto.graph.node]
    assert ("ReduceSum" in ops) == (poly and not model.quad_diag)
    assert ("Slice" in ops) == model.lstm_inputs_narrowed
    onnx.checker.check_model(proto, full_check=True)
    ort = OrtStepper(proto, layers, hidden)
    ref = ReferenceEvaluator(proto)
    tstep = TorchStep(model).eval()
    h = torch.zeros(layers, 1, hidden)
    c = torch.zeros(layers, 1, hidden)
    in_names, _ = state_names(layers)
    ref_state = [np.zeros((1, hidden), np.float32) for _ in in_names]
    for m, z in enumerate(random_inputs(model, seed, 40)):
        sf_ort, _ = ort.step(z)
        with torch.no_grad():
            sf_t, h, c = tstep(torch.from_numpy(z[None, :]), h, c)
        outs = ref.run(None, {"z": z[None, :], **dict(zip(in_names, ref_state, strict=True))})
        ref_state = outs[1:1 + 2 * layers]
        ort_h = np.stack(ort.state[0::2])[:, 0]
        ort_c = np.stack(ort.state[1::2])[:, 0]
        # sf_ppm = y * out_scale + out_offset: compare at the scale of y (tanh units), and
        # never tighter than a few float32 ulps of the output itself (engines sum in their
        # own order: seen here, 1 ulp at -3984 ppm on one CPU and 0 on another)
        scale = float(model.weights["out_scale"][0])
        tol = max(1e-6 * scale, 4 * float(np.spacing(np.float32(abs(sf_ort)))))
        assert abs(sf_ort - float(sf_t)) <= tol, f"seed {seed} step {m}"
        assert abs(sf_ort - float(outs[0][0, 0])) <= tol, f"seed {seed} step {m}"
        np.testing.assert_allclose(ort_h, h[:, 0].numpy(), atol=1e-6, err_msg=f"step {m}")
        np.testing.assert_allclose(ort_c, c[:, 0].numpy(), atol=1e-6, err_msg=f"step {m}")
        np.testing.assert_allclose(ort_h, np.stack(ref_state[0::2])[:, 0], atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("poly, n_in, diag, fdiag", [
    (False, None, False, False), (True, None, False, False), (True, 1, True, False),
    (True, 3, False, False), (True, 1, True, True)])
def test_onnx_step_matches_numpy_reference_over_a_ramp(poly, n_in, diag, fdiag) -> None:
    """z from the reference's feature map (full, or diagonal with feat_diag: F = 1+K) into
    the ONNX step, against the reference's own steps."""
    model = samples.random_model(3 if fdiag else 2, 4, 2, 8, 10, seed=7, poly_head=poly,
                                 lstm_inputs=n_in, quad_diag=diag, feat_diag=fdiag)
    temp, _ = samples.chamber_ramp(hours=1.0, seed=7)
    s = reference.frontend(temp, model.front_end).s
    ref = reference.run_steps(model, s)
    sf, hl = OrtStepper(build_step_onnx(model), model.layers, model.hidden).run(
        reference.features(model, s))
    assert np.max(np.abs(hl - ref.h_last)) <= 1e-6
    assert np.max(np.abs(sf - ref.sf_ppm)) <= 1e-6 * np.ptp(ref.sf_ppm) + 1e-5


def _parse_arrays(text: str) -> dict[str, np.ndarray]:
    out = {}
    for name, body in re.findall(r"static const float (\w+)\[[^\]]*\] = \{(.*?)\};", text,
                                 flags=re.S):
        vals = [v.strip().rstrip("f") for v in body.split(",") if v.strip()]
        out[name] = np.array([float(v) for v in vals], np.float32)
    for name, val in re.findall(r"static const float (\w+) = ([^;]+);", text):
        out[name] = np.array([float(val.rstrip("f"))], np.float32)
    return out


@pytest.mark.parametrize("params", POLY_SIZES + FORMS)
def test_header_is_lossless_and_deterministic(params) -> None:
    model = form_model(*params)
    k, layers, hidden, d, poly = (model.n_filters, model.layers, model.hidden,
                                  model.decimation, model.poly_head)
    files = render_model(model, "imu_x")
    assert sorted(files) == ["imu_x.c", "imu_x.h"]
    text, header = files["imu_x.c"], files["imu_x.h"]
    assert text.splitlines()[0].startswith("/* GENERATED by `fogsf export --name imu_x`")
    again = form_model(*params)
    assert render_model(again, "imu_x") == files
    arrays = _parse_arrays(text)
    w = model.weights
    names = ["feat_w", "feat_b", "head_w", "skip_w"]
    names += [f"lstm{layer}_{p}" for layer in range(layers) for p in "wrb"]
    names += ["filter_alpha"] * (k > 0) + ["quad_w", "cube_w"] * poly
    assert ("quad_w" in text) == poly
    for name in names:
        np.testing.assert_array_equal(arrays[name].view(np.uint32),
                                      w[name].ravel().view(np.uint32), err_msg=name)
    scalars = re.search(r"\n    (\S+), (\S+), (\S+), /\* head_b, out_scale, out_offset", text)
    assert scalars is not None
    for value, name in zip(scalars.groups(), ("head_b", "out_scale", "out_offset"), strict=True):
        assert np.float32(float(value.rstrip("f"))).tobytes() == w[name].tobytes()
    assert f'#define IMU_X_MODEL_ID "{model.model_id}"' in header
    assert f"#define IMU_X_HIDDEN {hidden}\n" in header
    assert f"#define IMU_X_DECIMATION {d}\n" in header
    assert f"#define IMU_X_POLY_HEAD {int(poly)}\n" in header
    assert f"#define IMU_X_LSTM_INPUTS {model.n_lstm_inputs} " in header
    assert f"#define IMU_X_QUAD_DIAG {int(model.quad_diag)} " in header
    assert ("#define IMU_X_FEAT_DIAG 1 " in header) == model.feat_diag
    assert ("FEAT_DIAG" in header) == ("FOGSF_FEAT_DIAG" in text) == model.feat_diag
    fields = re.search(r"\n    (\d+)u, (\d)u, (\d)u, /\* LSTM inputs", text)
    assert fields is not None
    assert (int(fields[1]), int(fields[2]), int(fields[3])) == (
        model.n_lstm_inputs, int(model.quad_diag), int(model.feat_diag))
    assert arrays["lstm0_w"].size == 4 * hidden * model.n_lstm_inputs
    assert arrays["feat_w"].size == model.n_features * (1 if model.feat_diag else 1 + k)
    assert "extern const fogsf_model imu_x;" in header


@pytest.mark.parametrize("bad", ["1x", "imu-x", "fogsf_x", "", "a b"])
def test_model_name_must_be_a_c_identifier(bad) -> None:
    with pytest.raises(ValueError, match="--name"):
        check_name(bad)


def test_c_float_roundtrips_every_kind_of_float() -> None:
    rng = np.random.default_rng(0)
    vals = np.concatenate([rng.normal(0, 1, 2000), [0.0, -0.0, 1.0, 1e-45, 3.4e38, -1e-38]])
    for v in vals.astype(np.float32):
        text = c_float(v)
        assert text.endswith("f") and ("." in text or "e" in text)
        assert np.float32(float(text[:-1])).tobytes() == v.tobytes()


@pytest.mark.parametrize("poly", [False, True])
def test_export_command_writes_both_files(poly, tmp_path, capsys) -> None:
    model = samples.random_model(seed=3, poly_head=poly)
    model.save(tmp_path / "m")
    assert main(["export", str(tmp_path / "m"), "--out", str(tmp_path / "b"),
                 "--name", "imu_y"]) == 0
    printed = capsys.readouterr().out
    assert "model.onnx" in printed and "imu_y.h" in printed and "imu_y.c" in printed
    assert ("LSTM + polynomial head, D=10" in printed) == poly, printed
    first = (tmp_path / "b" / "imu_y.c").read_bytes()
    onnx.checker.check_model(onnx.load(str(tmp_path / "b" / "model.onnx")))
    export_model(st.StreamModel.load(tmp_path / "m"), tmp_path / "c", "imu_y")
    assert (tmp_path / "c" / "imu_y.c").read_bytes() == first
    assert main(["export", str(tmp_path / "m"), "--out", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "gyro_model.h").is_file()  # the default name
    assert main(["export", str(tmp_path / "m"), "--out", str(tmp_path / "x"),
                 "--name", "9bad"]) == 2
    assert "--name" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing"), "--out", str(tmp_path / "x")]) == 2
