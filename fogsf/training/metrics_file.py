"""metrics.json, the record `fogsf train` leaves in a model directory: `to_json` turns a
run's typed metrics (`training.results`, `PlateauMetrics`) into its content, `write_metrics`
writes it, `from_json` and `read_metrics` read it back. The one place that knows its keys
and their order: the same run writes the same bytes (docs/train.md)."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

from fogsf.models.stream_format import METRICS_FILE
from fogsf.training.interval.transfer import RampSegment, RateTransfer
from fogsf.training.results import (
    BiasMetrics,
    BiasOnlyMetrics,
    BiasScore,
    BiasTransfer,
    PlateauMetrics,
    RampRateCheck,
    SFScore,
    TableScore,
    TrainMetrics,
)

Metrics = TrainMetrics | BiasOnlyMetrics | PlateauMetrics
JSON = dict[str, Any]


def write_metrics(out_dir: Path, metrics: Metrics | Mapping[str, Any]) -> Path:
    """OUT_DIR/metrics.json from typed metrics (or content already turned, as `fogsf train
    --prior` extends it); replaced whole, so a reader never sees half a file."""
    content = metrics if isinstance(metrics, Mapping) else to_json(metrics)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / METRICS_FILE
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(content, indent=2) + "\n")
    os.replace(tmp, path)
    return path


def read_metrics(directory: str | Path) -> Metrics:
    """The typed metrics of a model directory that `fogsf train` wrote."""
    return from_json(json.loads((Path(directory) / METRICS_FILE).read_text()))


def to_json(m: Metrics) -> JSON:
    """metrics.json's content (lists where the values hold tuples, as JSON reads back)."""
    if isinstance(m, PlateauMetrics):
        return asdict(m)
    if isinstance(m, BiasOnlyMetrics):
        return {"model": m.model, "bias_only": True, "window_s": m.window_s,
                "settle_s": m.settle_s, "bias": _bias_json(m.bias), "params": m.params,
                "weights_bytes": m.weights_bytes, "features": list(m.features),
                "filter_tau_s": list(m.filter_tau_s), "decimation": m.decimation,
                "model_step_s": m.model_step_s, "sample_rate_hz": m.sample_rate_hz,
                "exportable": m.exportable, "train_seconds": m.train_seconds,
                "seed": m.seed, "model_id": m.model_id}
    return _train_json(m)


def _train_json(m: TrainMetrics) -> JSON:
    out: JSON = {"model": m.model, "window_s": m.window_s, "settle_s": m.settle_s}
    # the noise floor is the test log's when there is one (written beside it), else the
    # first training log's (written after the training scores)
    if m.test is not None:
        out["noise_floor_ppm"] = m.noise_floor_ppm
        out["test"] = _sf_json(m.test)
    if m.rate_transfer is not None:
        out["rate_transfer"] = m.rate_transfer.as_dict()
    out["train"] = (_sf_json(m.train[0]) if len(m.train) == 1
                    else {f"log{i}": _sf_json(s) for i, s in enumerate(m.train)})
    out["train_ramp_rates_c_per_min"] = list(m.train_ramp_rates_c_per_min)
    out["train_ramp_segments"] = [[asdict(sg) for sg in lg] for lg in m.train_ramp_segments]
    if m.bias is not None:
        out["bias"] = _bias_json(m.bias)
    if m.test is None:
        out["noise_floor_ppm"] = m.noise_floor_ppm
    out.update({
        "params": m.params, "weights_bytes": m.weights_bytes, "features": list(m.features),
        "filter_tau_s": list(m.filter_tau_s), "decimation": m.decimation,
        "model_step_s": m.model_step_s, "sample_rate_hz": m.sample_rate_hz,
        "ref_sf_ratio": m.ref_sf_ratio, "exportable": m.exportable,
        "train_seconds": m.train_seconds, "seed": m.seed, "val_chunk": list(m.val_chunk)})
    for key, value in (("structure_choice", m.structure_choice),
                       ("hysteresis_choice", m.hysteresis_choice), ("model_id", m.model_id),
                       ("kept_least_squares_start", m.kept_least_squares_start),
                       ("prior", m.prior)):
        if value is not None:
            out[key] = value
    return out


def _sf_json(s: SFScore) -> JSON:
    return {"before": dict(s.before), "after": dict(s.after)}


def _bias_score_json(s: BiasScore | None) -> JSON | None:
    if s is None:
        return None
    return {"source": s.source, "windows": s.windows, "before": dict(s.before),
            "after": dict(s.after)}


def _bias_json(b: BiasMetrics) -> JSON:
    out: JSON = {"model": b.model}
    if b.tested:
        out["test"] = _bias_score_json(b.test)
    if b.transfer is not None:
        rt = b.transfer.interval
        if rt is not None and b.transfer.ramp_rates is not None:
            rt = {**rt, "ramp_rates": asdict(b.transfer.ramp_rates)}
        out["rate_transfer"] = rt
    out["train"] = {f"log{i}": _bias_score_json(s) for i, s in enumerate(b.train)}
    return out


def from_json(d: Mapping[str, Any]) -> Metrics:
    """The typed metrics of metrics.json's content (`to_json` of them gives it back)."""
    if d.get("model") == "plateau":
        test = d.get("test")
        return PlateauMetrics(**{
            **d, "temp_range_c": tuple(d["temp_range_c"]),
            "train": [TableScore(**t) for t in d["train"]],
            "test": None if test is None else TableScore(**test)})
    if d.get("bias_only"):
        return BiasOnlyMetrics(
            model=d["model"], window_s=d["window_s"], settle_s=d["settle_s"],
            bias=_bias_from(d["bias"]), params=d["params"], weights_bytes=d["weights_bytes"],
            features=tuple(d["features"]), filter_tau_s=tuple(d["filter_tau_s"]),
            decimation=d["decimation"], model_step_s=d["model_step_s"],
            sample_rate_hz=d["sample_rate_hz"], train_seconds=d["train_seconds"],
            seed=d["seed"], model_id=d["model_id"], exportable=d["exportable"])
    rt = d.get("rate_transfer")
    return TrainMetrics(
        model=d["model"], window_s=d["window_s"], settle_s=d["settle_s"],
        noise_floor_ppm=d["noise_floor_ppm"], train=_sf_from(d["train"]),
        train_ramp_rates_c_per_min=tuple(d["train_ramp_rates_c_per_min"]),
        train_ramp_segments=tuple(tuple(RampSegment(**sg) for sg in lg)
                                  for lg in d["train_ramp_segments"]),
        params=d["params"], weights_bytes=d["weights_bytes"], features=tuple(d["features"]),
        filter_tau_s=tuple(d["filter_tau_s"]), decimation=d["decimation"],
        model_step_s=d["model_step_s"], sample_rate_hz=d["sample_rate_hz"],
        ref_sf_ratio=d["ref_sf_ratio"], exportable=d["exportable"],
        train_seconds=d["train_seconds"], seed=d["seed"], val_chunk=tuple(d["val_chunk"]),
        test=SFScore(**d["test"]) if "test" in d else None,
        rate_transfer=None if rt is None else RateTransfer(**rt),
        bias=_bias_from(d["bias"]) if "bias" in d else None,
        structure_choice=d.get("structure_choice"),
        hysteresis_choice=d.get("hysteresis_choice"), model_id=d.get("model_id"),
        kept_least_squares_start=d.get("kept_least_squares_start"), prior=d.get("prior"))


def _sf_from(part: Mapping[str, Any]) -> tuple[SFScore, ...]:
    """One log's block, or `log0`, `log1`, ... in the order written."""
    if "after" in part:
        return (SFScore(**part),)
    return tuple(SFScore(**v) for v in part.values())


def _bias_score_from(s: Mapping[str, Any] | None) -> BiasScore | None:
    return None if s is None else BiasScore(**s)


def _bias_from(b: Mapping[str, Any]) -> BiasMetrics:
    transfer = None
    if "rate_transfer" in b:
        rt = None if b["rate_transfer"] is None else dict(b["rate_transfer"])
        rr = None if rt is None else rt.pop("ramp_rates", None)
        transfer = BiasTransfer(rt, None if rr is None else RampRateCheck(**rr))
    return BiasMetrics(
        model=b["model"], train=tuple(_bias_score_from(s) for s in b["train"].values()),
        tested="test" in b, test=_bias_score_from(b.get("test")), transfer=transfer)
