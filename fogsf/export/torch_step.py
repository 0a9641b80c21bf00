"""A torch module of the streaming step built from an artifact (to check ONNX against torch).

Like the ONNX step it takes z, so a model's feature map (full or `feat_diag`) is not in it."""

from __future__ import annotations

import torch

from fogsf.models.gate_order import onnx_to_torch_lstm
from fogsf.models.stream import StreamModel


class TorchStep(torch.nn.Module):
    """z [1, F], h [L, 1, H], c [L, 1, H] -> (sf_ppm [1, 1], h, c), via torch.nn.LSTM."""

    # the buffers __init__ registers (quad_w, cube_w with a polynomial head)
    head_w: torch.Tensor
    head_b: torch.Tensor
    skip_w: torch.Tensor
    out_scale: torch.Tensor
    out_offset: torch.Tensor
    quad_w: torch.Tensor
    cube_w: torch.Tensor

    def __init__(self, model: StreamModel) -> None:
        super().__init__()
        w = model.weights
        self.n_in = model.n_lstm_inputs
        self.lstm = torch.nn.LSTM(self.n_in, model.hidden, model.layers)
        with torch.no_grad():
            for layer in range(model.layers):
                parts = onnx_to_torch_lstm(w[f"lstm{layer}_w"], w[f"lstm{layer}_r"],
                                           w[f"lstm{layer}_b"])
                for name, arr in zip(("weight_ih", "weight_hh", "bias_ih", "bias_hh"), parts,
                                     strict=True):
                    getattr(self.lstm, f"{name}_l{layer}").copy_(torch.from_numpy(arr))
        self.poly_head, self.quad_diag = model.poly_head, model.quad_diag
        names = ("head_w", "head_b", "skip_w", "out_scale", "out_offset")
        for name in names + (("quad_w", "cube_w") if model.poly_head else ()):
            self.register_buffer(name, torch.from_numpy(w[name].copy()))

    def forward(self, z: torch.Tensor, h: torch.Tensor, c: torch.Tensor
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        y_seq, (h_new, c_new) = self.lstm(z[:, :self.n_in].unsqueeze(0), (h, c))
        y = y_seq[0] @ self.head_w + self.head_b + z @ self.skip_w
        if self.poly_head:
            quad = ((z * z) @ self.quad_w if self.quad_diag
                    else ((z @ self.quad_w) * z).sum(-1))
            y = y + quad + (z * z * z) @ self.cube_w
        return (y * self.out_scale + self.out_offset).reshape(1, 1), h_new, c_new
