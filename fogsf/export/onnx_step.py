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
"""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from fogsf.models.stream import StreamModel

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
                                   "decimation": str(model.decimation)})
    onnx.checker.check_model(proto, full_check=True)
    return proto


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
        self.bias_dph = 0.0  # the bias head's output of the latest step (0 without one)
        self.bias_dps = np.float32(0)  # bias_dph / 3600 of the latest step (float32)
        self.sf_k = np.float32(0)  # the correction's factor of the latest step (float32)
        self.bias_seq = np.zeros(0, np.float32)  # of the latest `run`
        self.k_seq = np.zeros(0, np.float32)
        self.bias_dps_seq = np.zeros(0, np.float32)
        self.reset()

    def reset(self) -> None:
        self.state = [np.zeros((1, self.hidden), np.float32) for _ in self.in_names]

    def step(self, z: np.ndarray) -> tuple[float, np.ndarray]:
        """One step: (sf_ppm, last layer's new h [H])."""
        feeds = {"z": np.asarray(z, np.float32).reshape(1, -1)}
        feeds.update(zip(self.in_names, self.state, strict=True))
        names = ["sf_ppm", *self.out_names, "sf_k",
                 *(["bias_dps", "bias_dph"] if self.has_bias else [])]
        outs = self.session.run(names, feeds)
        if self.has_bias:
            self.bias_dph = float(outs.pop()[0, 0])
            self.bias_dps = np.float32(outs.pop()[0, 0])
        self.sf_k = np.float32(outs.pop()[0, 0])
        self.state = outs[1:]
        return float(outs[0][0, 0]), self.state[-2][0]

    def run(self, z_seq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """From reset over a sequence of z: (sf_ppm [n], h_last [n, H]); the bias, sf_k and
        bias_dps per step are kept in bias_seq, k_seq and bias_dps_seq."""
        self.reset()
        n = z_seq.shape[0]
        sf = np.empty(n, np.float32)
        hl = np.empty((n, self.hidden), np.float32)
        self.bias_seq = np.zeros(n, np.float32)
        self.k_seq = np.zeros(n, np.float32)
        self.bias_dps_seq = np.zeros(n, np.float32)
        for m in range(n):
            sf[m], hl[m] = self.step(z_seq[m])
            self.bias_seq[m] = self.bias_dph
            self.k_seq[m] = self.sf_k
            self.bias_dps_seq[m] = self.bias_dps
        return sf, hl
