"""The streaming model artifact's checks (docs/stream-contract.md): every key and array
of a `StreamModel` (read through the `Checked` protocol) against the contract, one
`UserError` naming what is wrong."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

from fogsf.errors import UserError
from fogsf.models.front_end import filter_alpha
from fogsf.models.stream_format import (
    BIAS_ARRAYS,
    BIAS_KEY,
    CONFIG_FILE,
    FEAT_DIAG_KEY,
    LSTM_INPUTS_KEY,
    MAX_PLAY_WIDTH_C,
    MAX_RATE_FS_DPS,
    MAX_RATE_ROWS,
    MAX_RATE_TEMP_COEFS,
    PLAY_SOURCE_KEY,
    PLAY_WIDTH_KEY,
    POLY_ARRAYS,
    POLY_KEY,
    QUAD_DIAG_KEY,
    RATE_ARRAY,
    RATE_KEY,
    WEIGHTS_FILE,
)


class Checked(Protocol):
    """What the checks read of a `StreamModel` (fogsf/models/stream.py): its fields and
    sizes, named here so that the artifact's module imports its checks, not the reverse."""

    model: str
    decimation: int
    t_ref_c: float
    t_min_c: float
    t_max_c: float
    stuck_samples: int
    filter_tau_s: list[float]
    n_features: int
    layers: int
    hidden: int
    weights: dict[str, np.ndarray]
    sample_dt_s: float
    poly_head: bool
    lstm_inputs: int | None
    quad_diag: bool
    bias_head: bool
    play_width_c: list[float]
    play_source_w: list[list[float]]
    feat_diag: bool
    rate_fs_dps: float

    @property
    def has_rate_part(self) -> bool: ...
    @property
    def n_filters(self) -> int: ...
    @property
    def n_plays(self) -> int: ...
    @property
    def n_lstm_inputs(self) -> int: ...
    @property
    def lstm_inputs_narrowed(self) -> bool: ...
    def expected_shapes(self) -> dict[str, tuple[int, ...]]: ...


def validate_model(self: Checked, where: str = "model") -> None:
    """Refuse an inconsistent artifact with one message naming what is wrong."""
    def bad(msg: str) -> UserError:
        return UserError(f"{where}: {msg}")

    for name, value in (("decimation", self.decimation), ("layers", self.layers),
                        ("hidden", self.hidden), ("n_features", self.n_features)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise bad(f"'{name}' must be an integer >= 1, got {value!r}")
    if not isinstance(self.stuck_samples, int) or not 0 <= self.stuck_samples < 2**31:
        raise bad(f"'stuck_samples' must be an integer in [0, 2^31), got "
                  f"{self.stuck_samples!r}")
    if self.decimation >= 2**31:  # the kernel counts samples in uint32
        raise bad(f"'decimation' must be below 2^31, got {self.decimation}")
    if not (isinstance(self.sample_dt_s, (int, float)) and self.sample_dt_s > 0):
        raise bad(f"'sample_dt_s' must be > 0, got {self.sample_dt_s!r}")
    temps = {"t_ref_c": self.t_ref_c, "t_min_c": self.t_min_c, "t_max_c": self.t_max_c}
    for name, temp in temps.items():
        if not (isinstance(temp, (int, float)) and math.isfinite(temp)
                and -273.15 < temp < 1000.0):
            raise bad(f"'{name}' must be a finite temperature in C, got {temp!r}")
    if not isinstance(self.poly_head, bool):
        raise bad(f"'{POLY_KEY}' must be true or false, got {self.poly_head!r}")
    if not isinstance(self.quad_diag, bool):
        raise bad(f"'{QUAD_DIAG_KEY}' must be true or false, got {self.quad_diag!r}")
    if not isinstance(self.bias_head, bool):
        raise bad(f"'{BIAS_KEY}' must be true or false, got {self.bias_head!r}")
    if not isinstance(self.feat_diag, bool):
        raise bad(f"'{FEAT_DIAG_KEY}' must be true or false, got {self.feat_diag!r}")
    if self.quad_diag and not self.poly_head:
        raise bad(f"'{QUAD_DIAG_KEY}' is true but '{POLY_KEY}' is false: a diagonal "
                  f"quadratic needs the polynomial head")
    n_in = self.lstm_inputs
    if n_in is not None and (not isinstance(n_in, int) or isinstance(n_in, bool)
                             or not 1 <= n_in <= self.n_features):
        raise bad(f"'{LSTM_INPUTS_KEY}' must be an integer in [1, n_features = "
                  f"{self.n_features}], got {n_in!r}")
    if not self.t_min_c < self.t_max_c:
        raise bad(f"t_min_c ({self.t_min_c}) must be below t_max_c ({self.t_max_c})")
    if not self.t_min_c <= self.t_ref_c <= self.t_max_c:
        raise bad(f"t_ref_c ({self.t_ref_c}) must lie in [t_min_c, t_max_c] = "
                  f"[{self.t_min_c}, {self.t_max_c}]")
    for tau in self.filter_tau_s:
        if not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0):
            raise bad(f"'filter_tau_s' must hold positive time constants, got {tau!r}")
    _validate_plays(self, bad)
    _validate_rate(self, bad)
    n_s = 1 + self.n_filters + self.n_plays
    if self.feat_diag and self.n_features != n_s:
        raise bad(f"'{FEAT_DIAG_KEY}' is true but n_features = {self.n_features} is not "
                  f"1+K+P = {n_s} (K={self.n_filters} filters, P={self.n_plays} plays): "
                  f"a diagonal feat_w maps each entry of s to one feature")
    expected = self.expected_shapes()
    missing = sorted(set(expected) - set(self.weights))
    if missing:
        quad = "[F]" if self.quad_diag else "[F, F]"
        why = (f" ({POLY_KEY} is true: the polynomial head needs quad_w {quad} and cube_w "
               f"[F])" if self.poly_head and set(missing) & set(POLY_ARRAYS) else "")
        why += (f" ({BIAS_KEY} is true: the bias head needs {', '.join(BIAS_ARRAYS)})"
                if self.bias_head and set(missing) & set(BIAS_ARRAYS) else "")
        raise bad(f"{WEIGHTS_FILE} lacks array(s) {', '.join(missing)}{why}")
    stray = sorted(set(POLY_ARRAYS) & set(self.weights) - set(expected))
    if stray:
        raise bad(f"{WEIGHTS_FILE} holds {', '.join(stray)} but {POLY_KEY} is false: set "
                  f"\"{POLY_KEY}\": true in {CONFIG_FILE} or drop the array(s)")
    stray = sorted(set(BIAS_ARRAYS) & set(self.weights) - set(expected))
    if stray:
        raise bad(f"{WEIGHTS_FILE} holds {', '.join(stray)} but {BIAS_KEY} is false: set "
                  f"\"{BIAS_KEY}\": true in {CONFIG_FILE} or drop the array(s)")
    if RATE_ARRAY in self.weights and RATE_ARRAY not in expected:
        raise bad(f"{WEIGHTS_FILE} holds {RATE_ARRAY} but {CONFIG_FILE} has no {RATE_KEY}: "
                  f"give the rate part's full scale or drop the array")
    for name, shape in expected.items():
        arr = self.weights[name]
        if arr.dtype != np.float32:
            raise bad(f"array '{name}' must be float32, got {arr.dtype}")
        if arr.shape != shape:
            extra = (f" {LSTM_INPUTS_KEY}={self.n_lstm_inputs}" if name == "lstm0_w"
                     and self.lstm_inputs_narrowed else "")
            extra += f" {QUAD_DIAG_KEY}=true" if name == "quad_w" and self.quad_diag else ""
            extra += f" {FEAT_DIAG_KEY}=true" if name == "feat_w" and self.feat_diag else ""
            raise bad(f"array '{name}' has shape {arr.shape}, expected {shape} from "
                      f"K={self.n_filters} F={self.n_features} L={self.layers} "
                      f"H={self.hidden}{extra}")
        if not np.all(np.isfinite(arr)):
            raise bad(f"array '{name}' holds NaN or Inf")
    alpha = self.weights["filter_alpha"].astype(np.float64)
    if np.any(alpha <= 0) or np.any(alpha > 1):
        raise bad(f"filter_alpha must lie in (0, 1], got {alpha.tolist()}")
    want = filter_alpha(self.filter_tau_s, self.decimation, self.sample_dt_s)
    if not np.allclose(alpha, want, rtol=1e-5, atol=0):
        raise bad(f"filter_alpha {alpha.tolist()} does not match 1-exp(-D*dt/tau) = "
                  f"{want.tolist()} for filter_tau_s={self.filter_tau_s}, D={self.decimation}")

def _validate_plays(self: Checked, bad: Callable[[str], UserError]) -> None:
    widths, sources = self.play_width_c, self.play_source_w
    if not isinstance(widths, list) or not isinstance(sources, list) \
            or len(widths) != len(sources):
        raise bad(f"'{PLAY_WIDTH_KEY}' and '{PLAY_SOURCE_KEY}' must be lists of one "
                  f"length, got {widths!r} and {sources!r}")
    for w in widths:
        if not (isinstance(w, (int, float)) and not isinstance(w, bool)
                and math.isfinite(w) and 0 <= w <= MAX_PLAY_WIDTH_C):
            raise bad(f"'{PLAY_WIDTH_KEY}' must hold widths in [0, {MAX_PLAY_WIDTH_C:g}] "
                      f"C, got {w!r}")
    for r in sources:
        if not (isinstance(r, list) and len(r) == 1 + self.n_filters
                and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                        and math.isfinite(v) and abs(v) <= 1e3 for v in r)):
            raise bad(f"'{PLAY_SOURCE_KEY}' must hold one row of 1+K = "
                      f"{1 + self.n_filters} finite weights (|w| <= 1000) per play over "
                      f"[Tm, y_1..y_K], got {r!r}")


def _validate_rate(self: Checked, bad: Callable[[str], UserError]) -> None:
    """The rate part: a finite full scale in (0, MAX_RATE_FS_DPS] and rate_w [R, Q] within
    MAX_RATE_ROWS x MAX_RATE_TEMP_COEFS (the kernel's fixed sizes)."""
    fs = self.rate_fs_dps
    if not (isinstance(fs, (int, float)) and not isinstance(fs, bool) and math.isfinite(fs)
            and 0 <= fs <= MAX_RATE_FS_DPS):
        raise bad(f"'{RATE_KEY}' must be a full scale in (0, {MAX_RATE_FS_DPS:g}] deg/s, got "
                  f"{fs!r}")
    if not self.has_rate_part:
        return
    rate = self.weights.get(RATE_ARRAY)
    if rate is None:
        raise bad(f"{WEIGHTS_FILE} lacks array {RATE_ARRAY} ({RATE_KEY} is given: the rate "
                  f"part needs its coefficients [R, Q])")
    if rate.ndim != 2 or not (1 <= rate.shape[0] <= MAX_RATE_ROWS
                              and 1 <= rate.shape[1] <= MAX_RATE_TEMP_COEFS):
        raise bad(f"array '{RATE_ARRAY}' has shape {rate.shape}, expected [R, Q] with 1 <= R "
                  f"<= {MAX_RATE_ROWS} terms and 1 <= Q <= {MAX_RATE_TEMP_COEFS} coefficients")
