"""The nets fitted on one feature spec (torch at the top: `fit_spec` loads this module for
the mlp and the LSTM models only): the paper's MLP, and the streaming LSTM with its
least-squares head, written as the firmware artifact."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import torch

from fogsf.models.features import FeatureSpec, SeqData
from fogsf.models.nets import count_params, to_stream_model
from fogsf.models.structures.lag_bank import BankFit
from fogsf.models.structures.physics_nodes import NodeFit
from fogsf.training.fitted_model import Fitted
from fogsf.training.inputs import TrainingInputs
from fogsf.training.net.config import LSTMConfig, MLPConfig
from fogsf.training.net.loops import predict_stream, train_mlp, train_stream
from fogsf.training.options import TrainOptions


def fit_mlp(opts: TrainOptions, spec: FeatureSpec, ti: TrainingInputs) -> Fitted:
    """The paper's MLP on (T, filtered dT/dt), full batch (no firmware form)."""
    norm, offset, scale = ti.norm, ti.offset, ti.scale
    net, hist = train_mlp(ti.data, ti.z, MLPConfig(seed=opts.seed), offset, scale,
                          opts.progress)

    def predict(d: SeqData) -> np.ndarray:
        with torch.no_grad():
            out = net(torch.from_numpy(norm.apply(d.s))).numpy().astype(np.float64)
        return out * scale + offset

    n = count_params(net)
    return Fitted(opts.model, spec, ti.fe, predict, n, 4 * n, {"history": hist.as_dict()},
                  torch_state=net.state_dict())


def fit_lstm(opts: TrainOptions, spec: FeatureSpec, ti: TrainingInputs, lstm_cfg: LSTMConfig,
             head: BankFit | NodeFit | None) -> Fitted:
    """The streaming LSTM (on what `head`, the least-squares part carried exactly in its
    polynomial head, leaves), and its firmware artifact."""
    kind, norm, offset, scale = opts.model, ti.norm, ti.offset, ti.scale
    net, hist = train_stream(ti.data, ti.z, lstm_cfg, offset, scale, opts.progress, head)
    info: dict = {"history": hist.as_dict(), "hyper": asdict(lstm_cfg)}
    structure = None
    if isinstance(head, NodeFit):
        structure = "physics-nodes"
        info["physics_nodes"] = {"taus_s": list(head.taus_s), "ridge_lambda": head.lam,
                                 "dof": head.dof}
    elif head is not None:
        structure = "lag-bank"
        info["lag_bank"] = {"ridge_lambda": head.lam, "dof": head.dof,
                            "cross_terms": bool(head.quad.ndim == 2)}
    sm = to_stream_model(net, kind, spec, norm, ti.fe, offset, scale,
                         extra={"hyper": asdict(lstm_cfg),
                                **({"structure": structure} if structure else {})})
    n = sm.params  # the artifact's count, as `fogsf export` prints it (filter alphas and the
    # polynomial head included; the torch net holds the LSTM and linear head only)
    return Fitted(kind, spec, ti.fe, lambda d: predict_stream(net, norm.apply(d.s)) * scale
                  + offset, n, 4 * n, info, stream_model=sm, torch_state=net.state_dict())
