"""The streaming contract's computation in numpy: the reference that the trainer, the ONNX
step and the C kernel are checked against, bit for bit (docs/stream-contract.md).

- `frontend(temp_c, fe)`: the float32 front end (sanitise, clamp, stuck detection, block means
  of D samples, first-order lag filters) in exactly the C kernel's float32 operation order,
  so the trainer's features are the firmware's features bit for bit. Vectorised: 110k
  samples take well under a second.
- `features`, `lstm_step`, `run_steps`: the model step (z, LSTM layers, head) with dot
  products accumulated sequentially from the bias, as in C.
- `bias`: the optional bias head (deg/h) on the same z.
- `expand`, `correct`, `replay`: per-sample held outputs, the corrected gyro rate and flags.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from fogsf.errors import UserError
from fogsf.models.f32 import F32, _f32, sigmoid_f32, tanh_f32
from fogsf.models.front_end import FrontEnd, play_source_w
from fogsf.models.rate_part import apply_rate, rate_coefficients
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import (
    BIAS_LIMIT_DPH,
    FLAG_BIAS_CLAMPED,
    FLAG_GYRO_INVALID,
    FLAG_SF_CLAMPED,
    FLAG_TEMP_CLAMPED,
    FLAG_TEMP_INVALID,
    FLAG_TEMP_STUCK,
    FLAG_TEMP_UNPRIMED,
    PLAUSIBLE_C,
    POWER_ON_C,
    SF_LIMIT_PPM,
)

# --- the front end -------------------------------------------------------------------------

class FrontEndOut(NamedTuple):
    step_index: np.ndarray  # [n_steps] int64: the sample index at which each model step runs
    s: np.ndarray  # [n_steps, 1+K+P] float32: [Tm - t_ref, y_1 - t_ref, ..., p_1 - t_ref, ...]
    flags: np.ndarray  # [N] uint32: TEMP_* flags per sample


def sanitise_temperature(temp_c: np.ndarray, fe: FrontEnd) -> tuple[np.ndarray, np.ndarray]:
    """Step 1 of the contract per sample: (Tc float32 [N], flags uint32 [N])."""
    with np.errstate(over="ignore", invalid="ignore"):
        raw = np.ascontiguousarray(temp_c, dtype=np.float32)  # float64 -> float32 as C's cast
    if raw.ndim != 1:
        raise UserError(f"temperature must be a 1-D array, got shape {raw.shape}")
    n = raw.shape[0]
    t_min, t_max, t_ref = F32(fe.t_min_c), F32(fe.t_max_c), F32(fe.t_ref_c)
    finite = np.isfinite(raw)
    flags = np.zeros(n, dtype=np.uint32)
    flags[~finite] |= FLAG_TEMP_INVALID
    with np.errstate(invalid="ignore"):
        out_of_range = finite & ((raw < t_min) | (raw > t_max))
    flags[out_of_range] |= FLAG_TEMP_CLAMPED
    clamped = np.where(raw < t_min, t_min, np.where(raw > t_max, t_max, raw))
    idx = np.arange(n)
    last_good = np.maximum.accumulate(np.where(finite, idx, -1)) if n else idx
    tc = np.where(last_good >= 0, clamped[np.maximum(last_good, 0)], t_ref).astype(np.float32)
    if fe.stuck_samples > 0 and n > 1:
        bits = raw.view(np.uint32)
        reset = np.ones(n, dtype=bool)
        reset[1:] = bits[1:] != bits[:-1]
        run = idx - np.maximum.accumulate(np.where(reset, idx, 0))
        flags[run >= fe.stuck_samples] |= FLAG_TEMP_STUCK
    return tc, flags


def block_means(tc: np.ndarray, decimation: int) -> np.ndarray:
    """Tm per model step: Tc[0], then the float32 sequential mean of each later block of D."""
    n = tc.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.float32)
    n_steps = (n - 1) // decimation + 1
    tm = np.empty(n_steps, dtype=np.float32)
    tm[0] = tc[0]
    if n_steps > 1:
        blocks = tc[1:1 + (n_steps - 1) * decimation].reshape(n_steps - 1, decimation)
        acc = np.cumsum(blocks, axis=1, dtype=np.float32)[:, -1]  # sequential, like C
        tm[1:] = acc / F32(decimation)
    return tm


def lag_filters(tm: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """y_k per model step [n_steps, K]: y = Tm[0] primed, then y += alpha * (Tm - y)."""
    n_steps, k = tm.shape[0], alpha.shape[0]
    y_out = np.empty((n_steps, k), dtype=np.float32)
    values = list(tm)  # numpy float32 scalars: each op below rounds to float32, as C does
    for j in range(k):
        a = F32(alpha[j])
        y = values[0] if n_steps else F32(0)
        col = np.empty(n_steps, dtype=np.float32)
        for m, x in enumerate(values):
            y = y + a * (x - y)
            col[m] = y
        y_out[:, j] = col
    return y_out


def plays(tm: np.ndarray, y: np.ndarray, half_c: np.ndarray, source_w: np.ndarray
          ) -> np.ndarray:
    """p_j per model step [n_steps, P]: p = Tm[0] primed, then per step, after the lag
    filters, x = 0 + v_0 Tm + v_1 y_1 + ... + v_K y_K (float32, index order), lo = x - h,
    hi = x + h, p = lo if p < lo, else hi if p > hi, else p (the play or backlash
    operator)."""
    n_steps = tm.shape[0]
    src = np.asarray(source_w, dtype=np.float32)
    v = np.column_stack([tm, y]).astype(np.float32) if n_steps else np.zeros((0, 1 + y.shape[1]),
                                                                             np.float32)
    out = np.empty((n_steps, src.shape[0]), dtype=np.float32)
    for j in range(src.shape[0]):
        x_col = np.zeros(n_steps, dtype=np.float32)
        for i in range(src.shape[1]):
            x_col = x_col + src[j, i] * v[:, i]  # float32 per op, index order, as C
        h = F32(half_c[j])
        p = F32(tm[0]) if n_steps else F32(0)
        col = np.empty(n_steps, dtype=np.float32)
        for m, x in enumerate(x_col):
            lo, hi = x - h, x + h
            p = lo if p < lo else (hi if p > hi else p)
            col[m] = p
        out[:, j] = col
    return out


def frontend(temp_c: np.ndarray, fe: FrontEnd) -> FrontEndOut:
    """Contract steps 1-4 up to s, for a whole log from reset, bit for bit as the C kernel."""
    tc, flags = sanitise_temperature(temp_c, fe)
    tm = block_means(tc, fe.decimation)
    step_index = np.arange(tm.shape[0], dtype=np.int64) * fe.decimation
    return FrontEndOut(step_index, state_of(tm, fe), flags)


def state_of(tm: np.ndarray, fe: FrontEnd) -> np.ndarray:
    """Contract steps 3-4 from the step means Tm: s = [Tm - t_ref, y_1 - t_ref, ...,
    p_1 - t_ref, ...] per step (the lag filters, then the play operators)."""
    alpha = np.asarray(fe.filter_alpha, dtype=np.float32)
    y = lag_filters(tm, alpha)
    t_ref = F32(fe.t_ref_c)
    k = alpha.shape[0]
    s = np.empty((tm.shape[0], 1 + k + fe.n_plays), dtype=np.float32)
    s[:, 0] = tm - t_ref
    s[:, 1:1 + k] = y - t_ref
    if fe.n_plays:
        s[:, 1 + k:] = plays(tm, y, fe.play_half_c(),
                             play_source_w(fe.play_source_w, k)) - t_ref
    return s


# --- the model step ------------------------------------------------------------------------

def _seq_matvec(acc: np.ndarray, m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """acc + m @ v, accumulated over v's index in order (float32 rounding after every op)."""
    for j in range(v.shape[-1]):
        acc = acc + m[:, j] * v[j]
    return acc


def features(model: StreamModel, s: np.ndarray) -> np.ndarray:
    """z = feat_w s + feat_b per step, sequential from the bias: [n_steps, F] float32; with
    feat_diag (feat_w [F], F == 1+K+P) z_i = feat_b[i] + feat_w[i] * s_i, as the kernel."""
    w, b = model.weights["feat_w"], model.weights["feat_b"]
    s = np.asarray(s, dtype=np.float32)
    if w.ndim == 1:  # feat_diag (its validated shape; callers may pass only the weights)
        return (b[None, :] + w[None, :] * s).astype(np.float32)
    z = np.broadcast_to(b, (s.shape[0], b.shape[0])).copy()
    for j in range(w.shape[1]):
        z = z + w[:, j][None, :] * s[:, j][:, None]
    return z.astype(np.float32)


def lstm_cell(w: np.ndarray, r: np.ndarray, b: np.ndarray, x: np.ndarray, h: np.ndarray,
              c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One ONNX LSTM cell step (gate order i, o, f, c) in the kernel's float32 order."""
    hid = r.shape[1]
    gates = b[:4 * hid] + b[4 * hid:]
    gates = _seq_matvec(gates, w, x)
    gates = _seq_matvec(gates, r, h)
    i = sigmoid_f32(gates[:hid])
    o = sigmoid_f32(gates[hid:2 * hid])
    f = sigmoid_f32(gates[2 * hid:3 * hid])
    g = tanh_f32(gates[3 * hid:])
    c_new = f * c + i * g
    h_new = o * tanh_f32(c_new)
    return _f32(h_new), _f32(c_new)


def head(model: StreamModel, h_last: np.ndarray, z: np.ndarray) -> tuple[F32, F32, int]:
    """(y, sf_ppm, flags) from the last layer's h and z, sequential from head_b; with the
    polynomial head, then + quad_w[i, j] * (z_i * z_j) (i, then j ascending; with
    quad_diag + quad_w[i] * (z_i * z_i), i ascending) and + cube_w[i] * ((z_i * z_i) * z_i),
    one float32 op at a time as the kernel."""
    wts = model.weights
    y = wts["head_b"][0]
    for j in range(h_last.shape[0]):
        y = y + wts["head_w"][j] * h_last[j]
    for j in range(z.shape[0]):
        y = y + wts["skip_w"][j] * z[j]
    if model.poly_head:
        quad, cube = wts["quad_w"], wts["cube_w"]
        if model.quad_diag:
            for i in range(z.shape[0]):
                y = y + quad[i] * (z[i] * z[i])
        else:
            for i in range(z.shape[0]):
                for j in range(z.shape[0]):
                    y = y + quad[i, j] * (z[i] * z[j])
        for i in range(z.shape[0]):
            y = y + cube[i] * ((z[i] * z[i]) * z[i])
    sf = y * wts["out_scale"][0] + wts["out_offset"][0]
    sf, flags = clamp_sf(sf)
    return F32(y), sf, flags


def clamp_sf(sf: F32) -> tuple[F32, int]:
    """NaN -> 0, beyond +-SF_LIMIT_PPM -> the limit; flags SF_CLAMPED."""
    lim = F32(SF_LIMIT_PPM)
    if abs(sf) <= lim:
        return F32(sf), 0
    return (lim if sf > 0 else (-lim if sf < 0 else F32(0))), FLAG_SF_CLAMPED


def bias(model: StreamModel, z: np.ndarray) -> tuple[F32, int]:
    """(bias_dph, flags) of one step's z: bias_b, + bias_w[i] * z_i, + bias_quad_w[i] *
    (z_i * z_i), + bias_cube_w[i] * ((z_i * z_i) * z_i), i ascending in each sum, one
    float32 op at a time as the kernel; NaN -> 0 and beyond +-BIAS_LIMIT_DPH -> the limit,
    flagged BIAS_CLAMPED. (0, 0) without a bias head."""
    if not model.bias_head:
        return F32(0), 0
    w = model.weights
    y = w["bias_b"][0]
    for i in range(z.shape[0]):
        y = y + w["bias_w"][i] * z[i]
    for i in range(z.shape[0]):
        y = y + w["bias_quad_w"][i] * (z[i] * z[i])
    for i in range(z.shape[0]):
        y = y + w["bias_cube_w"][i] * ((z[i] * z[i]) * z[i])
    lim = F32(BIAS_LIMIT_DPH)
    if abs(y) <= lim:
        return F32(y), 0
    return (lim if y > 0 else (-lim if y < 0 else F32(0))), FLAG_BIAS_CLAMPED


def initial_state(model: StreamModel) -> tuple[np.ndarray, np.ndarray]:
    shape = (model.layers, model.hidden)
    return np.zeros(shape, np.float32), np.zeros(shape, np.float32)


def lstm_step(model: StreamModel, z: np.ndarray, h: np.ndarray, c: np.ndarray
              ) -> tuple[F32, F32, int, np.ndarray, np.ndarray]:
    """One model step from z: (y, sf_ppm, flags, h [L,H], c [L,H]); h and c are new arrays."""
    h, c = h.copy(), c.copy()
    x = np.asarray(z, dtype=np.float32)[:model.n_lstm_inputs]
    for layer in range(model.layers):
        h[layer], c[layer] = lstm_cell(model.weights[f"lstm{layer}_w"],
                                       model.weights[f"lstm{layer}_r"],
                                       model.weights[f"lstm{layer}_b"], x, h[layer], c[layer])
        x = h[layer]
    y, sf, flags = head(model, h[-1], np.asarray(z, dtype=np.float32))
    return y, sf, flags, h, c


class StepsOut(NamedTuple):
    y: np.ndarray  # [n_steps] float32 head output before scaling
    sf_ppm: np.ndarray  # [n_steps] float32
    flags: np.ndarray  # [n_steps] uint32 (SF_CLAMPED, BIAS_CLAMPED)
    h_last: np.ndarray  # [n_steps, H] float32 last layer's hidden state
    bias_dph: np.ndarray  # [n_steps] float32 (0 without a bias head)


def run_steps(model: StreamModel, s: np.ndarray) -> StepsOut:
    """The model over a sequence of s from reset (one row per model step)."""
    z = features(model, s)
    h, c = initial_state(model)
    n = z.shape[0]
    ys = np.empty(n, np.float32)
    sfs = np.empty(n, np.float32)
    fl = np.zeros(n, np.uint32)
    hl = np.empty((n, model.hidden), np.float32)
    bs = np.zeros(n, np.float32)
    for m in range(n):
        ys[m], sfs[m], fl[m], h, c = lstm_step(model, z[m], h, c)
        hl[m] = h[-1]
        if model.bias_head:
            bs[m], bflag = bias(model, z[m])
            fl[m] |= bflag
    return StepsOut(ys, sfs, fl, hl, bs)


def expand(step_values: np.ndarray, n_samples: int, decimation: int) -> np.ndarray:
    """Per-sample held values: sample i gets the value of step i // D."""
    return np.asarray(step_values)[np.arange(n_samples) // decimation]


def expand_late(step_values: np.ndarray, n_samples: int, decimation: int) -> np.ndarray:
    """Held values of the even-time kernel (FOGSF_EVEN_TIME: each step computed over the D
    samples after its own and held from the next step's sample on): sample i gets the value
    of step i // D - 1, and 0 before sample D."""
    v = np.asarray(step_values)
    idx = np.arange(n_samples) // decimation - 1
    out = v[np.maximum(idx, 0)] if v.shape[0] else np.zeros(n_samples, v.dtype)
    before = (idx >= 0).reshape(-1, *([1] * (v.ndim - 1)))  # per sample, per row of v
    return np.where(before, out, np.zeros((), v.dtype)).astype(v.dtype)


def correction_terms(sf_ppm: np.ndarray, bias_dph: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The per-step factors of the correction, float32 as the kernel computes them at each
    model step: (k, b) with s = sf_ppm * 1e-6, k = s / (1 + s), b = bias_dph / 3600 (0
    without a bias)."""
    sf = np.asarray(sf_ppm, dtype=np.float32)
    s = sf * F32(1e-6)
    k = (s / (F32(1) + s)).astype(np.float32)
    if bias_dph is None:
        return k, np.zeros_like(k)
    return k, (np.asarray(bias_dph, dtype=np.float32) / F32(3600)).astype(np.float32)


def correct(gyro_dps: np.ndarray, sf_ppm: np.ndarray, bias_dph: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """corrected = (g - bias/3600) / (1 + sf*1e-6) in float32 as the kernel (contract step 5):
    g as float32, d = g - b, corrected = d - d * k (`correction_terms`); non-finite -> 0.0
    and GYRO_INVALID. Returned as float64 holding the float32 values exactly."""
    with np.errstate(all="ignore"):
        g = np.asarray(gyro_dps, dtype=np.float64).astype(np.float32)  # as C's cast
        k, b = correction_terms(sf_ppm, bias_dph)
        d = g - b
        out = (d - d * k).astype(np.float32)
    bad = ~np.isfinite(out)
    out[bad] = 0.0
    return (out.astype(np.float64),
            np.where(bad, np.uint32(FLAG_GYRO_INVALID), np.uint32(0)).astype(np.uint32))


class ReplayOut(NamedTuple):
    corrected_dps: np.ndarray  # [N] float64 holding the kernel's float32 values exactly
    sf_ppm: np.ndarray  # [N] float32, held between model steps
    flags: np.ndarray  # [N] uint32
    bias_dph: np.ndarray | None = None  # [N] float32, held (0 without a bias head)


def first_plausible(temp_c: np.ndarray) -> int:
    """Index of the first temperature the kernel primes its filters with (the power-on rule:
    finite, within PLAUSIBLE_C, not POWER_ON_C); len(temp_c) if none."""
    with np.errstate(over="ignore", invalid="ignore"):
        t = np.asarray(temp_c, dtype=np.float32)
        ok = ((t >= np.float32(PLAUSIBLE_C[0])) & (t <= np.float32(PLAUSIBLE_C[1]))
              & (t != np.float32(POWER_ON_C)))
    hits = np.flatnonzero(ok)
    return int(hits[0]) if hits.size else int(t.shape[0])


def replay(model: StreamModel, temp_c: np.ndarray, gyro_dps: np.ndarray,
           even_time: bool = False) -> ReplayOut:
    """The whole contract per sample from reset: what the C kernel returns, bit for bit
    (`even_time`: what a kernel built with FOGSF_EVEN_TIME returns, the same step outputs
    held D samples later, `expand_late`). Before the first plausible temperature the gyro
    passes as it is (sf 0, bias 0, TEMP_UNPRIMED); from it on, a clean start there."""
    i0 = first_plausible(temp_c)
    if i0 == 0:
        return replay_primed(model, temp_c, gyro_dps, even_time)
    with np.errstate(over="ignore", invalid="ignore"):
        t = np.asarray(temp_c, dtype=np.float32)
        g = np.asarray(gyro_dps, dtype=np.float64).astype(np.float32)
    head, gflags = correct(g[:i0], np.zeros(i0, np.float32))
    head_flags = (np.uint32(FLAG_TEMP_UNPRIMED) | gflags
                  | np.where(np.isfinite(t[:i0]), 0, FLAG_TEMP_INVALID).astype(np.uint32))
    rest = replay_primed(model, t[i0:], g[i0:], even_time)
    zeros = np.zeros(i0, np.float32)
    return ReplayOut(np.concatenate([head, rest.corrected_dps]),
                     np.concatenate([zeros, rest.sf_ppm]),
                     np.concatenate([head_flags, rest.flags]).astype(np.uint32),
                     np.concatenate([zeros, rest.bias_dph]))


def replay_primed(model: StreamModel, temp_c: np.ndarray, gyro_dps: np.ndarray,
                  even_time: bool = False) -> ReplayOut:
    """The contract with the filters primed at the first sample whatever it holds (`replay`
    from its first plausible temperature on; what a kernel without the power-on rule did)."""
    fe = frontend(temp_c, model.front_end)
    steps = run_steps(model, fe.s)
    n = fe.flags.shape[0]
    held = expand_late if even_time else expand
    sf = held(steps.sf_ppm, n, model.decimation)
    b = held(steps.bias_dph, n, model.decimation)
    corrected, gflags = correct(gyro_dps, sf, b if model.bias_head else None)
    flags = fe.flags | gflags | held(steps.flags, n, model.decimation)
    if model.has_rate_part:
        a = held(rate_coefficients(model, fe.s[:, 0]), n, model.decimation)
        out, rflags = apply_rate(model, corrected, a, flags)
        corrected, flags = out.astype(np.float64), flags | rflags
    return ReplayOut(corrected, sf, flags.astype(np.uint32), b)
