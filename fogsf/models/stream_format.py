"""The streaming model artifact's format on disk (docs/stream-contract.md): its format name,
its two files, the keys stream.json must hold and their types, the optional keys and the
weight arrays they bring, and the kind of model `fogsf train` recorded in a directory
that holds no artifact."""

from __future__ import annotations

import json
from pathlib import Path

FORMAT = "fogsf-stream-1"
CONFIG_FILE = "stream.json"
WEIGHTS_FILE = "stream_weights.npz"
# what `fogsf train` records beside the artifact (written and read by
# `training.metrics_file`; here its "model" only, as this stage may not import training)
METRICS_FILE = "metrics.json"

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
# optional stream.json key (absent = false): the bias head over the same z, in deg/h:
# bias = bias_b + bias_w.z + bias_quad_w.z^2 + bias_cube_w.z^3 (each [F], bias_b [1])
BIAS_KEY = "bias_head"
BIAS_ARRAYS = ("bias_b", "bias_w", "bias_quad_w", "bias_cube_w")
# optional stream.json keys (absent = no plays): play (backlash) operators in the front end,
# p_j = min(max(p_j, x_j - w_j/2), x_j + w_j/2), x_j = v_j . [Tm, y_1, ..., y_K] (the
# source weights v_j, float32, summed in index order); s gains p_j - t_ref after the
# filters, so feat_w is [F, 1+K+P]
PLAY_WIDTH_KEY = "play_width_c"
PLAY_SOURCE_KEY = "play_source_w"
MAX_PLAY_WIDTH_C = 200.0
# optional stream.json key (absent = false; needs F == 1+K+P): feat_w is [F], the diagonal
# only (z_i = feat_w[i] * s_i + feat_b[i]; `diagonal_features` converts a model to it)
FEAT_DIAG_KEY = "feat_diag"


def _trained_kind(directory: Path) -> str | None:
    """The model kind `fogsf train` recorded in the directory's metrics.json, if any."""
    try:
        kind = json.loads((directory / METRICS_FILE).read_text()).get("model")
    except (OSError, ValueError, AttributeError):
        return None
    return kind if isinstance(kind, str) else None
# optional stream.json key (absent = no rate part): the full scale FS (deg/s) of the rate
# part, whose array rate_w [R, Q] holds, per term (row 0: |x|; row r >= 1: x^(r+1), with
# x = corrected / FS), its coefficients in deg/s of powers 0..Q-1 of s0 = Tm - t_ref
RATE_KEY = "rate_fs_dps"
RATE_ARRAY = "rate_w"
MAX_RATE_ROWS = 9  # |x| and x^2 .. x^9
MAX_RATE_TEMP_COEFS = 3  # coefficients at most quadratic in temperature
MAX_RATE_FS_DPS = 1.0e4
