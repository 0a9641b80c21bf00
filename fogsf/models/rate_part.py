"""The optional rate part of the streaming model (docs/stream-contract.md, "Optional rate
part") in numpy, op for op as the kernel computes it in float32: its coefficients at each
model step (`rate_coefficients`) and its correction of each sample (`apply_rate`)."""

from __future__ import annotations

import numpy as np

from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_GYRO_INVALID, FLAG_RATE_CLAMPED
from fogsf.models.stream_format import RATE_ARRAY

F32 = np.float32


def inverse_full_scale(model: StreamModel) -> np.float32:
    """1 / FS rounded once from double to float32, the kernel's constant."""
    return F32(1.0 / model.rate_fs_dps)


def rate_coefficients(model: StreamModel, s0: np.ndarray) -> np.ndarray:
    """[n_steps, R] float32: a_r = Horner over q = Q-1 .. 0 of rate_w[r, q] in s0 = Tm - t_ref
    (each model step's s[0])."""
    w = np.asarray(model.weights[RATE_ARRAY], np.float32)
    s = np.asarray(s0, np.float32)[:, None]
    a = np.repeat(w[None, :, -1], s.shape[0], axis=0)
    for q in range(w.shape[1] - 2, -1, -1):
        a = (a * s).astype(np.float32) + w[None, :, q]
    return a.astype(np.float32)


def apply_rate(model: StreamModel, corrected: np.ndarray, a: np.ndarray, flags: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """(corrected float32, RATE_CLAMPED and GYRO_INVALID flags) per sample, `a` the held
    coefficients [N, R]: x = c * (1/FS) clamped to [-1, 1] (RATE_CLAMPED beyond), p = Horner
    of a_{R-1} .. a_1 in x, then (p * x) * x (0 when R = 1), e = p + a_0 * |x|, out = c - e
    (not finite: 0.0 and GYRO_INVALID). A sample already GYRO_INVALID (its corrected is 0.0)
    passes unchanged."""
    c = np.asarray(corrected, np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        x = (c * inverse_full_scale(model)).astype(np.float32)
    ok = (np.asarray(flags) & FLAG_GYRO_INVALID) == 0
    clamped = ok & ((x > F32(1)) | (x < F32(-1)))
    x = np.clip(x, F32(-1), F32(1)).astype(np.float32)
    r = a.shape[1]
    if r >= 2:
        p = a[:, r - 1].copy()
        for k in range(r - 2, 0, -1):
            p = (p * x).astype(np.float32) + a[:, k]
        p = ((p * x).astype(np.float32) * x).astype(np.float32)
    else:
        p = np.zeros_like(c)
    with np.errstate(over="ignore", invalid="ignore"):
        e = (p + (a[:, 0] * np.abs(x)).astype(np.float32)).astype(np.float32)
        out = np.where(ok, (c - e).astype(np.float32), c).astype(np.float32)
    bad = ok & ~np.isfinite(out)  # a broken artifact's coefficients: 0.0 and GYRO_INVALID
    out[bad] = 0.0
    flags = np.where(clamped & ~bad, np.uint32(FLAG_RATE_CLAMPED), np.uint32(0))
    return out, (flags | np.where(bad, np.uint32(FLAG_GYRO_INVALID), np.uint32(0))).astype(
        np.uint32)
