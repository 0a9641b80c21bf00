"""The bias model in the stream-model artifact: joined to the SF model's artifact as its
bias head (`with_bias_head`; the artifact gains the bias's own filters and features, every SF
weight on them zero, where the bias reads more than the SF model's z), or alone as a bias-only
artifact whose SF part is exactly zero (`bias_only_stream_model`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fogsf.models.stream import StreamModel
from fogsf.models.stream_forms import diagonal_features
from fogsf.training.bias.features import FeatureMap
from fogsf.training.bias.model import BiasModel


def with_bias_head(sm: StreamModel, model: BiasModel) -> StreamModel:
    """The artifact with the bias model as its bias head (float32, deg/h); the bias model
    must read the artifact's own z (`feature_map_of(sm, ...)`), or that z followed by
    features of its own (`with_rows`), which the artifact then gains."""
    if model.fm.feat_w.shape[0] > sm.n_features:
        sm = _widened(sm, model.fm)
    if model.fm.feat_w.tobytes() != sm.weights["feat_w"].tobytes():
        raise ValueError("the bias model reads other features than the artifact")
    f = model.fit
    weights = dict(sm.weights)
    weights.update({"bias_b": np.array([f.intercept], np.float32),
                    "bias_w": f.lin.astype(np.float32),
                    "bias_quad_w": f.quad.astype(np.float32),
                    "bias_cube_w": f.cube.astype(np.float32)})
    out = replace(sm, weights=weights, bias_head=True, extra=dict(sm.extra))
    out.validate()
    return out


def _widened(sm: StreamModel, fm: FeatureMap) -> StreamModel:
    """The artifact with `fm`'s filters and features after its own (`with_rows`): every SF
    weight on them zero, the LSTM reading the features it read, so sf_ppm is the same."""
    f, k = sm.n_features, sm.n_filters
    f2, k2 = fm.feat_w.shape[0], len(fm.fe.filter_tau_s)
    if (list(fm.fe.filter_tau_s[:k]) != list(sm.filter_tau_s) or fm.fe.filter_alpha[:k].tobytes()
            != sm.weights["filter_alpha"].tobytes() or fm.feat_w[:f].tobytes()
            != np.insert(sm.weights["feat_w"], [1 + k] * (k2 - k), 0.0, axis=1).tobytes()
            or fm.feat_b[:f].tobytes() != sm.weights["feat_b"].tobytes()
            or list(fm.fe.play_width_c) != list(sm.play_width_c)
            or fm.fe.decimation != sm.decimation):
        raise ValueError("the bias model's features do not extend the artifact's")
    w = dict(sm.weights)
    pad = np.zeros(f2 - f, np.float32)
    w.update({"filter_alpha": fm.fe.filter_alpha, "feat_w": fm.feat_w, "feat_b": fm.feat_b,
              "skip_w": np.concatenate([w["skip_w"], pad])})
    if sm.poly_head:
        w["cube_w"] = np.concatenate([w["cube_w"], pad])
        w["quad_w"] = (np.concatenate([w["quad_w"], pad]) if sm.quad_diag
                       else np.pad(w["quad_w"], ((0, f2 - f), (0, f2 - f))))
    extra = dict(sm.extra)
    if isinstance(extra.get("feature_names"), list) and len(fm.names) == f2:
        extra["feature_names"] = [*extra["feature_names"], *fm.names[f:]]
    out = replace(sm, weights=w, filter_tau_s=list(fm.fe.filter_tau_s), n_features=f2,
                  lstm_inputs=sm.n_lstm_inputs, extra=extra,
                  play_source_w=[list(r) for r in fm.fe.play_source_w])
    out.validate()
    return out


def bias_only_stream_model(model: BiasModel) -> StreamModel:
    """A bias-only artifact: the bias head on the bank's z, and an SF part that is exactly
    zero (a 1 x 1 LSTM reading z[0:1] with zero weights, zero head: sf_ppm = 0); its feature
    map as its diagonal (`feat_diag`) where it is one, as `fogsf train` writes SF models."""
    fm, f = model.fm, model.fm.feat_w.shape[0]
    zeros = {"lstm0_w": (4, 1), "lstm0_r": (4, 1), "lstm0_b": (8,), "head_w": (1,),
             "head_b": (1,), "skip_w": (f,), "out_offset": (1,)}
    weights = {k: np.zeros(s, np.float32) for k, s in zeros.items()}
    weights.update({"filter_alpha": np.asarray(fm.fe.filter_alpha, np.float32),
                    "feat_w": fm.feat_w, "feat_b": fm.feat_b,
                    "out_scale": np.ones(1, np.float32)})
    sm = StreamModel(model="bias", decimation=fm.fe.decimation, t_ref_c=fm.fe.t_ref_c,
                     t_min_c=fm.fe.t_min_c, t_max_c=fm.fe.t_max_c,
                     stuck_samples=fm.fe.stuck_samples,
                     filter_tau_s=list(fm.fe.filter_tau_s), n_features=f, layers=1, hidden=1,
                     weights=weights, sample_dt_s=fm.fe.sample_dt_s, lstm_inputs=1,
                     extra={"structure": "bias-only"})
    return diagonal_features(with_bias_head(sm, model))
