"""The scores of `fogsf train`: before/after metrics of the SF (and bias) on the training and
test logs, the rate-transfer check, and what metrics.json says of the model."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import log_metrics
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.measure.sf_reference import reference_sf_of_logs
from fogsf.logs.read.columns import Column
from fogsf.training.bias.model import BiasModel, score_logs
from fogsf.training.fitted_model import Fitted, per_sample_prediction
from fogsf.training.interval.rate_transfer import rate_transfer
from fogsf.training.interval.transfer import ramp_segments, training_ramp_rates
from fogsf.training.options import TrainOptions


def score(fitted: Fitted, logs: list[ChamberLog], ref: float, window_s: float,
          latitude_deg: float | None, settle_s: float = SETTLE_S) -> dict:
    """Before/after metrics over `logs` (their windows pooled)."""
    if len(logs) != 1:
        return {f"log{i}": score(fitted, [lg], ref, window_s, latitude_deg, settle_s)
                for i, lg in enumerate(logs)}
    lg = logs[0]
    pred = per_sample_prediction(fitted, lg, latitude_deg)
    return {"before": log_metrics(lg, window_s, ref=ref, latitude_deg=latitude_deg,
                                  settle_s=settle_s),
            "after": log_metrics(lg, window_s, latitude_deg=latitude_deg,
                                 correction_ppm=pred, settle_s=settle_s)}


def training_metrics(opts: TrainOptions, fitted: Fitted, bias: BiasModel | None,
                     train_logs: list[ChamberLog], test_log: ChamberLog | None,
                     sf_of: Callable[[ChamberLog], Column], train_s: float) -> dict:
    """metrics.json's content: the scores, then the model's size, front end and choices."""
    ref = opts.ref_sf if opts.ref_sf is not None else reference_sf_of_logs(
        train_logs, opts.window_s, opts.latitude_deg, settle_s=opts.settle_s)
    metrics: dict = {"model": fitted.kind, "window_s": opts.window_s,
                     "settle_s": opts.settle_s}
    if test_log is not None:
        test = score(fitted, [test_log], ref, opts.window_s, opts.latitude_deg, opts.settle_s)
        metrics["noise_floor_ppm"] = test["before"]["noise_floor_ppm"]
        metrics["test"] = test
    if test_log is not None and opts.transfer_check:
        metrics["rate_transfer"] = rate_transfer(
            train_logs, test_log, opts.latitude_deg,
            per_sample_prediction(fitted, test_log, opts.latitude_deg),
            step_s=fitted.fe.step_s, window_s=opts.window_s, settle_s=opts.settle_s).as_dict()
    metrics["train"] = score(fitted, train_logs, ref, opts.window_s, opts.latitude_deg,
                             opts.settle_s)
    # every ramp of every training log, read per segment (up and down, several rates a log)
    metrics["train_ramp_rates_c_per_min"] = training_ramp_rates(train_logs)
    metrics["train_ramp_segments"] = [[asdict(sg) for sg in ramp_segments(lg)]
                                      for lg in train_logs]
    if bias is not None:  # the logs measure the bias: its model and before/after (deg/h)
        metrics["bias"] = score_logs(bias, train_logs, test_log, opts.window_s,
                                     opts.latitude_deg, opts.settle_s, sf_of)
    if "noise_floor_ppm" not in metrics:
        first = metrics["train"] if "after" in metrics["train"] else metrics["train"]["log0"]
        metrics["noise_floor_ppm"] = first["before"]["noise_floor_ppm"]
    features, taus = list(fitted.spec.names), list(fitted.spec.taus_s)
    if bias is not None and fitted.stream_model is not None and bias.n_shared:
        # the bias head's own features and filters, after the SF model's (`lead`)
        features += list(bias.fm.names[bias.n_shared:])
        taus += list(bias.fm.fe.filter_tau_s[len(taus):])
    metrics.update({
        "params": fitted.params,
        "weights_bytes": fitted.weights_bytes,
        "features": features,
        "filter_tau_s": taus,
        "decimation": fitted.fe.decimation,
        "model_step_s": fitted.fe.step_s,
        "sample_rate_hz": 1.0 / fitted.fe.sample_dt_s,
        "ref_sf_ratio": ref,
        "exportable": fitted.stream_model is not None,
        "train_seconds": train_s,
        "seed": opts.seed,
        "val_chunk": list(opts.val_chunk),
    })
    if "structure_choice" in fitted.info:
        metrics["structure_choice"] = fitted.info["structure_choice"]
    if "hysteresis_choice" in fitted.info:
        metrics["hysteresis_choice"] = fitted.info["hysteresis_choice"]
    if fitted.stream_model is not None:
        metrics["model_id"] = fitted.stream_model.model_id
        hist = fitted.info.get("history", {})
        # best_iter 0: no training step beat the least-squares start on the validation part,
        # so the model is that start (its LSTM contributes nothing learned)
        metrics["kept_least_squares_start"] = bool(hist.get("best_iter", 1) == 0)
    return metrics
