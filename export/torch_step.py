"""A torch module of the streaming step built from an artifact (to check ONNX against torch)."""

from __future__ import annotations

import torch

from trainer.stream import StreamModel, onnx_to_torch_lstm


class TorchStep(torch.nn.Module):
    """z [1, F], h [L, 1, H], c [L, 1, H] -> (sf_ppm [1, 1], h, c), via torch.nn.LSTM."""

    def __init__(self, model: StreamModel) -> None:
        super().__init__()
        w = model.weights
        self.lstm = torch.nn.LSTM(model.n_features, model.hidden, model.layers)
        with torch.no_grad():
            for layer in range(model.layers):
                parts = onnx_to_torch_lstm(w[f"lstm{layer}_w"], w[f"lstm{layer}_r"],
                                           w[f"lstm{layer}_b"])
                for name, arr in zip(("weight_ih", "weight_hh", "bias_ih", "bias_hh"), parts,
                                     strict=True):
                    getattr(self.lstm, f"{name}_l{layer}").copy_(torch.from_numpy(arr))
        for name in ("head_w", "head_b", "skip_w", "out_scale", "out_offset"):
            self.register_buffer(name, torch.from_numpy(w[name].copy()))

    def forward(self, z: torch.Tensor, h: torch.Tensor, c: torch.Tensor
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        y_seq, (h_new, c_new) = self.lstm(z.unsqueeze(0), (h, c))
        y = y_seq[0] @ self.head_w + self.head_b + z @ self.skip_w
        return (y * self.out_scale + self.out_offset).reshape(1, 1), h_new, c_new
