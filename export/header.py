"""Render the generated C header `fogsf_model.h` from a model artifact (jinja2 templates)."""

from __future__ import annotations

import jinja2
import numpy as np

from trainer.stream import FORMAT, StreamModel

FORMAT_VERSION = 1
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
    return jinja2.Environment(loader=jinja2.PackageLoader("export", "templates"),
                              undefined=jinja2.StrictUndefined, keep_trailing_newline=True,
                              autoescape=False)


def render_header(model: StreamModel) -> str:
    """The bytes of fogsf_model.h: the same model gives the same text."""
    w = model.weights
    names = range(model.layers)
    context = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "model_id": model.model_id,
        "kind": model.model.replace('"', "'").replace("*/", "* /"), "params": model.params,
        "k": model.n_filters, "k_alloc": max(model.n_filters, 1), "f": model.n_features,
        "layers": model.layers, "hidden": model.hidden, "decimation": model.decimation,
        "sample_dt_s": c_float(model.sample_dt_s), "t_ref_c": c_float(model.t_ref_c),
        "t_min_c": c_float(model.t_min_c), "t_max_c": c_float(model.t_max_c),
        "stuck_samples": model.stuck_samples,
        "filter_tau_s": [c_float(t) for t in model.filter_tau_s],
        "filter_alpha": c_array(w["filter_alpha"]), "feat_w": c_array(w["feat_w"]),
        "feat_b": c_array(w["feat_b"]),
        "lstm": [{"n_in": model.n_features if layer == 0 else model.hidden,
                  "w": c_array(w[f"lstm{layer}_w"]), "r": c_array(w[f"lstm{layer}_r"]),
                  "b": c_array(w[f"lstm{layer}_b"])} for layer in names],
        "lstm_w_names": ", ".join(f"fogsf_lstm{layer}_w" for layer in names),
        "lstm_r_names": ", ".join(f"fogsf_lstm{layer}_r" for layer in names),
        "lstm_b_names": ", ".join(f"fogsf_lstm{layer}_b" for layer in names),
        "head_w": c_array(w["head_w"]), "skip_w": c_array(w["skip_w"]),
        "head_b": c_float(w["head_b"][0]), "out_scale": c_float(w["out_scale"][0]),
        "out_offset": c_float(w["out_offset"][0]),
    }
    return _environment().get_template("fogsf_model.h.j2").render(**context)
