"""`fogsf train`: fit a compensation model on training logs, score it on a test log.

Models (all causal, all from the board thermometer and time only):
- `poly`: polynomial in T (the industry's first try);
- `polyrate`: polynomial in T with a filtered dT/dt (the industry standard);
- `mlp`: the paper's MLP baseline on (T, filtered dT/dt);
- `lstm`: the paper's LSTM on (T, filtered dT/dt), Table 1 defaults (2 x 200, batch 32,
  lr 0.02, Adam);
- `lag-lstm` (the default): the physics part fitted by least squares and carried exactly in
  the polynomial head, a 1 x 16 LSTM learning what it leaves. Its structure is chosen by
  the training logs (`structure="auto"`, `training.structure.choice`: held-out prediction
  of their parts among physics nodes with 1-3 nodes and the lag bank), or given: physics nodes
  (`models.structures.physics_nodes`: T and N first-order lags of it with identified time constants,
  a quadratic with cross terms), the lag bank (`models.structures.lag_bank`: T and its lags at 11
  time constants, ridge with a prior that logs of many held-out parts may lower; in the head's
  diagonal quadratic, or the full one with the cross terms those logs may add) or, with
  `structure="node"`, one or two effective sensing temperatures
  T_eff = w T + (1 - w) lag(T, tau), (tau, w) profiled over a grid; the LSTM reads the
  first BANK_LSTM_INPUTS features (T). A hysteresis (play) term joins the bank or the
  physics nodes when logs that turn back in temperature ask for it
  (`training.structure.hysteresis`; `hysteresis="on"` / `"off"` to force it);
- `gsa-lstm`: GSA searches batch size, layers, hidden units and learning rate (Table 1's
  four) and (tau, w) of T_eff; fitness is the error on the validation part of the training
  logs, never the test log.

The LSTM models run at the model rate (one step per D samples, state carried) and are
written in the firmware artifact format (stream.json + stream_weights.npz) for `fogsf export`.

`train_model` is the recipe: fit the SF part (`training.sf.fit`), the bias part
(`training.bias.head`), score (`training.score`, typed metrics: `training.results`), save
(`training.save`, metrics.json by `training.metrics_file`); stationary logs alone train a
bias-only model (`training.bias.stationary`). `run_training` gives its metrics as
metrics.json's content.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.read.sampling import common_rate
from fogsf.models.front_end import decimation_for
from fogsf.training.bias.head import finish_artifact, fit_bias_part
from fogsf.training.bias.model import BiasModel
from fogsf.training.bias.stationary import train_bias_only
from fogsf.training.bias.targets import check_mixed
from fogsf.training.fitted_model import Fitted, sf_predictions
from fogsf.training.metrics_file import to_json
from fogsf.training.options import TrainOptions
from fogsf.training.results import BiasOnlyMetrics, TrainMetrics
from fogsf.training.save import save
from fogsf.training.score import training_metrics
from fogsf.training.sf.fit import fit_sf

MIN_TRAIN_STEPS = 12  # model steps the training logs must span: a minute at 5 s


def run_training(opts: TrainOptions, train_logs: list[ChamberLog],
                 test_log: ChamberLog | None, out_dir: Path,
                 fit: Callable[[TrainOptions, list[ChamberLog]], Fitted] | None = None
                 ) -> tuple[dict[str, Any], Fitted]:
    """`train_model`, its metrics as metrics.json holds them (for the callers that read or
    extend that content: the fleet, `training.with_prior`, the benchmarks)."""
    metrics, fitted = train_model(opts, train_logs, test_log, out_dir, fit)
    return to_json(metrics), fitted  # type: ignore[return-value]


def train_model(opts: TrainOptions, train_logs: list[ChamberLog],
                test_log: ChamberLog | None, out_dir: Path,
                fit: Callable[[TrainOptions, list[ChamberLog]], Fitted] | None = None
                ) -> tuple[TrainMetrics | BiasOnlyMetrics, Fitted | BiasModel]:
    """Train, score, and write the model directory; returns the metrics and the fitted
    model (a `BiasModel` when the logs are stationary). `fit`: what fits the SF part
    instead of `fit_sf` (the fleet's prior, `training.with_prior`)."""
    train_logs = common_rate(train_logs)  # other rates, jitter, drops: on one grid of time
    for lg in [*train_logs, *([test_log] if test_log is not None else [])]:
        decimation_for(opts.model_step_s, lg.sample_dt_s, lg.path)  # before the fit, not after
    steps = sum(len(lg.time_s) * lg.sample_dt_s for lg in train_logs) / opts.model_step_s
    if steps < MIN_TRAIN_STEPS:  # fewer: the folds that choose the structure hold nothing
        names = ", ".join(str(lg.path) for lg in train_logs)
        raise UserError(f"{names}: the training logs span {steps * opts.model_step_s:.0f} s: "
                        f"too short to train on (at least {MIN_TRAIN_STEPS} model steps of "
                        f"{opts.model_step_s:g} s, --model-step-s)")
    if check_mixed(train_logs):  # stationary logs alone: a bias-only model
        return train_bias_only(opts, train_logs, test_log, out_dir)
    t0 = time.perf_counter()
    fitted = (fit or fit_sf)(opts, train_logs)
    sf_of = sf_predictions(fitted, opts.latitude_deg)  # once a log: the fit and the scores
    bias = fit_bias_part(opts, fitted, train_logs, sf_of)
    finish_artifact(fitted)
    train_s = time.perf_counter() - t0
    metrics = training_metrics(opts, fitted, bias, train_logs, test_log, sf_of, train_s)
    save(fitted, metrics, out_dir)
    return metrics, fitted
