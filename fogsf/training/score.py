"""The scores of `fogsf train`: before/after metrics of the SF (and bias) on the training and
test logs, the rate-transfer check, and what metrics.json says of the model."""

from __future__ import annotations

from collections.abc import Callable

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
from fogsf.training.results import SFScore, TrainMetrics


def score(fitted: Fitted, logs: list[ChamberLog], ref: float, window_s: float,
          latitude_deg: float | None, settle_s: float = SETTLE_S) -> tuple[SFScore, ...]:
    """Before/after metrics of each of `logs`."""
    out = []
    for lg in logs:
        pred = per_sample_prediction(fitted, lg, latitude_deg)
        out.append(SFScore(
            log_metrics(lg, window_s, ref=ref, latitude_deg=latitude_deg, settle_s=settle_s),
            log_metrics(lg, window_s, latitude_deg=latitude_deg, correction_ppm=pred,
                        settle_s=settle_s)))
    return tuple(out)


def training_metrics(opts: TrainOptions, fitted: Fitted, bias: BiasModel | None,
                     train_logs: list[ChamberLog], test_log: ChamberLog | None,
                     sf_of: Callable[[ChamberLog], Column], train_s: float) -> TrainMetrics:
    """The run's metrics (metrics.json by `metrics_file`): the scores, then the model's size,
    front end and choices."""
    ref = opts.ref_sf if opts.ref_sf is not None else reference_sf_of_logs(
        train_logs, opts.window_s, opts.latitude_deg, settle_s=opts.settle_s)
    test = transfer = None
    if test_log is not None:
        (test,) = score(fitted, [test_log], ref, opts.window_s, opts.latitude_deg,
                        opts.settle_s)
    if test_log is not None and opts.transfer_check:
        transfer = rate_transfer(
            train_logs, test_log, opts.latitude_deg,
            per_sample_prediction(fitted, test_log, opts.latitude_deg),
            step_s=fitted.fe.step_s, window_s=opts.window_s, settle_s=opts.settle_s)
    train = score(fitted, train_logs, ref, opts.window_s, opts.latitude_deg, opts.settle_s)
    bias_block = None
    if bias is not None:  # the logs measure the bias: its model and before/after (deg/h)
        bias_block = score_logs(bias, train_logs, test_log, opts.window_s, opts.latitude_deg,
                                opts.settle_s, sf_of)
    features, taus = list(fitted.spec.names), list(fitted.spec.taus_s)
    if bias is not None and fitted.stream_model is not None and bias.n_shared:
        # the bias head's own features and filters, after the SF model's (`lead`)
        features += list(bias.fm.names[bias.n_shared:])
        taus += list(bias.fm.fe.filter_tau_s[len(taus):])
    hist = fitted.info.get("history", {})
    exported = fitted.stream_model is not None
    return TrainMetrics(
        model=fitted.kind, window_s=opts.window_s, settle_s=opts.settle_s,
        noise_floor_ppm=(test or train[0]).before["noise_floor_ppm"], train=train,
        # every ramp of every training log, read per segment (up and down, several a log)
        train_ramp_rates_c_per_min=tuple(training_ramp_rates(train_logs)),
        train_ramp_segments=tuple(tuple(ramp_segments(lg)) for lg in train_logs),
        params=fitted.params, weights_bytes=fitted.weights_bytes, features=tuple(features),
        filter_tau_s=tuple(taus), decimation=fitted.fe.decimation,
        model_step_s=fitted.fe.step_s, sample_rate_hz=1.0 / fitted.fe.sample_dt_s,
        ref_sf_ratio=ref, exportable=exported, train_seconds=train_s, seed=opts.seed,
        val_chunk=(opts.val_chunk[0], opts.val_chunk[1]), test=test, rate_transfer=transfer,
        bias=bias_block, structure_choice=fitted.info.get("structure_choice"),
        hysteresis_choice=fitted.info.get("hysteresis_choice"),
        model_id=fitted.stream_model.model_id if fitted.stream_model is not None else None,
        # best_iter 0: no training step beat the least-squares start on the validation
        # part, so the model is that start (its LSTM contributes nothing learned)
        kept_least_squares_start=bool(hist.get("best_iter", 1) == 0) if exported else None)
