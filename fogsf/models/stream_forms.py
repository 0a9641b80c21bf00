"""Equivalent forms of a streaming model artifact, what `fogsf train` writes: a diagonal
feature map stored as its diagonal (`diagonal_features`, bit for bit the same outputs), a
play feature's row moved onto its own play state (`pure_play_rows`, exact algebra rounded
once to float32)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fogsf.models.stream import StreamModel


def diagonal_features(model: StreamModel) -> StreamModel:
    """The same model with `feat_diag`: feat_w [F] the diagonal of its feat_w (the same
    float32 bits), when feat_w is square, [F, 1+K+P], with every entry off the diagonal 0
    (+0.0 or -0.0) and no feat_b entry is -0.0; else `model` itself (also when it already
    has feat_diag). The result gives every output bit for bit as `model` does.

    Why: the kernel computes z_i = feat_b[i], then + feat_w[i, j] * s_j for j ascending; s is
    always finite (the front end clamps the temperature), so each off-diagonal term is an
    exact +0.0 or -0.0, and x + (+-0.0) is x for every x but -0.0 (-0.0 + +0.0 = +0.0). With
    feat_b[i] not -0.0 the running sum is never -0.0: feat_b[i] before the diagonal term,
    feat_b[i] + feat_w[i, i] * s_i after it (-0.0 only when both are), so the zero terms
    change nothing and z_i is the diagonal form's feat_b[i] + feat_w[i] * s_i. With
    feat_b[i] = -0.0 the sign of a zero z_i would hang on the signs of the other s_j: such
    a model stays dense."""
    if model.feat_diag:
        return model
    w, b = model.weights["feat_w"], model.weights["feat_b"]
    f = model.n_features
    if w.shape != (f, 1 + model.n_filters + model.n_plays) or w.shape != (f, f):
        return model
    if np.any(w[~np.eye(f, dtype=bool)] != 0) or np.any((b == 0) & np.signbit(b)):
        return model
    weights = dict(model.weights)
    weights["feat_w"] = np.diagonal(w).astype(np.float32)  # a copy, the same bits
    out = replace(model, weights=weights, feat_diag=True)
    out.validate()
    return out


def pure_play_rows(model: StreamModel) -> StreamModel:
    """The same model with every play feature's row of feat_w on its own play state only, so
    that `diagonal_features` applies: a play feature that mixes in other states (the
    hysteresis term's play(x) - x) has those states' part moved to the linear weights
    (skip_w, bias_w) of the features that are those states alone, and their offsets to
    head_b and bias_b. Exact algebra, rounded once to float32 (outputs within float32
    rounding of the model's, not bit for bit). Applies when every other row of feat_w is
    diagonal, the play features enter linearly only (no LSTM input, quadratic or cube on
    them) and feat_w is square; else returns `model` itself."""
    p = model.n_plays
    n = 1 + model.n_filters + p
    w = model.weights["feat_w"]
    if model.feat_diag or p == 0 or w.shape != (n, n) or model.n_features != n:
        return model
    wts = model.weights
    off = w.astype(np.float64) * (1.0 - np.eye(n))
    plays, others = np.arange(n - p, n), np.arange(n - p)
    diag = np.diagonal(w).astype(np.float64)
    linear_only: bool | np.bool_ = model.n_lstm_inputs <= n - p and np.all(diag[others] != 0)
    if model.poly_head:
        q = wts["quad_w"]
        linear_only &= not (q[plays].any() if model.quad_diag else
                            q[plays].any() or q[:, plays].any()) and not wts["cube_w"][plays].any()
    if model.bias_head:
        linear_only &= not (wts["bias_quad_w"][plays].any() or wts["bias_cube_w"][plays].any())
    if off[others].any() or off[np.ix_(plays, plays)].any() or not linear_only:
        return model
    b = wts["feat_b"].astype(np.float64)
    ratio = off[np.ix_(plays, others)] / diag[others]  # s_j = (z_j - b_j) / w_jj
    out = dict(wts)
    for lin, const in (("skip_w", "head_b"), ("bias_w", "bias_b")):
        if lin not in wts:
            continue
        v = wts[lin].astype(np.float64)
        moved = v[plays] @ ratio
        v[others] += moved
        out[lin] = v.astype(np.float32)
        out[const] = (wts[const].astype(np.float64) - moved @ b[others]).astype(np.float32)
    fw = w.copy()
    fw[np.ix_(plays, others)] = 0.0
    out["feat_w"] = fw
    res = replace(model, weights=out)
    res.validate()
    return res
