"""The kernel's generic LSTM cell (runtime sizes) against ONNX's own LSTM node cases.

The cases ship in the onnx wheel as generators (onnx.backend.test.case.node.lstm): each
`export_*` builds inputs and expected outputs with ONNX's reference LSTMHelper and hands them
to `expect`. We capture those calls and drive fogsf_lstm_cell over the sequence, per batch
entry; reverse and bidirectional runs are the same forward cell over the flipped sequence.
"""

from __future__ import annotations

import numpy as np
import pytest
from kernel_helpers import kernel_for
from onnx import helper
from onnx.backend.test.case.node import lstm as onnx_lstm

from fogsf.models import samples

CASES = ["export_defaults", "export_initial_bias", "export_peepholes", "export_batchwise",
         "export_reverse", "export_bidirectional"]


@pytest.fixture(scope="session")
def kroot(tmp_path_factory):
    return tmp_path_factory.mktemp("kernels")


def capture(case: str, monkeypatch) -> list[tuple]:  # noqa: ANN001
    calls: list[tuple] = []
    monkeypatch.setattr(onnx_lstm, "expect",
                        lambda node, inputs, outputs, name, **kw: calls.append(
                            (node, inputs, outputs, name)))
    getattr(onnx_lstm.LSTM, case)()
    return calls


def run_cell(kernel, node, inputs: list[np.ndarray]) -> dict[str, np.ndarray]:  # noqa: ANN001
    attrs = {a.name: helper.get_attribute_value(a) for a in node.attribute}
    named = {name: arr for name, arr in zip(node.input, inputs, strict=False) if name}
    assert set(attrs) <= {"hidden_size", "layout", "direction"}, f"untested attributes {attrs}"
    layout = attrs.get("layout", 0)
    direction = attrs.get("direction", b"forward")
    direction = direction.decode() if isinstance(direction, bytes) else direction
    x = named["X"]
    if layout == 1:
        x = np.swapaxes(x, 0, 1)
    seq, batch, _ = x.shape
    w, r = named["W"], named["R"]
    dirs, hid = w.shape[0], r.shape[-1]
    h0 = named.get("initial_h", np.zeros((dirs, batch, hid), np.float32))
    c0 = named.get("initial_c", np.zeros((dirs, batch, hid), np.float32))
    if layout == 1 and "initial_h" in named:
        h0, c0 = np.swapaxes(h0, 0, 1), np.swapaxes(c0, 0, 1)
    if "sequence_lens" in named:
        assert np.all(named["sequence_lens"] == seq), "only full-length sequences"
    y = np.zeros((seq, dirs, batch, hid), np.float32)
    y_h = np.zeros((dirs, batch, hid), np.float32)
    y_c = np.zeros((dirs, batch, hid), np.float32)
    for d in range(dirs):
        flip = direction == "reverse" or (direction == "bidirectional" and d == 1)
        order = range(seq - 1, -1, -1) if flip else range(seq)
        b = named["B"][d] if "B" in named else None
        p = named["P"][d] if "P" in named else None
        for n in range(batch):
            h, c = h0[d, n], c0[d, n]
            for t in order:
                h, c = kernel.lstm_cell(w[d], r[d], b, p, x[t, n], h, c)
                y[t, d, n] = h
            y_h[d, n], y_c[d, n] = h, c
    if layout == 1:
        y, y_h, y_c = np.transpose(y, [2, 0, 1, 3]), np.swapaxes(y_h, 0, 1), np.swapaxes(y_c, 0, 1)
    return {"Y": y, "Y_h": y_h, "Y_c": y_c}


@pytest.mark.parametrize("case", CASES)
def test_generic_cell_passes_onnx_lstm_node_case(case, monkeypatch, kroot) -> None:
    kernel = kernel_for(samples.random_model(seed=0), kroot)
    calls = capture(case, monkeypatch)
    assert calls, f"{case} produced no test case"
    for node, inputs, outputs, name in calls:
        got = run_cell(kernel, node, inputs)
        produced = [o for o in node.output if o]
        assert len(produced) == len(outputs)
        for out_name, want in zip(produced, outputs, strict=True):
            np.testing.assert_allclose(got[out_name], want, rtol=1e-5, atol=1e-6,
                                       err_msg=f"{name}: output {out_name}")


def test_generic_cell_matches_reference_on_random_sizes(kroot) -> None:
    """Random sizes, peepholes and biases: C cell vs ONNX's LSTMHelper (float64 maths)."""
    kernel = kernel_for(samples.random_model(seed=0), kroot)
    rng = np.random.default_rng(17)
    for trial in range(8):
        n_in, hid, seq = (int(v) for v in rng.integers(1, 24, 3))
        w = rng.normal(0, 0.4, (1, 4 * hid, n_in)).astype(np.float32)
        r = rng.normal(0, 0.4, (1, 4 * hid, hid)).astype(np.float32)
        b = rng.normal(0, 0.3, (1, 8 * hid)).astype(np.float32)
        p = rng.normal(0, 0.3, (1, 3 * hid)).astype(np.float32)
        x = rng.normal(0, 1, (seq, 1, n_in)).astype(np.float32)
        h0 = rng.normal(0, 0.5, (1, 1, hid)).astype(np.float32)
        c0 = rng.normal(0, 0.5, (1, 1, hid)).astype(np.float32)
        ref = onnx_lstm.LSTMHelper(X=x.astype(np.float64), W=w.astype(np.float64),
                                   R=r.astype(np.float64), B=b.astype(np.float64),
                                   P=p.astype(np.float64), initial_h=h0.astype(np.float64),
                                   initial_c=c0.astype(np.float64))
        y_ref, _, c_ref = ref.step()
        h, c = h0[0, 0], c0[0, 0]
        for t in range(seq):
            h, c = kernel.lstm_cell(w[0], r[0], b[0], p[0], x[t, 0], h, c)
            np.testing.assert_allclose(h, y_ref[t, 0, 0], atol=3e-6,
                                       err_msg=f"trial {trial} step {t}")
        np.testing.assert_allclose(c, c_ref[0, 0], atol=1e-5, rtol=1e-5, err_msg=f"trial {trial}")
