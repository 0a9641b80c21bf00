"""`fogsf train` on stationary logs alone: a bias-only model (no SF is measured, none is
predicted). The bias model (`bias_model`, its structure chosen by the log) has a front end
of its own; the artifact is a stream model whose SF part is exactly zero and whose bias head
carries it, so `fogsf export` and `fogsf replay` take it as any other."""

from __future__ import annotations

import json
import time
from pathlib import Path

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.training.bias.artifact import bias_only_stream_model
from fogsf.training.bias.fit import fit_bias
from fogsf.training.bias.model import BiasModel, score_logs
from fogsf.training.metrics_file import write_metrics
from fogsf.training.options import TrainOptions
from fogsf.training.results import BiasOnlyMetrics

KIND = "bias"  # metrics.json's "model" of a bias-only model


def train_bias_only(opts: TrainOptions, train_logs: list[ChamberLog],
                    test_log: ChamberLog | None, out_dir: Path
                    ) -> tuple[BiasOnlyMetrics, BiasModel]:
    """Fit, score and write metrics.json and train_info.json; returns (metrics, model)."""
    t0 = time.perf_counter()
    model = fit_bias(None, train_logs, opts.window_s, opts.latitude_deg, opts.settle_s,
                     opts.model_step_s)
    if model is None:  # a stationary log always measures the bias; kept for the type
        raise UserError("the training logs measure no bias")
    fm = model.fm
    train_s = time.perf_counter() - t0
    sm = bias_only_stream_model(model)
    n_params = sm.params
    metrics = BiasOnlyMetrics(
        model=KIND, window_s=opts.window_s, settle_s=opts.settle_s,
        bias=score_logs(model, train_logs, test_log, opts.window_s, opts.latitude_deg,
                        opts.settle_s),
        params=n_params, weights_bytes=4 * n_params,
        features=tuple(fm.names) or ("T", *(f"lag(T,{t:.0f}s)" for t in fm.fe.filter_tau_s)),
        filter_tau_s=tuple(fm.fe.filter_tau_s), decimation=fm.fe.decimation,
        model_step_s=fm.fe.step_s, sample_rate_hz=1.0 / fm.fe.sample_dt_s,
        train_seconds=train_s, seed=opts.seed, model_id=sm.model_id)
    write_metrics(out_dir, metrics)
    (out_dir / "train_info.json").write_text(json.dumps(
        {"model": KIND, "features": list(metrics.features),
         "filter_tau_s": list(metrics.filter_tau_s), "bias": model.as_dict()}, indent=2) + "\n")
    sm.save(out_dir)
    return metrics, model
