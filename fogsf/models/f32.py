"""The C kernel's float32 arithmetic in numpy, op for op: its own exp, sigmoid and tanh
(Cephes expf / tanhf; the kernel calls no libm, so host and Cortex-M4F give the same bits)."""

from __future__ import annotations

import numpy as np

F32 = np.float32

# --- activations: float32, op for op as firmware/c/fogsf.c (Cephes expf / tanhf) ---------
EXP_LO = F32(-87.0)
EXP_HI = F32(88.0)
LOG2E = F32(1.44269502)
LN2_HI = F32(0.693359375)
LN2_LO = F32(-0.000212194442)
EXP_P = tuple(F32(v) for v in (0.000198756912, 0.00139819994, 0.00833345205,
                                0.0416657962, 0.166666657, 0.500000012))
TANH_SMALL = F32(0.625)
TANH_CLAMP = F32(10.0)
TANH_P = tuple(F32(v) for v in (-0.00570498873, 0.0206390880, -0.0537397154,
                                 0.133314422, -0.333332818))
HALF = F32(0.5)
ONE = F32(1.0)
TWO = F32(2.0)


def _f32(x: np.ndarray | float) -> np.ndarray:
    return np.asarray(x, dtype=np.float32)


def exp_f32(x: np.ndarray | float) -> np.ndarray:
    """exp(x) in float32, as the kernel computes it (NaN counts as -87; result within ~2 ulp)."""
    x = _f32(x)
    x = np.where(x > EXP_LO, x, EXP_LO)  # NaN -> EXP_LO, as `if (!(x > lo)) x = lo;`
    x = np.where(x > EXP_HI, EXP_HI, x)
    t = x * LOG2E
    n = np.trunc(t + np.where(t >= 0, HALF, -HALF)).astype(np.int32)
    nf = n.astype(np.float32)
    r = (x - nf * LN2_HI) - nf * LN2_LO
    z = r * r
    p = EXP_P[0]
    for coef in EXP_P[1:]:
        p = p * r + coef
    e = (p * z + r) + ONE
    scale = ((n + 127).astype(np.uint32) << np.uint32(23)).view(np.float32)
    return _f32(e * scale)


def sigmoid_f32(x: np.ndarray | float) -> np.ndarray:
    """1 / (1 + exp(-x)) in float32 with the kernel's exp."""
    x = _f32(x)
    return _f32(ONE / (ONE + exp_f32(-x)))


def tanh_f32(x: np.ndarray | float) -> np.ndarray:
    """tanh in float32: odd polynomial for |x| <= 0.625, else 1 - 2 / (exp(2|x|) + 1).

    x is first clamped to [-10, 10] (tanh(10) rounds to 1.0f anyway); NaN counts as -10.
    """
    x = _f32(x)
    x = np.where(x >= -TANH_CLAMP, x, -TANH_CLAMP)
    x = np.where(x > TANH_CLAMP, TANH_CLAMP, x)
    a = np.abs(x)
    big = ONE - TWO / (exp_f32(a + a) + ONE)
    big = np.where(x < 0, -big, big)
    z = x * x
    p = TANH_P[0]
    for coef in TANH_P[1:]:
        p = p * z + coef
    small = (p * z) * x + x
    return _f32(np.where(a > TANH_SMALL, big, small))
