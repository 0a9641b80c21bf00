"""The streaming step as an ONNX graph: one call per model step, state passed in and out.

Inputs `z` [1, F] (the features of contract step 4, computed before the graph from s by
feat_w, full or diagonal with `feat_diag`: the graph is the same for both) and, per layer
l, `h{l}` and `c{l}` [1, H]; outputs `sf_ppm` [1, 1] and the new `h{l}_out`, `c{l}_out`
[1, H]. Each layer is an ONNX LSTM node over a sequence of length 1, so onnxruntime steps
exactly like firmware.
A model with the polynomial head gets a few more nodes (z quad_w z^T + (z*z*z) cube_w;
(z*z) quad_w with the diagonal quadratic); without it the graph is what it was before the
head existed. A model whose first LSTM layer reads z[0:N] only (`lstm_inputs`) slices z
before it; without the key the graph is unchanged. A model with a bias head has one more
output, `bias_dph` [1, 1] (bias_b + z bias_w + (z*z) bias_quad_w + (z*z*z) bias_cube_w);
without it the graph is unchanged.

The per-sample correction of contract "fogsf-stream-2" (docs/stream-contract.md, step 5)
needs two numbers per model step, which the graph outputs after the states, float32 op for
op as the kernel: `sf_k` [1, 1] = s / (1 + s), s = sf_ppm * 1e-6, and with a bias head
`bias_dps` [1, 1] = bias_dph / 3600 (before `bias_dph`, which stays last). A sample g is then
corrected as d = g - bias_dps, d - d * sf_k, in float32.
A model with the rate part has one more input, `s0` [1, 1] (Tm - t_ref, the step's s[0]),
and one more output after `sf_k`, `rate_a` [1, R]: the held coefficients a_r (Horner of
rate_w's rows in s0); the property `rate_inv_fs` holds 1/FS (float32, 9 digits), and
`OrtStepper.correct` applies the per-sample polynomial. Without the part the graph is
unchanged.
"""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from fogsf.models.rate_part import inverse_full_scale
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_GYRO_INVALID, FLAG_RATE_CLAMPED
from fogsf.models.stream_format import RATE_ARRAY

F32 = np.float32

OPSET = 17
IR_VERSION = 8


def state_names(layers: int) -> tuple[list[str], list[str]]:
    """(input state names, output state names) in the order h0, c0, h1, c1, ..."""
    ins = [f"{kind}{layer}" for layer in range(layers) for kind in ("h", "c")]
    return ins, [f"{name}_out" for name in ins]


def build_step_onnx(model: StreamModel) -> onnx.ModelProto:
    """The ONNX model of one streaming step (onnx.checker clean)."""
    f, hid, layers = model.n_features, model.hidden, model.layers
    w = model.weights
    inits = [numpy_helper.from_array(np.array([0], np.int64), "axis0"),
             numpy_helper.from_array(w["head_w"].reshape(hid, 1), "head_w"),
             numpy_helper.from_array(w["head_b"].reshape(1), "head_b"),
             numpy_helper.from_array(w["skip_w"].reshape(f, 1), "skip_w"),
             numpy_helper.from_array(w["out_scale"].reshape(1), "out_scale"),
             numpy_helper.from_array(w["out_offset"].reshape(1), "out_offset")]
    if model.lstm_inputs_narrowed:  # the first layer reads z[:, 0:N] only
        n0 = model.n_lstm_inputs
        inits += [numpy_helper.from_array(np.array([0], np.int64), "lstm_in_start"),
                  numpy_helper.from_array(np.array([n0], np.int64), "lstm_in_end"),
                  numpy_helper.from_array(np.array([1], np.int64), "lstm_in_axis")]
        nodes = [helper.make_node("Slice", ["z", "lstm_in_start", "lstm_in_end",
                                            "lstm_in_axis"], ["z_lstm"]),
                 helper.make_node("Unsqueeze", ["z_lstm", "axis0"], ["x0"])]
    else:
        nodes = [helper.make_node("Unsqueeze", ["z", "axis0"], ["x0"])]
    inputs = [helper.make_tensor_value_info("z", TensorProto.FLOAT, [1, f])]
    outputs = [helper.make_tensor_value_info("sf_ppm", TensorProto.FLOAT, [1, 1])]
    x = "x0"
    for layer in range(layers):
        n_in = model.n_lstm_inputs if layer == 0 else hid
        inits += [
            numpy_helper.from_array(w[f"lstm{layer}_w"].reshape(1, 4 * hid, n_in), f"W{layer}"),
            numpy_helper.from_array(w[f"lstm{layer}_r"].reshape(1, 4 * hid, hid), f"R{layer}"),
            numpy_helper.from_array(w[f"lstm{layer}_b"].reshape(1, 8 * hid), f"B{layer}"),
        ]
        for kind in ("h", "c"):
            inputs.append(helper.make_tensor_value_info(f"{kind}{layer}", TensorProto.FLOAT,
                                                        [1, hid]))
            outputs.append(helper.make_tensor_value_info(f"{kind}{layer}_out",
                                                         TensorProto.FLOAT, [1, hid]))
            nodes.append(helper.make_node("Unsqueeze", [f"{kind}{layer}", "axis0"],
                                          [f"{kind}{layer}_3d"]))
        nodes.append(helper.make_node(
            "LSTM", [x, f"W{layer}", f"R{layer}", f"B{layer}", "", f"h{layer}_3d",
                     f"c{layer}_3d"],
            [f"Y{layer}", f"Yh{layer}", f"Yc{layer}"], hidden_size=hid, name=f"lstm{layer}"))
        nodes.append(helper.make_node("Squeeze", [f"Yh{layer}", "axis0"], [f"h{layer}_out"]))
        nodes.append(helper.make_node("Squeeze", [f"Yc{layer}", "axis0"], [f"c{layer}_out"]))
        x = f"Yh{layer}"  # [1, 1, H]: the next layer's sequence of length 1
    last = f"h{layers - 1}_out"
    inits += [numpy_helper.from_array(np.array([1e-6], np.float32), "ppm"),
              numpy_helper.from_array(np.array([1.0], np.float32), "one")]
    outputs.append(helper.make_tensor_value_info("sf_k", TensorProto.FLOAT, [1, 1]))
    y_lin = "y_lin" if model.poly_head else "y"
    nodes += [
        helper.make_node("MatMul", [last, "head_w"], ["head_dot"]),
        helper.make_node("Add", ["head_dot", "head_b"], ["head_y"]),
        helper.make_node("MatMul", ["z", "skip_w"], ["skip_dot"]),
        helper.make_node("Add", ["head_y", "skip_dot"], [y_lin]),
    ]
    if model.poly_head:
        inits += poly_initializers(model)
        nodes += poly_nodes(y_lin, "y", model.quad_diag)
    nodes += [
        helper.make_node("Mul", ["y", "out_scale"], ["y_scaled"]),
        helper.make_node("Add", ["y_scaled", "out_offset"], ["sf_ppm"]),
        helper.make_node("Mul", ["sf_ppm", "ppm"], ["sf_rel"]),
        helper.make_node("Add", ["one", "sf_rel"], ["sf_one_plus"]),
        helper.make_node("Div", ["sf_rel", "sf_one_plus"], ["sf_k"]),
    ]
    props = {}
    if model.has_rate_part:  # s0 in, the held a_r out after sf_k
        rate_init, rate_node_list = rate_nodes(model)
        inits += rate_init
        nodes += rate_node_list
        inputs.append(helper.make_tensor_value_info("s0", TensorProto.FLOAT, [1, 1]))
        outputs.append(helper.make_tensor_value_info(
            "rate_a", TensorProto.FLOAT, [1, model.weights[RATE_ARRAY].shape[0]]))
        props["rate_inv_fs"] = f"{float(inverse_full_scale(model)):.9g}"
    if model.bias_head:
        inits += bias_initializers(model)
        inits.append(numpy_helper.from_array(np.array([3600.0], np.float32), "s_per_h"))
        nodes += bias_nodes()
        nodes.append(helper.make_node("Div", ["bias_dph", "s_per_h"], ["bias_dps"]))
        outputs.append(helper.make_tensor_value_info("bias_dps", TensorProto.FLOAT, [1, 1]))
        outputs.append(helper.make_tensor_value_info("bias_dph", TensorProto.FLOAT, [1, 1]))
    graph = helper.make_graph(nodes, "fogsf_step", inputs, outputs, inits)
    proto = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                              producer_name="fogsf", ir_version=IR_VERSION,
                              doc_string="fogsf-stream-2 streaming step: z, (h, c) per layer "
                                         "-> sf_ppm, new (h, c), sf_k")
    helper.set_model_props(proto, {"format": "fogsf-stream-2", "model_id": model.model_id,
                                   "decimation": str(model.decimation), **props})
    onnx.checker.check_model(proto, full_check=True)
    return proto


def rate_nodes(model: StreamModel) -> tuple[list[onnx.TensorProto], list[onnx.NodeProto]]:
    """rate_a [1, R] = Horner over q = Q-1 .. 0 of rate_w[:, q] in s0 (a Mul and an Add a
    power, float32 as the kernel's)."""
    w = model.weights[RATE_ARRAY]
    q = w.shape[1]
    inits = [numpy_helper.from_array(np.ascontiguousarray(w[:, j].reshape(1, -1)), f"rate_c{j}")
             for j in range(q)]
    nodes: list[onnx.NodeProto] = []
    acc = f"rate_c{q - 1}"
    for j in range(q - 2, -1, -1):
        nodes += [helper.make_node("Mul", [acc, "s0"], [f"rate_m{j}"]),
                  helper.make_node("Add", [f"rate_m{j}", f"rate_c{j}"], [f"rate_h{j}"])]
        acc = f"rate_h{j}"
    nodes.append(helper.make_node("Identity", [acc], ["rate_a"]))
    return inits, nodes


def rate_correct(corrected: np.ndarray, a: np.ndarray, inv_fs: np.float32
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The rate part per sample on finite corrected rates (float32, the contract's order):
    (corrected - e, RATE_CLAMPED flags), `a` [N, R] the held coefficients."""
    c = np.asarray(corrected, np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        x = c * inv_fs
    clamped = (x > F32(1)) | (x < F32(-1))
    x = np.clip(x, F32(-1), F32(1)).astype(np.float32)
    r = a.shape[1]
    p = np.zeros_like(c)
    if r >= 2:
        p = a[:, r - 1].astype(np.float32)
        for k in range(r - 2, 0, -1):
            p = (p * x).astype(np.float32) + a[:, k]
        p = ((p * x).astype(np.float32) * x).astype(np.float32)
    e = (p + (a[:, 0] * np.abs(x)).astype(np.float32)).astype(np.float32)
    return (c - e).astype(np.float32), np.where(clamped, FLAG_RATE_CLAMPED, 0).astype(np.uint32)


def bias_initializers(model: StreamModel) -> list[onnx.TensorProto]:
    """The bias head: bias_b [1], bias_w, bias_quad_w, bias_cube_w [F, 1]."""
    f, w = model.n_features, model.weights
    return [numpy_helper.from_array(w["bias_b"].reshape(1), "bias_b"),
            *(numpy_helper.from_array(w[n].reshape(f, 1), n)
              for n in ("bias_w", "bias_quad_w", "bias_cube_w"))]


def bias_nodes() -> list[onnx.NodeProto]:
    """bias_dph = bias_b + z bias_w + (z*z) bias_quad_w + (z*z*z) bias_cube_w, [1, 1]."""
    return [
        helper.make_node("Mul", ["z", "z"], ["bias_z_sq"]),
        helper.make_node("Mul", ["bias_z_sq", "z"], ["bias_z_cube"]),
        helper.make_node("MatMul", ["z", "bias_w"], ["bias_lin"]),
        helper.make_node("MatMul", ["bias_z_sq", "bias_quad_w"], ["bias_quad"]),
        helper.make_node("MatMul", ["bias_z_cube", "bias_cube_w"], ["bias_cube"]),
        helper.make_node("Add", ["bias_b", "bias_lin"], ["bias_1"]),
        helper.make_node("Add", ["bias_1", "bias_quad"], ["bias_2"]),
        helper.make_node("Add", ["bias_2", "bias_cube"], ["bias_dph"]),
    ]


def poly_initializers(model: StreamModel) -> list[onnx.TensorProto]:
    """quad_w [F, F] ([F, 1] with quad_diag), cube_w [F, 1] and the axis of the row sum."""
    f, w = model.n_features, model.weights
    if model.quad_diag:
        return [numpy_helper.from_array(w["quad_w"].reshape(f, 1), "quad_w"),
                numpy_helper.from_array(w["cube_w"].reshape(f, 1), "cube_w")]
    return [numpy_helper.from_array(w["quad_w"].reshape(f, f), "quad_w"),
            numpy_helper.from_array(w["cube_w"].reshape(f, 1), "cube_w"),
            numpy_helper.from_array(np.array([1], np.int64), "axis1")]


def poly_nodes(y_in: str, y_out: str, quad_diag: bool = False) -> list[onnx.NodeProto]:
    """y_out = y_in + z quad_w z^T + (z*z*z) cube_w, each [1, 1] (z is [1, F]); with
    quad_diag, (z*z) quad_w for the quadratic."""
    if quad_diag:
        return [
            helper.make_node("Mul", ["z", "z"], ["z_sq"]),
            helper.make_node("MatMul", ["z_sq", "quad_w"], ["quad_sum"]),
            helper.make_node("Mul", ["z_sq", "z"], ["z_cube"]),
            helper.make_node("MatMul", ["z_cube", "cube_w"], ["cube_sum"]),
            helper.make_node("Add", [y_in, "quad_sum"], ["y_quad"]),
            helper.make_node("Add", ["y_quad", "cube_sum"], [y_out]),
        ]
    return [
        helper.make_node("MatMul", ["z", "quad_w"], ["quad_zq"]),  # [1, F]: sum_i z_i Q_ij
        helper.make_node("Mul", ["quad_zq", "z"], ["quad_terms"]),
        helper.make_node("ReduceSum", ["quad_terms", "axis1"], ["quad_sum"], keepdims=1),
        helper.make_node("Mul", ["z", "z"], ["z_sq"]),
        helper.make_node("Mul", ["z_sq", "z"], ["z_cube"]),
        helper.make_node("MatMul", ["z_cube", "cube_w"], ["cube_sum"]),
        helper.make_node("Add", [y_in, "quad_sum"], ["y_quad"]),
        helper.make_node("Add", ["y_quad", "cube_sum"], [y_out]),
    ]


class OrtStepper:
    """onnxruntime stepping the exported model one call per model step, like firmware."""

    def __init__(self, proto: onnx.ModelProto, layers: int, hidden: int) -> None:
        import onnxruntime as ort

        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        opts.inter_op_num_threads = 1
        self.session = ort.InferenceSession(proto.SerializeToString(), opts,
                                            providers=["CPUExecutionProvider"])
        self.layers, self.hidden = layers, hidden
        self.in_names, self.out_names = state_names(layers)
        self.has_bias = any(o.name == "bias_dph" for o in proto.graph.output)
        props = {p.key: p.value for p in proto.metadata_props}
        self.has_rate = "rate_inv_fs" in props
        self.rate_inv_fs = F32(float(props.get("rate_inv_fs", "0")))
        self.rate_a = np.zeros(0, np.float32)  # the held a_r of the latest step
        self.rate_seq = np.zeros((0, 0), np.float32)
        self.bias_dph = 0.0  # the bias head's output of the latest step (0 without one)
        self.bias_dps = np.float32(0)  # bias_dph / 3600 of the latest step (float32)
        self.sf_k = np.float32(0)  # the correction's factor of the latest step (float32)
        self.bias_seq = np.zeros(0, np.float32)  # of the latest `run`
        self.k_seq = np.zeros(0, np.float32)
        self.bias_dps_seq = np.zeros(0, np.float32)
        self.reset()

    def reset(self) -> None:
        self.state = [np.zeros((1, self.hidden), np.float32) for _ in self.in_names]

    def step(self, z: np.ndarray, s0: float = 0.0) -> tuple[float, np.ndarray]:
        """One step (s0 = Tm - t_ref, read with a rate part): (sf_ppm, last layer's new h
        [H])."""
        feeds = {"z": np.asarray(z, np.float32).reshape(1, -1)}
        feeds.update(zip(self.in_names, self.state, strict=True))
        if self.has_rate:
            feeds["s0"] = np.array([[s0]], np.float32)
        names = ["sf_ppm", *self.out_names, "sf_k",
                 *(["bias_dps", "bias_dph"] if self.has_bias else [])]
        outs = self.session.run(names + (["rate_a"] if self.has_rate else []), feeds)
        if self.has_rate:
            self.rate_a = outs.pop()[0].astype(np.float32)
        if self.has_bias:
            self.bias_dph = float(outs.pop()[0, 0])
            self.bias_dps = np.float32(outs.pop()[0, 0])
        self.sf_k = np.float32(outs.pop()[0, 0])
        self.state = outs[1:]
        return float(outs[0][0, 0]), self.state[-2][0]

    def run(self, z_seq: np.ndarray, s0_seq: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
        """From reset over a sequence of z (and of s0 with a rate part): (sf_ppm [n], h_last
        [n, H]); the bias, sf_k, bias_dps and a_r per step are kept in bias_seq, k_seq,
        bias_dps_seq and rate_seq."""
        self.reset()
        n = z_seq.shape[0]
        s0 = np.zeros(n, np.float32) if s0_seq is None else np.asarray(s0_seq, np.float32)
        self.rate_seq = np.zeros((n, 0), np.float32)  # [n, R] once the first step gave R
        sf = np.empty(n, np.float32)
        hl = np.empty((n, self.hidden), np.float32)
        self.bias_seq = np.zeros(n, np.float32)
        self.k_seq = np.zeros(n, np.float32)
        self.bias_dps_seq = np.zeros(n, np.float32)
        for m in range(n):
            sf[m], hl[m] = self.step(z_seq[m], float(s0[m]))
            if self.has_rate:
                if m == 0:
                    self.rate_seq = np.zeros((n, self.rate_a.shape[0]), np.float32)
                self.rate_seq[m] = self.rate_a
            self.bias_seq[m] = self.bias_dph
            self.k_seq[m] = self.sf_k
            self.bias_dps_seq[m] = self.bias_dps
        return sf, hl

    def correct(self, gyro_dps: np.ndarray, decimation: int) -> tuple[np.ndarray, np.ndarray]:
        """The samples of the latest `run` (step m held over samples mD .. mD + D - 1)
        corrected as the kernel does, float32: d = g - bias_dps, d - d * sf_k, then with a
        rate part its polynomial; (corrected, GYRO_INVALID | RATE_CLAMPED flags)."""
        g = np.asarray(gyro_dps, np.float64).astype(np.float32)
        idx = np.arange(g.shape[0]) // decimation
        with np.errstate(all="ignore"):
            d = g - self.bias_dps_seq[idx]
            c = (d - d * self.k_seq[idx]).astype(np.float32)
        flags = np.zeros(g.shape[0], np.uint32)
        if self.has_rate:
            ok = np.isfinite(c)
            out, rflags = rate_correct(np.where(ok, c, F32(0)), self.rate_seq[idx],
                                       self.rate_inv_fs)
            c, flags = np.where(ok, out, c), np.where(ok, rflags, 0).astype(np.uint32)
        bad = ~np.isfinite(c)
        c[bad] = 0.0
        return c, (flags | np.where(bad, FLAG_GYRO_INVALID, 0)).astype(np.uint32)
