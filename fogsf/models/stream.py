"""The streaming model artifact "fogsf-stream-1" (docs/stream-contract.md): `StreamModel` (load,
save, validate, `model_id`, re-rate); its files and keys: `stream_format`; flags: `stream_flags`."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.models.front_end import FrontEnd
from fogsf.models.stream_checks import validate_model
from fogsf.models.stream_format import (
    _CONFIG_KEYS,
    BIAS_KEY,
    CONFIG_FILE,
    FEAT_DIAG_KEY,
    FORMAT,
    LSTM_INPUTS_KEY,
    PLAY_SOURCE_KEY,
    PLAY_WIDTH_KEY,
    POLY_KEY,
    QUAD_DIAG_KEY,
    RATE_ARRAY,
    RATE_KEY,
    WEIGHTS_FILE,
    _trained_kind,
)


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
    bias_head: bool = False  # the bias (deg/h) from z too: bias_b, bias_w, bias_quad_w, ...
    play_width_c: list[float] = field(default_factory=list)  # P plays' widths (C)
    play_source_w: list[list[float]] = field(default_factory=list)  # [P][1+K] sources
    feat_diag: bool = False  # F == 1+K+P and feat_w [F] is the diagonal of the feature map
    rate_fs_dps: float = 0.0  # > 0: the rate part's full scale, rate_w [R, Q] present

    def __post_init__(self) -> None:
        extra = dict(self.extra)
        if PLAY_WIDTH_KEY in extra:
            self.play_width_c = self.play_width_c or extra.pop(PLAY_WIDTH_KEY)
        if PLAY_SOURCE_KEY in extra:
            self.play_source_w = self.play_source_w or extra.pop(PLAY_SOURCE_KEY)
        if BIAS_KEY in extra:
            self.bias_head = self.bias_head or extra.pop(BIAS_KEY)
        if POLY_KEY in extra:  # given as a stream.json key: it is the field
            self.poly_head = self.poly_head or extra.pop(POLY_KEY)
        if QUAD_DIAG_KEY in extra:
            self.quad_diag = self.quad_diag or extra.pop(QUAD_DIAG_KEY)
        if FEAT_DIAG_KEY in extra:
            self.feat_diag = self.feat_diag or extra.pop(FEAT_DIAG_KEY)
        if RATE_KEY in extra:
            self.rate_fs_dps = self.rate_fs_dps or extra.pop(RATE_KEY)
        if LSTM_INPUTS_KEY in extra:
            value = extra.pop(LSTM_INPUTS_KEY)
            self.lstm_inputs = value if self.lstm_inputs is None else self.lstm_inputs
        self.extra = extra

    @property
    def has_rate_part(self) -> bool:
        """True when the model corrects the SF's dependence on rate (docs/stream-contract.md,
        "Optional rate part")."""
        return self.rate_fs_dps != 0.0

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

    @property
    def n_plays(self) -> int:
        return len(self.play_width_c)

    def expected_shapes(self) -> dict[str, tuple[int, ...]]:
        k, f, h = self.n_filters, self.n_features, self.hidden
        shapes: dict[str, tuple[int, ...]] = {
            "filter_alpha": (k,),
            "feat_w": (f,) if self.feat_diag else (f, 1 + k + self.n_plays), "feat_b": (f,),
            "head_w": (h,), "head_b": (1,), "skip_w": (f,),
            "out_scale": (1,), "out_offset": (1,),
        }
        if self.poly_head:
            shapes["quad_w"] = (f,) if self.quad_diag else (f, f)
            shapes["cube_w"] = (f,)
        if self.bias_head:
            shapes.update({"bias_b": (1,), "bias_w": (f,), "bias_quad_w": (f,),
                           "bias_cube_w": (f,)})
        if self.has_rate_part:  # its sizes are the array's own, bounded by the checks
            rate = self.weights.get(RATE_ARRAY)
            shapes[RATE_ARRAY] = tuple(rate.shape) if rate is not None and rate.ndim == 2 \
                else (1, 1)
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
        poly += " + bias head" if self.bias_head else ""
        plays = (f", {self.n_plays} play(s) of width "
                 f"{', '.join(f'{w:g}' for w in self.play_width_c)} C" if self.n_plays else "")
        feats = " (diagonal feat_w)" if self.feat_diag else ""
        if self.has_rate_part:
            r, q = self.weights[RATE_ARRAY].shape
            poly += (f" + rate part (|x|{f', x^2..x^{r}' if r > 1 else ''}, {q} "
                     f"coefficient(s) in T, full scale {self.rate_fs_dps:g} deg/s)")
        return (f"K={self.n_filters} filters{plays}, F={self.n_features} features{feats}, "
                f"{self.layers}x{self.hidden} LSTM{reads}{poly}, D={self.decimation}, "
                f"{self.params} parameters")

    @property
    def front_end(self) -> FrontEnd:
        return FrontEnd(t_ref_c=self.t_ref_c, t_min_c=self.t_min_c, t_max_c=self.t_max_c,
                        decimation=self.decimation, stuck_samples=self.stuck_samples,
                        filter_alpha=self.weights["filter_alpha"],
                        sample_dt_s=self.sample_dt_s,
                        filter_tau_s=tuple(float(t) for t in self.filter_tau_s),
                        play_width_c=tuple(float(w) for w in self.play_width_c),
                        play_source_w=tuple(tuple(float(v) for v in r)
                                            for r in self.play_source_w))

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
        if self.feat_diag:
            cfg[FEAT_DIAG_KEY] = True
        if self.bias_head:
            cfg[BIAS_KEY] = True
        if self.has_rate_part:
            cfg[RATE_KEY] = self.rate_fs_dps
        if self.n_plays:
            cfg[PLAY_WIDTH_KEY] = [float(w) for w in self.play_width_c]
            cfg[PLAY_SOURCE_KEY] = [[float(v) for v in r] for r in self.play_source_w]
        return cfg

    @property
    def model_id(self) -> str:
        """16 hex digits of SHA-256 over the contract config and the float32 weight bytes.

        `poly_head` enters only when true, `lstm_inputs` only when below F, `quad_diag`,
        `feat_diag` and `bias_head` only when true, the rate part and the plays only when
        there are some, so models without them keep the ids they had before the keys existed."""
        optional = {POLY_KEY: self.poly_head, LSTM_INPUTS_KEY: self.lstm_inputs_narrowed,
                    QUAD_DIAG_KEY: self.quad_diag, FEAT_DIAG_KEY: self.feat_diag,
                    BIAS_KEY: self.bias_head, RATE_KEY: self.has_rate_part,
                    PLAY_WIDTH_KEY: self.n_plays > 0, PLAY_SOURCE_KEY: self.n_plays > 0}
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
        """Refuse an inconsistent artifact with one message naming what is wrong
        (`stream_checks.validate_model`)."""
        validate_model(self, where)

    # -- I/O
    def save(self, directory: str | Path) -> Path:
        """Write stream.json and stream_weights.npz into `directory` (created if needed)."""
        self.validate()
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        (out / CONFIG_FILE).write_text(json.dumps(self.config(), indent=2) + "\n")
        weights = {k: np.asarray(v, np.float32) for k, v in sorted(self.weights.items())}
        np.savez(out / WEIGHTS_FILE, **weights)  # type: ignore[arg-type]  # ** read as allow_pickle
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
        for key in (POLY_KEY, QUAD_DIAG_KEY, BIAS_KEY, FEAT_DIAG_KEY):
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
                                                          QUAD_DIAG_KEY, BIAS_KEY,
                                                          FEAT_DIAG_KEY, RATE_KEY)},
            poly_head=cfg.get(POLY_KEY, False), lstm_inputs=n_in,
            quad_diag=cfg.get(QUAD_DIAG_KEY, False), bias_head=cfg.get(BIAS_KEY, False),
            feat_diag=cfg.get(FEAT_DIAG_KEY, False), rate_fs_dps=cfg.get(RATE_KEY, 0.0),
        )
        model.validate(where=str(d))
        return model
