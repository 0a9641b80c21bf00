"""The streaming model contract "fogsf-stream-1" (docs/stream-contract.md) in numpy.

One computation, three implementations: the trainer (torch), the ONNX step (onnxruntime) and
the C kernel (firmware/c). This module is the reference all three are checked against:

- `StreamModel`: the artifact (stream.json + stream_weights.npz): load, save, validate,
  `model_id` (a hash of weights and config).
- `frontend(temp_c, fe)`: the float32 front end (sanitise, clamp, stuck detection, block means
  of D samples, first-order lag filters) in exactly the C kernel's float32 operation order,
  so the trainer's features are the firmware's features bit for bit. Vectorised: 110k
  samples take well under a second.
- `exp_f32`, `sigmoid_f32`, `tanh_f32`: the kernel's own activations, op for op (the C kernel
  does not call libm so that host and Cortex-M4F give the same bits).
- `features`, `lstm_step`, `run_steps`: the model step (z, LSTM layers, head) with dot
  products accumulated sequentially from the bias, as in C.
- `expand`, `correct`, `replay`: per-sample held outputs, the corrected gyro rate and flags.
- `torch_to_onnx_lstm`, `onnx_to_torch_lstm`: gate-order converters (torch i,f,g,o with
  weight_ih, weight_hh, bias_ih, bias_hh <-> ONNX i,o,f,c with W, R, B).
- `random_model`: a seeded random model of any size, weights scaled so the LSTM is not
  saturated (for tests and benchmarks before trained models exist), optionally with the
  polynomial head (quad_w, cube_w: a quadratic/cubic fit in z added to the output).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from fogsf.trainer.errors import UserError

FORMAT = "fogsf-stream-1"
CONFIG_FILE = "stream.json"
WEIGHTS_FILE = "stream_weights.npz"

# Status flags, one bit each (the C kernel's FOGSF_FLAG_* have the same values).
FLAG_TEMP_INVALID = 1  # temperature not finite: last good value (or t_ref) used
FLAG_TEMP_CLAMPED = 2  # temperature outside [t_min, t_max]: clamped
FLAG_TEMP_STUCK = 4  # raw temperature bitwise unchanged for >= stuck_samples samples
FLAG_GYRO_INVALID = 8  # gyro input (or corrected output) not finite: corrected = 0.0
FLAG_SF_CLAMPED = 16  # model output not finite or beyond +-SF_LIMIT_PPM: clamped
FLAG_NAMES = {FLAG_TEMP_INVALID: "TEMP_INVALID", FLAG_TEMP_CLAMPED: "TEMP_CLAMPED",
              FLAG_TEMP_STUCK: "TEMP_STUCK", FLAG_GYRO_INVALID: "GYRO_INVALID",
              FLAG_SF_CLAMPED: "SF_CLAMPED"}
SF_LIMIT_PPM = 1.0e5  # |predicted SF error| beyond 10 % is a broken model, never a gyro

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


# --- the artifact --------------------------------------------------------------------------

def filter_alpha(filter_tau_s: list[float], decimation: int, sample_dt_s: float = 0.1
                 ) -> np.ndarray:
    """alpha_k = 1 - exp(-D*dt/tau_k), computed in float64, stored as float32."""
    return np.array([1.0 - math.exp(-decimation * sample_dt_s / tau) for tau in filter_tau_s],
                    dtype=np.float32)


# A model step may differ from D * dt by this fraction at most (D an integer of samples)
STEP_TOLERANCE = 0.01


def decimation_for(step_s: float, sample_dt_s: float, where: str | None = None) -> int:
    """Samples per model step: step_s / sample_dt_s, which must be (within STEP_TOLERANCE)
    a whole number >= 1; `where` (a log's path) starts the refusal."""
    d = max(1, int(round(step_s / sample_dt_s)))
    if abs(d * sample_dt_s - step_s) > STEP_TOLERANCE * step_s:
        raise UserError(f"{where + ': ' if where else ''}a model step of {step_s:g} s is "
                        f"{step_s / sample_dt_s:.4g} samples at {1.0 / sample_dt_s:.6g} Hz, "
                        "not a whole number: the step must be a multiple of "
                        f"{sample_dt_s:.6g} s at this rate (`fogsf train --model-step-s`)")
    return d


@dataclass(frozen=True)
class FrontEnd:
    """What the front end needs (a subset of the artifact; the trainer can build one alone)."""

    t_ref_c: float
    t_min_c: float
    t_max_c: float
    decimation: int
    stuck_samples: int
    filter_alpha: np.ndarray  # [K] float32
    sample_dt_s: float = 0.1
    filter_tau_s: tuple[float, ...] = ()  # () : unknown (the alphas are then rescaled)

    @property
    def step_s(self) -> float:
        """The model step in seconds: D samples."""
        return self.decimation * self.sample_dt_s

    def at_rate(self, sample_dt_s: float) -> FrontEnd:
        """The same front end for samples every `sample_dt_s`: the model step (s), the lag
        filters' time constants (s) and the stuck-thermometer time (s) kept, in samples."""
        d = decimation_for(self.step_s, sample_dt_s)
        if d == self.decimation:  # the same samples per step, a step within 1 %: the same
            return self
        return replace(self, decimation=d, sample_dt_s=sample_dt_s,
                       stuck_samples=int(round(self.stuck_samples * self.sample_dt_s
                                               / sample_dt_s)),
                       filter_alpha=self._alpha_at(d, sample_dt_s))

    def _alpha_at(self, decimation: int, sample_dt_s: float) -> np.ndarray:
        """Filter coefficients for D samples of sample_dt_s: the same bits when the step is
        the same (to 1e-9), else `filter_alpha` afresh (rescaled when tau is unknown)."""
        new_step_s = decimation * sample_dt_s
        if abs(new_step_s - self.step_s) <= 1e-9 * self.step_s:
            return np.asarray(self.filter_alpha, dtype=np.float32)
        if len(self.filter_tau_s):
            return filter_alpha(list(self.filter_tau_s), decimation, sample_dt_s)
        keep = 1.0 - np.asarray(self.filter_alpha, dtype=np.float64)
        return (1.0 - keep ** (new_step_s / self.step_s)).astype(np.float32)


_CONFIG_KEYS: dict[str, type | tuple[type, ...]] = {
    "format": str, "model": str, "decimation": int, "sample_dt_s": (int, float),
    "t_ref_c": (int, float), "t_min_c": (int, float), "t_max_c": (int, float),
    "stuck_samples": int, "filter_tau_s": list, "n_features": int, "layers": int,
    "hidden": int,
}
POLY_KEY = "poly_head"  # optional stream.json key (absent = false): quad_w and cube_w present
POLY_ARRAYS = ("quad_w", "cube_w")
# optional stream.json key (absent = n_features): the first LSTM layer reads z[0:N] only
LSTM_INPUTS_KEY = "lstm_inputs"
# optional stream.json key (absent = false; needs the polynomial head): quad_w is [F], the
# diagonal only (y += quad_w[i] * (z_i * z_i))
QUAD_DIAG_KEY = "quad_diag"


@dataclass
class StreamModel:
    """A streaming model artifact (docs/stream-contract.md). Weights are float32 arrays."""

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
    sample_dt_s: float = 0.1
    extra: dict = field(default_factory=dict)  # unknown stream.json keys, kept on save
    poly_head: bool = False  # y also carries sum quad_w[i,j] z_i z_j + sum cube_w[i] z_i^3
    lstm_inputs: int | None = None  # the first LSTM layer reads z[0:N]; None: all F
    quad_diag: bool = False  # with poly_head: quad_w [F] is the diagonal of the quadratic

    def __post_init__(self) -> None:
        extra = dict(self.extra)
        if POLY_KEY in extra:  # given as a stream.json key: it is the field
            self.poly_head = self.poly_head or extra.pop(POLY_KEY)
        if QUAD_DIAG_KEY in extra:
            self.quad_diag = self.quad_diag or extra.pop(QUAD_DIAG_KEY)
        if LSTM_INPUTS_KEY in extra:
            value = extra.pop(LSTM_INPUTS_KEY)
            self.lstm_inputs = value if self.lstm_inputs is None else self.lstm_inputs
        self.extra = extra

    @property
    def n_lstm_inputs(self) -> int:
        """N: how many features (z[0:N]) the first LSTM layer reads (F unless narrowed)."""
        return self.n_features if self.lstm_inputs is None else self.lstm_inputs

    @property
    def lstm_inputs_narrowed(self) -> bool:
        """True when the first layer reads fewer than all F features (the key is written
        and enters the model id only then)."""
        return self.n_lstm_inputs != self.n_features

    # -- shape bookkeeping
    @property
    def n_filters(self) -> int:
        return len(self.filter_tau_s)

    def expected_shapes(self) -> dict[str, tuple[int, ...]]:
        k, f, h = self.n_filters, self.n_features, self.hidden
        shapes: dict[str, tuple[int, ...]] = {
            "filter_alpha": (k,), "feat_w": (f, 1 + k), "feat_b": (f,),
            "head_w": (h,), "head_b": (1,), "skip_w": (f,),
            "out_scale": (1,), "out_offset": (1,),
        }
        if self.poly_head:
            shapes["quad_w"] = (f,) if self.quad_diag else (f, f)
            shapes["cube_w"] = (f,)
        for layer in range(self.layers):
            n_in = self.n_lstm_inputs if layer == 0 else h
            shapes[f"lstm{layer}_w"] = (4 * h, n_in)
            shapes[f"lstm{layer}_r"] = (4 * h, h)
            shapes[f"lstm{layer}_b"] = (8 * h,)
        return shapes

    @property
    def params(self) -> int:
        """Trainable parameters (filter alphas included, they are part of the model)."""
        return int(sum(a.size for a in self.weights.values()))

    @property
    def summary(self) -> str:
        """One line for people: sizes, head, decimation, parameters."""
        poly = ((" + polynomial head (diagonal quadratic)" if self.quad_diag
                 else " + polynomial head") if self.poly_head else "")
        reads = (f" on z[0:{self.n_lstm_inputs}]" if self.lstm_inputs_narrowed else "")
        return (f"K={self.n_filters} filters, F={self.n_features} features, "
                f"{self.layers}x{self.hidden} LSTM{reads}{poly}, D={self.decimation}, "
                f"{self.params} parameters")

    @property
    def front_end(self) -> FrontEnd:
        return FrontEnd(t_ref_c=self.t_ref_c, t_min_c=self.t_min_c, t_max_c=self.t_max_c,
                        decimation=self.decimation, stuck_samples=self.stuck_samples,
                        filter_alpha=self.weights["filter_alpha"],
                        sample_dt_s=self.sample_dt_s,
                        filter_tau_s=tuple(float(t) for t in self.filter_tau_s))

    @property
    def step_s(self) -> float:
        """The model step in seconds (D samples of sample_dt_s)."""
        return self.decimation * self.sample_dt_s

    def at_rate(self, sample_dt_s: float) -> StreamModel:
        """The same model for samples every `sample_dt_s` (docs/stream-contract.md, "Sample
        rate"): D = step / dt (the step in seconds kept), filter alphas for that step (the
        same bits when it is the same), stuck_samples for the same time. The weights are
        unchanged; the model id changes (D and dt are part of it) and the result records
        the id it was re-rated from as `rated_from`."""
        fe = self.front_end.at_rate(sample_dt_s)
        if fe.decimation == self.decimation:
            return self
        weights = dict(self.weights)
        weights["filter_alpha"] = fe.filter_alpha
        extra = dict(self.extra)
        extra.setdefault("rated_from", self.model_id)
        model = replace(self, decimation=fe.decimation, sample_dt_s=float(sample_dt_s),
                        stuck_samples=fe.stuck_samples, weights=weights, extra=extra)
        model.validate()
        return model

    def config(self) -> dict:
        cfg = dict(self.extra)
        cfg.update({
            "format": FORMAT, "model": self.model, "decimation": self.decimation,
            "sample_dt_s": self.sample_dt_s, "t_ref_c": self.t_ref_c, "t_min_c": self.t_min_c,
            "t_max_c": self.t_max_c, "stuck_samples": self.stuck_samples,
            "filter_tau_s": list(self.filter_tau_s), "n_features": self.n_features,
            "layers": self.layers, "hidden": self.hidden, POLY_KEY: self.poly_head,
        })
        # the extensions after poly_head are written only when they change something, so
        # an artifact without them saves as it did before they existed
        if self.lstm_inputs_narrowed:
            cfg[LSTM_INPUTS_KEY] = self.n_lstm_inputs
        if self.quad_diag:
            cfg[QUAD_DIAG_KEY] = True
        return cfg

    @property
    def model_id(self) -> str:
        """16 hex digits of SHA-256 over the contract config and the float32 weight bytes.

        `poly_head` enters only when true, `lstm_inputs` only when below F, `quad_diag` only
        when true, so models without them keep the ids they had before the keys existed."""
        optional = {POLY_KEY: self.poly_head, LSTM_INPUTS_KEY: self.lstm_inputs_narrowed,
                    QUAD_DIAG_KEY: self.quad_diag}
        cfg = {k: v for k, v in self.config().items()
               if k in _CONFIG_KEYS or optional.get(k, False)}
        digest = hashlib.sha256(json.dumps(cfg, sort_keys=True, separators=(",", ":")).encode())
        for name in sorted(self.weights):
            arr = np.ascontiguousarray(self.weights[name], dtype="<f4")
            digest.update(f"{name}:{arr.shape}".encode())
            digest.update(arr.tobytes())
        return digest.hexdigest()[:16]

    # -- validation
    def validate(self, where: str = "model") -> None:
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
        for name, value in temps.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and -273.15 < value < 1000.0):
                raise bad(f"'{name}' must be a finite temperature in C, got {value!r}")
        if not isinstance(self.poly_head, bool):
            raise bad(f"'{POLY_KEY}' must be true or false, got {self.poly_head!r}")
        if not isinstance(self.quad_diag, bool):
            raise bad(f"'{QUAD_DIAG_KEY}' must be true or false, got {self.quad_diag!r}")
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
        expected = self.expected_shapes()
        missing = sorted(set(expected) - set(self.weights))
        if missing:
            quad = "[F]" if self.quad_diag else "[F, F]"
            why = (f" ({POLY_KEY} is true: the polynomial head needs quad_w {quad} and cube_w "
                   f"[F])" if self.poly_head and set(missing) & set(POLY_ARRAYS) else "")
            raise bad(f"{WEIGHTS_FILE} lacks array(s) {', '.join(missing)}{why}")
        stray = sorted(set(POLY_ARRAYS) & set(self.weights) - set(expected))
        if stray:
            raise bad(f"{WEIGHTS_FILE} holds {', '.join(stray)} but {POLY_KEY} is false: set "
                      f"\"{POLY_KEY}\": true in {CONFIG_FILE} or drop the array(s)")
        for name, shape in expected.items():
            arr = self.weights[name]
            if arr.dtype != np.float32:
                raise bad(f"array '{name}' must be float32, got {arr.dtype}")
            if arr.shape != shape:
                extra = (f" {LSTM_INPUTS_KEY}={self.n_lstm_inputs}" if name == "lstm0_w"
                         and self.lstm_inputs_narrowed else "")
                extra += f" {QUAD_DIAG_KEY}=true" if name == "quad_w" and self.quad_diag else ""
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

    # -- I/O
    def save(self, directory: str | Path) -> Path:
        """Write stream.json and stream_weights.npz into `directory` (created if needed)."""
        self.validate()
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        (out / CONFIG_FILE).write_text(json.dumps(self.config(), indent=2) + "\n")
        np.savez(out / WEIGHTS_FILE, **{k: np.asarray(v, np.float32)
                                        for k, v in sorted(self.weights.items())})
        return out

    @classmethod
    def load(cls, directory: str | Path) -> StreamModel:
        """Read and validate a model directory; every problem is a UserError naming the file."""
        d = Path(directory)
        if not d.is_dir():
            raise UserError(f"{d}: no such model directory (train one with `fogsf train ... "
                            f"--out {d}`)")
        cfg_path, w_path = d / CONFIG_FILE, d / WEIGHTS_FILE
        kind = _trained_kind(d)
        if not cfg_path.is_file() and kind is not None:
            raise UserError(f"{d}: a '{kind}' model has no firmware form; export and replay "
                            "take the LSTM models (lstm, lag-lstm, gsa-lstm)")
        for p in (cfg_path, w_path):
            if not p.is_file():
                raise UserError(f"{p}: missing; a model directory holds {CONFIG_FILE} and "
                                f"{WEIGHTS_FILE} (docs/stream-contract.md)")
        try:
            cfg = json.loads(cfg_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise UserError(f"{cfg_path}: not valid JSON: {e}") from None
        if not isinstance(cfg, dict):
            raise UserError(f"{cfg_path}: must hold a JSON object")
        if cfg.get("format") != FORMAT:
            raise UserError(f"{cfg_path}: format is {cfg.get('format')!r}, this fogsf reads "
                            f"{FORMAT!r}")
        for key, typ in _CONFIG_KEYS.items():
            if key not in cfg:
                raise UserError(f"{cfg_path}: missing key '{key}'")
            if not isinstance(cfg[key], typ) or isinstance(cfg[key], bool):
                raise UserError(f"{cfg_path}: key '{key}' has the wrong type "
                                f"({type(cfg[key]).__name__}): {cfg[key]!r}")
        try:
            with np.load(w_path, allow_pickle=False) as npz:
                weights = {k: npz[k] for k in npz.files}
        except (OSError, ValueError) as e:
            raise UserError(f"{w_path}: cannot read the weights: {e}") from None
        for key in (POLY_KEY, QUAD_DIAG_KEY):
            if not isinstance(cfg.get(key, False), bool):
                raise UserError(f"{cfg_path}: key '{key}' must be true or false, got "
                                f"{cfg[key]!r}")
        n_in = cfg.get(LSTM_INPUTS_KEY)
        if n_in is not None and (not isinstance(n_in, int) or isinstance(n_in, bool)):
            raise UserError(f"{cfg_path}: key '{LSTM_INPUTS_KEY}' must be an integer (the "
                            f"features z[0:N] the first LSTM layer reads), got {n_in!r}")
        model = cls(
            model=cfg["model"], decimation=cfg["decimation"], t_ref_c=float(cfg["t_ref_c"]),
            t_min_c=float(cfg["t_min_c"]), t_max_c=float(cfg["t_max_c"]),
            stuck_samples=cfg["stuck_samples"],
            filter_tau_s=[float(t) if isinstance(t, (int, float)) else t
                          for t in cfg["filter_tau_s"]],
            n_features=cfg["n_features"], layers=cfg["layers"], hidden=cfg["hidden"],
            weights=weights, sample_dt_s=float(cfg["sample_dt_s"]),
            extra={k: v for k, v in cfg.items()
                   if k not in _CONFIG_KEYS and k not in (POLY_KEY, LSTM_INPUTS_KEY,
                                                          QUAD_DIAG_KEY)},
            poly_head=cfg.get(POLY_KEY, False), lstm_inputs=n_in,
            quad_diag=cfg.get(QUAD_DIAG_KEY, False),
        )
        model.validate(where=str(d))
        return model


def _trained_kind(directory: Path) -> str | None:
    """The model kind `fogsf train` recorded in the directory's metrics.json, if any."""
    try:
        kind = json.loads((directory / "metrics.json").read_text()).get("model")
    except (OSError, ValueError, AttributeError):
        return None
    return kind if isinstance(kind, str) else None


# --- the front end -------------------------------------------------------------------------

class FrontEndOut(NamedTuple):
    step_index: np.ndarray  # [n_steps] int64: the sample index at which each model step runs
    s: np.ndarray  # [n_steps, 1+K] float32: [Tm - t_ref, y_1 - t_ref, ...]
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


def frontend(temp_c: np.ndarray, fe: FrontEnd) -> FrontEndOut:
    """Contract steps 1-4 up to s, for a whole log from reset, bit for bit as the C kernel."""
    tc, flags = sanitise_temperature(temp_c, fe)
    tm = block_means(tc, fe.decimation)
    alpha = np.asarray(fe.filter_alpha, dtype=np.float32)
    y = lag_filters(tm, alpha)
    t_ref = F32(fe.t_ref_c)
    s = np.empty((tm.shape[0], 1 + alpha.shape[0]), dtype=np.float32)
    s[:, 0] = tm - t_ref
    s[:, 1:] = y - t_ref
    step_index = np.arange(tm.shape[0], dtype=np.int64) * fe.decimation
    return FrontEndOut(step_index, s, flags)


# --- the model step ------------------------------------------------------------------------

def _seq_matvec(acc: np.ndarray, m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """acc + m @ v, accumulated over v's index in order (float32 rounding after every op)."""
    for j in range(v.shape[-1]):
        acc = acc + m[:, j] * v[j]
    return acc


def features(model: StreamModel, s: np.ndarray) -> np.ndarray:
    """z = feat_w s + feat_b per step, sequential from the bias: [n_steps, F] float32."""
    w, b = model.weights["feat_w"], model.weights["feat_b"]
    s = np.asarray(s, dtype=np.float32)
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
    flags: np.ndarray  # [n_steps] uint32 (SF_CLAMPED)
    h_last: np.ndarray  # [n_steps, H] float32 last layer's hidden state


def run_steps(model: StreamModel, s: np.ndarray) -> StepsOut:
    """The model over a sequence of s from reset (one row per model step)."""
    z = features(model, s)
    h, c = initial_state(model)
    n = z.shape[0]
    ys = np.empty(n, np.float32)
    sfs = np.empty(n, np.float32)
    fl = np.zeros(n, np.uint32)
    hl = np.empty((n, model.hidden), np.float32)
    for m in range(n):
        ys[m], sfs[m], fl[m], h, c = lstm_step(model, z[m], h, c)
        hl[m] = h[-1]
    return StepsOut(ys, sfs, fl, hl)


def expand(step_values: np.ndarray, n_samples: int, decimation: int) -> np.ndarray:
    """Per-sample held values: sample i gets the value of step i // D."""
    return np.asarray(step_values)[np.arange(n_samples) // decimation]


def correct(gyro_dps: np.ndarray, sf_ppm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """corrected = g / (1 + sf*1e-6) in double; non-finite -> 0.0 and GYRO_INVALID."""
    g = np.asarray(gyro_dps, dtype=np.float64)
    with np.errstate(all="ignore"):
        out = g / (1.0 + np.asarray(sf_ppm, dtype=np.float32).astype(np.float64) * 1e-6)
    bad = ~np.isfinite(out)
    out[bad] = 0.0
    return out, np.where(bad, np.uint32(FLAG_GYRO_INVALID), np.uint32(0)).astype(np.uint32)


class ReplayOut(NamedTuple):
    corrected_dps: np.ndarray  # [N] float64
    sf_ppm: np.ndarray  # [N] float32, held between model steps
    flags: np.ndarray  # [N] uint32


def replay(model: StreamModel, temp_c: np.ndarray, gyro_dps: np.ndarray) -> ReplayOut:
    """The whole contract per sample from reset: what the C kernel returns, bit for bit."""
    fe = frontend(temp_c, model.front_end)
    steps = run_steps(model, fe.s)
    n = fe.flags.shape[0]
    sf = expand(steps.sf_ppm, n, model.decimation)
    corrected, gflags = correct(gyro_dps, sf)
    flags = fe.flags | gflags | expand(steps.flags, n, model.decimation)
    return ReplayOut(corrected, sf, flags.astype(np.uint32))


# --- gate order ----------------------------------------------------------------------------
# torch.nn.LSTM stacks gates as (i, f, g, o); ONNX as (i, o, f, c) with c == g.
_TORCH_TO_ONNX = (0, 3, 1, 2)
_ONNX_TO_TORCH = (0, 2, 3, 1)


def _reorder(a: np.ndarray, order: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(a)
    blocks = np.split(a, 4, axis=0)
    return np.concatenate([blocks[k] for k in order], axis=0)


def torch_to_onnx_lstm(weight_ih: np.ndarray, weight_hh: np.ndarray, bias_ih: np.ndarray,
                       bias_hh: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """torch (i,f,g,o) -> ONNX (W [4H,in], R [4H,H], B [8H]) in gate order (i,o,f,c)."""
    w = _reorder(weight_ih, _TORCH_TO_ONNX)
    r = _reorder(weight_hh, _TORCH_TO_ONNX)
    b = np.concatenate([_reorder(bias_ih, _TORCH_TO_ONNX), _reorder(bias_hh, _TORCH_TO_ONNX)])
    return w.astype(np.float32), r.astype(np.float32), b.astype(np.float32)


def onnx_to_torch_lstm(w: np.ndarray, r: np.ndarray, b: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ONNX (W, R, B) -> torch (weight_ih, weight_hh, bias_ih, bias_hh)."""
    hid4 = np.asarray(w).shape[0]
    b = np.asarray(b)
    return (_reorder(w, _ONNX_TO_TORCH).astype(np.float32),
            _reorder(r, _ONNX_TO_TORCH).astype(np.float32),
            _reorder(b[:hid4], _ONNX_TO_TORCH).astype(np.float32),
            _reorder(b[hid4:], _ONNX_TO_TORCH).astype(np.float32))


# --- a random model ------------------------------------------------------------------------

def random_model(filters: int = 2, n_features: int = 4, layers: int = 1, hidden: int = 8,
                 decimation: int = 10, seed: int = 0, *, taus_s: list[float] | None = None,
                 t_ref_c: float = 20.0, t_min_c: float = -45.0, t_max_c: float = 55.0,
                 stuck_samples: int = 600, gain: float = 0.8, out_scale: float = 300.0,
                 out_offset: float = 40.0, poly_head: bool = False,
                 lstm_inputs: int | None = None, quad_diag: bool = False) -> StreamModel:
    """A seeded random model in the artifact format.

    Scaled so nothing saturates on chamber temperatures: z is O(1) over -45..55 C, every gate's
    pre-activation has a standard deviation of about `gain`, so h moves through the linear part
    of tanh and sf_ppm spans a few hundred ppm (out_scale) around out_offset.
    With `poly_head`, quad_w and cube_w come from a second generator seeded from `seed` (the
    other arrays are those of the same call without the head), scaled so that the quadratic
    and cubic terms are O(0.3) each, like the skip term. `lstm_inputs` N: the first LSTM
    layer reads z[0:N] (its W is [4H, N], so the draws after it differ); `quad_diag`: quad_w
    is the diagonal [F] only (drawn from the head's generator, at the scale of a row).
    """
    rng = np.random.default_rng(seed)
    if taus_s is None:
        taus_s = [float(t) for t in np.geomspace(300.0, 1200.0, filters)] if filters else []
    if len(taus_s) != filters:
        raise UserError(f"random_model: {filters} filters but {len(taus_s)} time constants")
    k, f, h = filters, n_features, hidden
    half_span = max(t_max_c - t_ref_c, t_ref_c - t_min_c)

    def u(shape: tuple[int, ...], scale: float, gen: np.random.Generator = rng) -> np.ndarray:
        return (gen.uniform(-1.0, 1.0, size=shape) * scale).astype(np.float32)

    weights: dict[str, np.ndarray] = {
        "filter_alpha": filter_alpha(taus_s, decimation),
        "feat_w": u((f, 1 + k), math.sqrt(3.0) / (half_span * math.sqrt(1 + k))),
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
    model = StreamModel(model="random-lstm", decimation=decimation, t_ref_c=t_ref_c,
                        t_min_c=t_min_c, t_max_c=t_max_c, stuck_samples=stuck_samples,
                        filter_tau_s=list(taus_s), n_features=f, layers=layers, hidden=h,
                        weights=weights, extra={"random_seed": seed}, poly_head=poly_head,
                        lstm_inputs=lstm_inputs, quad_diag=quad_diag)
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
