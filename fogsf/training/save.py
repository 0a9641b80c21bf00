"""The model directory `fogsf train` writes: metrics.json, train_info.json, the firmware
artifact (stream.json, stream_weights.npz) of the exportable models, the torch state of the
nets, and gsa-lstm's search record."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fogsf.training.fitted_model import Fitted
from fogsf.training.metrics_file import write_metrics
from fogsf.training.results import TrainMetrics


def save(fitted: Fitted, metrics: TrainMetrics, out_dir: Path) -> None:
    info = {k: v for k, v in fitted.info.items() if k != "gsa_result"}
    write_metrics(out_dir, metrics)
    (out_dir / "train_info.json").write_text(json.dumps(
        {"model": fitted.kind, "features": list(metrics.features),
         "filter_tau_s": list(metrics.filter_tau_s), **info}, indent=2, default=_json) + "\n")
    if fitted.stream_model is not None:
        fitted.stream_model.save(out_dir)
    if fitted.torch_state is not None:
        import torch  # the nets' state only: the least-squares models never load torch

        torch.save(fitted.torch_state, out_dir / "model.pt")
    res = fitted.info.get("gsa_result")
    if res is not None:
        res.save_json(out_dir / "gsa_fitness.json")
        res.plot(out_dir / "gsa_fitness.png")


def _json(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(type(o).__name__)
