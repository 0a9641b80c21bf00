"""LSTM gate order: torch.nn.LSTM stacks its gates as (i, f, g, o), ONNX as (i, o, f, c) with
c == g; the converters between torch's weight_ih, weight_hh, bias_ih, bias_hh and ONNX's W,
R, B."""

from __future__ import annotations

import numpy as np

_TORCH_TO_ONNX = (0, 3, 1, 2)
_ONNX_TO_TORCH = (0, 2, 3, 1)


def _reorder(a: np.ndarray, order: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(a)
    blocks = np.split(a, 4, axis=0)
    return np.concatenate([blocks[k] for k in order], axis=0)


def torch_to_onnx_lstm(weight_ih: np.ndarray, weight_hh: np.ndarray, bias_ih: np.ndarray,
                       bias_hh: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """torch (i,f,g,o) -> ONNX (W [4H,in], R [4H,H], B [8H]) in gate order (i,o,f,c)."""
    w = _reorder(weight_ih, _TORCH_TO_ONNX)
    r = _reorder(weight_hh, _TORCH_TO_ONNX)
    b = np.concatenate([_reorder(bias_ih, _TORCH_TO_ONNX), _reorder(bias_hh, _TORCH_TO_ONNX)])
    return w.astype(np.float32), r.astype(np.float32), b.astype(np.float32)


def onnx_to_torch_lstm(w: np.ndarray, r: np.ndarray, b: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ONNX (W, R, B) -> torch (weight_ih, weight_hh, bias_ih, bias_hh)."""
    hid4 = np.asarray(w).shape[0]
    b = np.asarray(b)
    return (_reorder(w, _ONNX_TO_TORCH).astype(np.float32),
            _reorder(r, _ONNX_TO_TORCH).astype(np.float32),
            _reorder(b[:hid4], _ONNX_TO_TORCH).astype(np.float32),
            _reorder(b[hid4:], _ONNX_TO_TORCH).astype(np.float32))
