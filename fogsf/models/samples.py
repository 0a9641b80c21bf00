"""Seeded inputs for tests and benchmarks: a random model of any size and a chamber ramp."""

from __future__ import annotations

import math

import numpy as np

from fogsf.errors import UserError
from fogsf.models.front_end import filter_alpha
from fogsf.models.stream import StreamModel


def _geometric(start: float, stop: float, n: int) -> list[float]:
    """numpy's geomspace(start, stop, n) in Python's floats (10 ** a linear log10 grid, the
    ends exact): numpy's vector unit rounds the last digit of its powers by the CPU (AVX-512
    against AVX2), and the time constants enter the model's id; libm's pow does not."""
    if n < 2:
        return [start][:n]
    lo, hi = math.log10(start), math.log10(stop)
    step = (hi - lo) / (n - 1)
    out = [10.0 ** (lo + i * step) for i in range(n)]
    out[0], out[-1] = start, stop
    return out


def random_model(filters: int = 2, n_features: int = 4, layers: int = 1, hidden: int = 8,
                 decimation: int = 10, seed: int = 0, *, taus_s: list[float] | None = None,
                 t_ref_c: float = 20.0, t_min_c: float = -45.0, t_max_c: float = 55.0,
                 stuck_samples: int = 600, gain: float = 0.8, out_scale: float = 300.0,
                 out_offset: float = 40.0, poly_head: bool = False,
                 lstm_inputs: int | None = None, quad_diag: bool = False,
                 bias_head: bool = False, bias_dph: float = 2.0,
                 plays: tuple[tuple[tuple[float, ...], float], ...] = (),
                 feat_diag: bool = False, rate_part: tuple[int, int] | None = None,
                 rate_fs_dps: float = 150.0) -> StreamModel:
    """A seeded random model in the artifact format.

    Scaled so nothing saturates on chamber temperatures: z is O(1) over -45..55 C, every gate's
    pre-activation has a standard deviation of about `gain`, so h moves through the linear part
    of tanh and sf_ppm spans a few hundred ppm (out_scale) around out_offset.
    With `poly_head`, quad_w and cube_w come from a second generator seeded from `seed` (the
    other arrays are those of the same call without the head), scaled so that the quadratic
    and cubic terms are O(0.3) each, like the skip term. `lstm_inputs` N: the first LSTM
    layer reads z[0:N] (its W is [4H, N], so the draws after it differ); `quad_diag`: quad_w
    is the diagonal [F] only (drawn from the head's generator, at the scale of a row).
    With `bias_head`, the bias head's arrays come from a third generator (the others stay
    put): bias_b about `bias_dph` and each term O(bias_dph / 3) in deg/h. `plays`
    ((source weights over [Tm, y_1..y_K], width_c) each): play operators in the front end;
    feat_w is then [F, 1+K+P] (so the draws after it differ). `feat_diag` (F must be 1+K+P):
    feat_w is the diagonal [F] only, from a fourth generator at the scale of a row's sum, so
    z_i = feat_w[i] * s_i + feat_b[i] is O(1) too (the other arrays stay put). `rate_part`
    (R, Q): a rate part of full scale `rate_fs_dps`, rate_w from a fifth generator.
    """
    rng = np.random.default_rng(seed)
    if taus_s is None:
        taus_s = _geometric(300.0, 1200.0, filters)
    if len(taus_s) != filters:
        raise UserError(f"random_model: {filters} filters but {len(taus_s)} time constants")
    k, f, h = filters, n_features, hidden
    half_span = max(t_max_c - t_ref_c, t_ref_c - t_min_c)

    def u(shape: tuple[int, ...], scale: float, gen: np.random.Generator = rng) -> np.ndarray:
        return (gen.uniform(-1.0, 1.0, size=shape) * scale).astype(np.float32)

    weights: dict[str, np.ndarray] = {
        "filter_alpha": filter_alpha(taus_s, decimation),
        "feat_w": u((f, 1 + k + len(plays)),
                    math.sqrt(3.0) / (half_span * math.sqrt(1 + k + len(plays)))),
        "feat_b": u((f,), 0.2),
    }
    for layer in range(layers):
        n_in = (f if lstm_inputs is None else lstm_inputs) if layer == 0 else h
        # uniform(-a, a) has std a/sqrt(3); inputs are O(1/sqrt(n)) in norm per component
        weights[f"lstm{layer}_w"] = u((4 * h, n_in), gain * math.sqrt(3.0 / (n_in + h)))
        weights[f"lstm{layer}_r"] = u((4 * h, h), gain * math.sqrt(3.0 / (n_in + h)))
        weights[f"lstm{layer}_b"] = u((8 * h,), 0.1)
    weights["head_w"] = u((h,), math.sqrt(3.0 / h))
    weights["head_b"] = u((1,), 0.1)
    weights["skip_w"] = u((f,), 0.3 * math.sqrt(3.0 / f))
    weights["out_scale"] = np.array([out_scale], np.float32)
    weights["out_offset"] = np.array([out_offset], np.float32)
    if poly_head:
        poly_rng = np.random.default_rng([seed, 1])  # its own stream: the draws above stay put
        weights["quad_w"] = (u((f,), 0.3 * math.sqrt(3.0 / f), poly_rng) if quad_diag
                             else u((f, f), 0.3 * math.sqrt(3.0) / f, poly_rng))
        weights["cube_w"] = u((f,), 0.3 * math.sqrt(3.0 / f), poly_rng)
    if feat_diag:
        diag_rng = np.random.default_rng([seed, 3])
        weights["feat_w"] = u((f,), math.sqrt(3.0) / half_span, diag_rng)
    if bias_head:
        bias_rng = np.random.default_rng([seed, 2])
        scale = bias_dph / 3.0 * math.sqrt(3.0 / f)
        weights["bias_b"] = np.array([bias_dph], np.float32) + u((1,), 0.1 * bias_dph, bias_rng)
        for name in ("bias_w", "bias_quad_w", "bias_cube_w"):
            weights[name] = u((f,), scale, bias_rng)
    if rate_part is not None:  # (R, Q): an open-loop-sized rate error, ~0.1 % of FS a term
        rate_rng = np.random.default_rng([seed, 4])
        r, q = rate_part
        scales = 1e-3 * rate_fs_dps / (10.0 ** np.arange(q))  # per C, per C^2: smaller
        weights["rate_w"] = (rate_rng.uniform(-1.0, 1.0, (r, q)) * scales).astype(np.float32)
    model = StreamModel(model="random-lstm", decimation=decimation, t_ref_c=t_ref_c,
                        t_min_c=t_min_c, t_max_c=t_max_c, stuck_samples=stuck_samples,
                        filter_tau_s=list(taus_s), n_features=f, layers=layers, hidden=h,
                        weights=weights, extra={"random_seed": seed}, poly_head=poly_head,
                        lstm_inputs=lstm_inputs, quad_diag=quad_diag, bias_head=bias_head,
                        play_width_c=[float(w) for _, w in plays],
                        play_source_w=[[float(v) for v in src] for src, _ in plays],
                        feat_diag=feat_diag,
                        rate_fs_dps=rate_fs_dps if rate_part is not None else 0.0)
    model.validate()
    return model


def chamber_ramp(hours: float = 4.0, rate_c_per_min: float = 1.0, seed: int = 0,
                 t_lo: float = -40.0, t_hi: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """A 10 Hz board temperature (lagged chamber ramp, quantised to 1/256 C, with noise) and a
    raw gyro output on a 10 deg/s table: a realistic input stream for tests and benchmarks."""
    rng = np.random.default_rng(seed)
    n = int(hours * 36000)
    t = np.arange(n) * 0.1
    period = 2 * (t_hi - t_lo) / rate_c_per_min * 60.0
    phase = (t / period) % 1.0
    chamber = t_lo + (t_hi - t_lo) * np.where(phase < 0.5, 2 * phase, 2 - 2 * phase)
    alpha = 1.0 - math.exp(-0.1 / 400.0)  # board lags the chamber air by ~400 s
    board = np.empty(n)
    acc = chamber[0]
    for i in range(n):
        acc += alpha * (chamber[i] - acc)
        board[i] = acc
    temp = np.round((board + rng.normal(0.0, 0.01, n)) * 256.0) / 256.0
    sf_true_ppm = 300.0 * np.tanh((board - 20.0) / 40.0) + 40.0
    gyro = 10.0 * (1.0 + sf_true_ppm * 1e-6) + rng.normal(0.0, 0.01, n)
    return temp, gyro
