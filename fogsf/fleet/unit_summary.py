"""What a unit's record keeps for the design's prior and `fleet check`: the trained model's
structure and its physical parameters (a minimal version, read from the model folder).

`summarize_unit(train_logs, model_dir)` -> {"structure": ..., "params": {...}}:
- structure: "physics<N>" (N physics nodes), "bank" (the lag bank, with "+cross" when its
  quadratic has cross terms), "node<N>", or the model kind for the other models; "+play"
  when a hysteresis term joined;
- params: the time constants of the model's filters (s, ascending: the physics nodes' are
  identified per unit, the bank's are fixed), and its polynomial head's coefficients in ppm
  with the features in their physical unit z = (T - 20 C) / 50 C: `lin` (per feature),
  `quad` (the upper triangle, or the diagonal), `cube`; the bias head's, when there is one,
  in deg/h (`bias_lin`, ...).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np


def _structure(metrics: dict, info: dict) -> str:
    kind = metrics.get("model", "?")
    if "physics_nodes" in info:
        s = f"physics{len(info['physics_nodes']['taus_s'])}"
    elif "lag_bank" in info:
        s = "bank" + ("+cross" if info["lag_bank"].get("cross_terms") else "")
    elif kind in ("lag-lstm", "gsa-lstm"):
        s = f"node{max(1, len(metrics.get('filter_tau_s', [])))}"
    else:
        return str(kind)
    if (metrics.get("hysteresis_choice") or {}).get("used"):
        s += "+play"
    return s


def _round(a: np.ndarray) -> list:
    return [float(f"{v:.6g}") for v in np.asarray(a, dtype=np.float64).ravel()]


def summarize_unit(train_logs: list, model_dir: str | Path) -> dict[str, Any]:
    """The unit's structure and parameters from the model `fogsf train` wrote into
    `model_dir` (metrics.json, train_info.json and, for the exportable models, the
    firmware artifact). `train_logs`: the logs it was trained on (unused here)."""
    d = Path(model_dir)
    metrics = json.loads((d / "metrics.json").read_text())
    info_path = d / "train_info.json"
    info = json.loads(info_path.read_text()) if info_path.is_file() else {}
    params: dict[str, Any] = {"tau_s": sorted(float(t) for t in
                                              metrics.get("filter_tau_s", []))}
    out: dict[str, Any] = {"structure": _structure(metrics, info), "params": params}
    if not metrics.get("exportable"):
        return out
    from fogsf.models.stream import StreamModel

    sm = StreamModel.load(d)
    w = sm.weights
    scale = float(np.asarray(w["out_scale"]).ravel()[0])
    k = sm.n_filters
    order = [0] + [1 + int(i) for i in np.argsort(sm.filter_tau_s)]  # T, then nodes by tau
    lin = np.asarray(w["skip_w"], dtype=np.float64) * scale
    params["lin_ppm"] = _round(lin[order] if lin.size == k + 1 else lin)
    if sm.poly_head:
        quad = np.asarray(w["quad_w"], dtype=np.float64) * scale
        if quad.ndim == 2 and quad.shape[0] == k + 1:
            quad = quad[np.ix_(order, order)]
            quad = (quad + quad.T - np.diag(np.diag(quad)))[np.triu_indices(k + 1)]
        params["quad_ppm"] = _round(quad)
        params["cube_ppm"] = _round(np.asarray(w["cube_w"], dtype=np.float64)[:1] * scale)
    return out
