"""Render the generated C model `NAME.h` + `NAME.c` from a model artifact (jinja2 templates).

NAME.h declares `extern const fogsf_model NAME` and NAME_* size macros; NAME.c holds the weights
as `static const` float32 arrays and the model struct, so several models link into one image.
"""

from __future__ import annotations

import re
import struct
import zlib
from pathlib import Path

import jinja2
import numpy as np
from numpy.typing import ArrayLike

from fogsf.models.front_end import play_half_c, play_source_w
from fogsf.models.rate_part import inverse_full_scale
from fogsf.models.stream import StreamModel
from fogsf.models.stream_format import FORMAT, RATE_ARRAY

# 1: one fogsf_model.h per build; 2: the model as data (NAME.h/.c); 3: the model struct
# also holds lstm_inputs and quad_diag (and feat_diag); 4 and 5: the model as the first
# member of a larger struct with a bias head or plays; 6: one fogsf_model for every model, its
# bias head and plays through their own pointers (NULL when absent), and two CRC-32s of its
# sizes and tables (fogsf_model_check); 7: a model with the rate part, in fields appended to
# the struct (format 6 holds them NULL and 0). The kernel accepts these two only.
FORMAT_VERSION = 6
FORMAT_VERSION_RATE = 7
DEFAULT_NAME = "gyro_model"
NAME_RULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,62}")
PER_LINE = 6


def c_float(value: float | np.floating) -> str:
    """A float32 as a C float literal that reads back to the same bits (%.9g)."""
    v = np.float32(value)
    if not np.isfinite(v):
        raise ValueError(f"cannot print non-finite weight {v} as a C literal")
    text = f"{float(v):.9g}"
    if not any(ch in text for ch in ".e"):
        text += ".0"
    return text + "f"


def c_array(values: np.ndarray) -> str:
    """Comma-separated float literals, PER_LINE per line, indented by 4."""
    flat = [c_float(v) for v in np.asarray(values, np.float32).ravel()] or ["0.0f"]
    lines = [", ".join(flat[i:i + PER_LINE]) for i in range(0, len(flat), PER_LINE)]
    return ",\n".join("    " + line for line in lines)


def _environment() -> jinja2.Environment:
    return jinja2.Environment(loader=jinja2.PackageLoader("fogsf.export", "templates"),
                              undefined=jinja2.StrictUndefined, keep_trailing_newline=True,
                              autoescape=False)


def check_name(name: str) -> str:
    """A model name is a C identifier that does not start with fogsf_ (the kernel's prefix)."""
    if not NAME_RULE.fullmatch(name) or name.lower().startswith("fogsf"):
        raise ValueError(f"model name {name!r} must be a C identifier (letters, digits, _) "
                         "not starting with 'fogsf': pass another --name")
    return name


def even_time_parts(model: StreamModel) -> int:
    """The parts of a model step in the even-time build (firmware/c/fogsf.c, n_parts): the
    front, one part per LSTM unit (L*H), the head and the bias head."""
    return model.layers * model.hidden + 3


def check_even_time(model: StreamModel) -> None:
    """The even-time build's per-sample bound holds only when a step's parts end before the
    next step (docs/stream-contract.md, "Even time"): the front at the step's sample and one
    part on each of the D - 1 samples after it, so D >= L*H + 3. Below it the pending parts
    run at the next step's sample, on top of its front (the same bits, not the bound), so a
    model exported for that build is refused (ValueError, one line) rather than re-rated:
    raising D would change the model's step in seconds, which its filters were trained for."""
    bound = even_time_parts(model)
    if model.decimation < bound:
        rate_hz = bound / model.step_s
        raise ValueError(
            f"--even-time: the model step is D = {model.decimation} samples, below the "
            f"even-time bound D >= L*H + 3 = {bound} (L={model.layers}, H={model.hidden}): "
            f"export at --sample-rate-hz {rate_hz:g} or more (D = {model.step_s:g} s x rate), "
            "train a smaller model, or build the kernel without FOGSF_EVEN_TIME")


def format_version(model: StreamModel) -> int:
    """The generated C's format version of the model: 7 with a rate part, else 6."""
    return FORMAT_VERSION_RATE if model.has_rate_part else FORMAT_VERSION


def _rate_context(model: StreamModel) -> dict:
    """The rate part's template values: R = 0 without it (the struct's fields NULL and 0)."""
    if not model.has_rate_part:
        return {"rate_rows": 0, "rate_coefs": 0}
    rate_w = model.weights[RATE_ARRAY]
    return {"rate_rows": rate_w.shape[0], "rate_coefs": rate_w.shape[1],
            "rate_w": c_array(rate_w), "rate_inv_fs": c_float(inverse_full_scale(model)),
            "rate_fs_dps": f"{model.rate_fs_dps:g}"}


def _context(model: StreamModel, name: str, even_time: bool = False) -> dict:
    w = model.weights
    names = range(model.layers)
    check_name(name)
    if even_time:
        check_even_time(model)
    return {
        "name": name, "upper": name.upper(), "guard": f"{name.upper()}_FOGSF_MODEL_H",
        "even_time": even_time, "even_time_parts": even_time_parts(model),
        "format": FORMAT, "model_id": model.model_id,
        "format_version": format_version(model), "embedded": False, **_rate_context(model),
        **{key: f"0x{value:08x}u" for key, value in
           zip(("crc32_sizes", "crc32"), model_crc32(model), strict=True)},
        "kind": model.model.replace('"', "'").replace("*/", "* /"), "params": model.params,
        "k": model.n_filters, "k_alloc": max(model.n_filters, 1), "f": model.n_features,
        "layers": model.layers, "hidden": model.hidden, "decimation": model.decimation,
        "sample_dt_s": c_float(model.sample_dt_s), "t_ref_c": c_float(model.t_ref_c),
        "t_min_c": c_float(model.t_min_c), "t_max_c": c_float(model.t_max_c),
        "stuck_samples": model.stuck_samples,
        "filter_tau_s": ", ".join(c_float(t) for t in model.filter_tau_s) or "none",
        "filter_alpha": c_array(w["filter_alpha"]), "feat_w": c_array(w["feat_w"]),
        "feat_b": c_array(w["feat_b"]),
        "lstm_inputs": model.n_lstm_inputs, "quad_diag": model.quad_diag,
        "feat_diag": model.feat_diag,
        "n_plays": model.n_plays,
        "play_width_c": ", ".join(f"{w:g}" for w in model.play_width_c),
        "play_half_c": c_array(play_half_c(model.play_width_c)) if model.n_plays else "",
        "play_source_w": (c_array(play_source_w(model.play_source_w, model.n_filters))
                          if model.n_plays else ""),
        "lstm": [{"n_in": model.n_lstm_inputs if layer == 0 else model.hidden,
                  "w": c_array(w[f"lstm{layer}_w"]), "r": c_array(w[f"lstm{layer}_r"]),
                  "b": c_array(w[f"lstm{layer}_b"])} for layer in names],
        "lstm_w_names": ", ".join(f"lstm{layer}_w" for layer in names),
        "lstm_r_names": ", ".join(f"lstm{layer}_r" for layer in names),
        "lstm_b_names": ", ".join(f"lstm{layer}_b" for layer in names),
        "head_w": c_array(w["head_w"]), "skip_w": c_array(w["skip_w"]),
        "head_b": c_float(w["head_b"][0]), "out_scale": c_float(w["out_scale"][0]),
        "out_offset": c_float(w["out_offset"][0]), "poly_head": model.poly_head,
        "quad_w": c_array(w["quad_w"]) if model.poly_head else "",
        "cube_w": c_array(w["cube_w"]) if model.poly_head else "",
        "bias_head": model.bias_head,
        **({"bias_b": c_float(w["bias_b"][0]), "bias_w": c_array(w["bias_w"]),
            "bias_quad_w": c_array(w["bias_quad_w"]),
            "bias_cube_w": c_array(w["bias_cube_w"])} if model.bias_head else {}),
    }


def _words(values: list[int]) -> bytes:
    return b"".join(struct.pack("<I", v) for v in values)


def _floats(values: ArrayLike) -> bytes:
    return np.asarray(values, np.float32).astype("<f4").ravel().tobytes()


def model_crc32(model: StreamModel) -> tuple[int, int]:
    """(crc32_sizes, crc32) of the generated C model, as fogsf_model_crc32 computes them:
    zlib's CRC-32 of the sizes and scalars (each as 32 bits, least significant byte first),
    then of every table in the struct's order (docs/firmware.md, "Model integrity")."""
    w = model.weights
    k, f, h, p = model.n_filters, model.n_features, model.hidden, model.n_plays
    head = _words([format_version(model), k, f, model.layers, h, model.decimation,
                   model.stuck_samples])
    head += _floats([model.sample_dt_s, model.t_ref_c, model.t_min_c, model.t_max_c,
                     w["head_b"][0], w["out_scale"][0], w["out_offset"][0]])
    head += _words([model.n_lstm_inputs, int(model.quad_diag), int(model.feat_diag),
                    int(model.poly_head), int(model.bias_head), p])
    if model.bias_head:
        head += _floats(w["bias_b"][0])
    if model.has_rate_part:  # R, Q and 1/FS after them, rate_w after the other tables
        head += _words(list(w[RATE_ARRAY].shape)) + _floats(inverse_full_scale(model))
    tables = [w["filter_alpha"][:k], w["feat_w"], w["feat_b"]]
    for layer in range(model.layers):
        tables += [w[f"lstm{layer}_w"], w[f"lstm{layer}_r"], w[f"lstm{layer}_b"]]
    tables += [w["head_w"], w["skip_w"]]
    if model.poly_head:
        tables += [w["quad_w"], w["cube_w"]]
    if model.bias_head:
        tables += [w["bias_w"], w["bias_quad_w"], w["bias_cube_w"]]
    if p:
        tables += [play_half_c(model.play_width_c),
                   play_source_w(model.play_source_w, model.n_filters)]
    if model.has_rate_part:
        tables.append(w[RATE_ARRAY])
    sizes = zlib.crc32(head)
    return sizes, zlib.crc32(b"".join(_floats(t) for t in tables), sizes)


def render_model(model: StreamModel, name: str = DEFAULT_NAME, even_time: bool = False
                 ) -> dict[str, str]:
    """{'NAME.h': text, 'NAME.c': text}: the same model, name and even_time give the same
    bytes. even_time: for the kernel built with FOGSF_EVEN_TIME (check_even_time; NAME.h
    says so and NAME.c refuses to compile in another build)."""
    ctx = _context(model, name, even_time)
    env = _environment()
    return {f"{name}.h": env.get_template("model.h.j2").render(**ctx),
            f"{name}.c": env.get_template("model.c.j2").render(**ctx)}


def write_model(model: StreamModel, out_dir: Path, name: str = DEFAULT_NAME,
                even_time: bool = False) -> list[Path]:
    """Write NAME.h and NAME.c into out_dir (created); returns their paths."""
    texts = render_model(model, name, even_time)  # refused before anything is written
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for file_name, text in texts.items():
        path = out_dir / file_name
        path.write_text(text)
        paths.append(path)
    return paths
