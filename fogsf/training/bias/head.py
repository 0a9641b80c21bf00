"""The bias part of `fogsf train` on logs that measure the bias: the bias model fitted on the
SF model's features (`training.bias.fit`) and joined to its artifact as the bias head, so
one kernel step corrects both."""

from __future__ import annotations

from collections.abc import Callable

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.read.columns import Column
from fogsf.models.stream_forms import diagonal_features, pure_play_rows
from fogsf.training.bias.artifact import with_bias_head
from fogsf.training.bias.features import feature_map_of
from fogsf.training.bias.fit import fit_bias
from fogsf.training.bias.model import BiasModel
from fogsf.training.fitted_model import Fitted
from fogsf.training.options import TrainOptions


def fit_bias_part(opts: TrainOptions, fitted: Fitted, logs: list[ChamberLog],
                  sf_of: Callable[[ChamberLog], Column]) -> BiasModel | None:
    """The bias model of `logs` (None when none measures the bias), its head joined to
    `fitted`'s artifact; the SF model's prediction `sf_of` taken off the pairs' plateaus."""
    shared = (None if fitted.stream_model is None else  # the bias head reads the SF's z
              feature_map_of(fitted.stream_model, logs, opts.model_step_s))
    bias = fit_bias(shared, logs, opts.window_s, opts.latitude_deg, opts.settle_s,
                    opts.model_step_s, sf_of=sf_of,
                    full_quad=fitted.info.get("lag_bank", {}).get("cross_terms", False))
    if bias is not None and fitted.stream_model is not None:  # one step corrects both
        fitted.stream_model = with_bias_head(fitted.stream_model, bias)
    return bias


def finish_artifact(fitted: Fitted) -> None:
    """The artifact as the firmware takes it: a play's row on its own state, a diagonal
    feature map stored as its diagonal; the parameter count follows."""
    if fitted.stream_model is not None:
        fitted.stream_model = diagonal_features(pure_play_rows(fitted.stream_model))
        fitted.params, fitted.weights_bytes = (fitted.stream_model.params,
                                               4 * fitted.stream_model.params)
