"""Torch networks: the streaming LSTM of the firmware contract, and the paper's MLP baseline.

`StreamNet` is the contract's model step run over a sequence: L LSTM layers on z, a linear
head on the last layer's h, plus a linear skip from z; the output times `out_scale` plus
`out_offset` is the SF error in ppm vs nominal. `to_stream_model` writes it in the artifact
format (ONNX gate order) that the exporter and the C kernel read.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from fogsf.models.features import FeatureSpec, Normaliser
from fogsf.models.front_end import FrontEnd
from fogsf.models.gate_order import torch_to_onnx_lstm
from fogsf.models.stream import StreamModel


class StreamNet(nn.Module):
    """LSTM layers, a linear head on the last h and a linear skip from z; with `poly` also
    the contract's polynomial head: sum_ij quad_ij z_i z_j + sum_i cube_i z_i^3 (the physics
    least-squares model carried exactly, so the LSTM learns only what it leaves).
    `lstm_inputs` N: the first LSTM layer reads z[..., :N] only (None: all F);
    `quad_diag`: quad is the diagonal [F] only (sum_i quad_i z_i^2)."""

    def __init__(self, n_features: int, layers: int, hidden: int, poly: bool = False,
                 cubes: bool = True, lstm_inputs: int | None = None,
                 quad_diag: bool = False) -> None:
        super().__init__()
        self.layers, self.hidden, self.poly = layers, hidden, poly
        self.n_features = n_features
        self.lstm_inputs = n_features if lstm_inputs is None else int(lstm_inputs)
        if not 1 <= self.lstm_inputs <= n_features:
            raise ValueError(f"lstm_inputs must lie in [1, {n_features}], got {lstm_inputs}")
        self.quad_diag = bool(poly and quad_diag)
        self.lstm = nn.LSTM(self.lstm_inputs, hidden, layers, batch_first=True)
        self.head = nn.Linear(hidden, 1)
        self.skip = nn.Linear(n_features, 1, bias=False)
        if poly:
            self.quad = nn.Parameter(torch.zeros(n_features) if self.quad_diag
                                     else torch.zeros(n_features, n_features))
            self.cube = nn.Parameter(torch.zeros(n_features), requires_grad=cubes)

    def forward(self, z: torch.Tensor,
                state: tuple[torch.Tensor, torch.Tensor] | None = None
                ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """z [B, T, F] -> (normalised output [B, T], (h, c))."""
        x = z if self.lstm_inputs == self.n_features else z[..., :self.lstm_inputs]
        out, state = self.lstm(x, state)
        y = self.head(out).squeeze(-1) + self.skip(z).squeeze(-1)
        if self.poly:
            quad = (z * z) @ self.quad if self.quad_diag else ((z @ self.quad) * z).sum(-1)
            y = y + quad + (z * z * z) @ self.cube
        return y, state


class MLP(nn.Module):
    """The paper's MLP baseline: a static map of the features (no memory)."""

    def __init__(self, n_features: int, hidden: tuple[int, ...] = (32, 32)) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        n_in = n_features
        for h in hidden:
            layers += [nn.Linear(n_in, h), nn.Tanh()]
            n_in = h
        layers.append(nn.Linear(n_in, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return self.net(z).squeeze(-1)


def count_params(net: nn.Module) -> int:
    return int(sum(p.numel() for p in net.parameters()))


def to_stream_model(net: StreamNet, kind: str, spec: FeatureSpec, norm: Normaliser,
                    fe: FrontEnd, out_offset: float, out_scale: float,
                    extra: dict | None = None) -> StreamModel:
    """The trained network as a firmware artifact (docs/stream-contract.md)."""
    weights: dict[str, np.ndarray] = {
        "filter_alpha": np.asarray(fe.filter_alpha, np.float32),
        "feat_w": norm.feat_w.astype(np.float32),
        "feat_b": norm.feat_b.astype(np.float32),
    }
    sd = {k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}
    for layer in range(net.layers):
        w, r, b = torch_to_onnx_lstm(sd[f"lstm.weight_ih_l{layer}"],
                                     sd[f"lstm.weight_hh_l{layer}"],
                                     sd[f"lstm.bias_ih_l{layer}"],
                                     sd[f"lstm.bias_hh_l{layer}"])
        weights[f"lstm{layer}_w"], weights[f"lstm{layer}_r"], weights[f"lstm{layer}_b"] = w, r, b
    weights["head_w"] = sd["head.weight"][0].astype(np.float32)
    weights["head_b"] = sd["head.bias"].astype(np.float32)
    weights["skip_w"] = sd["skip.weight"][0].astype(np.float32)
    if net.poly:
        weights["quad_w"] = sd["quad"].astype(np.float32)
        weights["cube_w"] = sd["cube"].astype(np.float32)
    weights["out_scale"] = np.array([out_scale], np.float32)
    weights["out_offset"] = np.array([out_offset], np.float32)
    model = StreamModel(model=kind, decimation=fe.decimation, t_ref_c=fe.t_ref_c,
                        t_min_c=fe.t_min_c, t_max_c=fe.t_max_c,
                        stuck_samples=fe.stuck_samples, filter_tau_s=list(spec.taus_s),
                        n_features=spec.n_features, layers=net.layers, hidden=net.hidden,
                        weights=weights, poly_head=net.poly, sample_dt_s=fe.sample_dt_s,
                        lstm_inputs=(net.lstm_inputs if net.lstm_inputs != net.n_features
                                     else None),
                        quad_diag=net.quad_diag,
                        play_width_c=[float(w) for w in fe.play_width_c],
                        play_source_w=[[float(v) for v in r] for r in fe.play_source_w],
                        extra={"feature_names": list(spec.names),
                                                **(extra or {})})
    model.validate()
    return model
