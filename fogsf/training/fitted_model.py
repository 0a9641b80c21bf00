"""A trained model as the steps of `run_training` pass it on: its per-step prediction, what
to save, and its prediction per sample of a log."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.read.columns import Column, held, stand_in
from fogsf.models.features import FeatureSpec, SeqData, prepare
from fogsf.models.front_end import FrontEnd
from fogsf.models.stream import StreamModel


@dataclass
class Fitted:
    """A trained model: per-step predictions (ppm vs nominal) and what to save."""

    kind: str
    spec: FeatureSpec
    fe: FrontEnd
    predict_steps: Callable[[SeqData], np.ndarray]
    params: int
    weights_bytes: int
    info: dict
    stream_model: StreamModel | None = None  # the firmware artifact (exportable models)
    torch_state: dict | None = None


def per_sample_prediction(fitted: Fitted, log: ChamberLog, latitude_deg: float | None
                          ) -> np.ndarray:
    d = prepare(log, fitted.fe, None, latitude_deg)
    # a log on disk: the prediction made a block at a time too
    return stand_in(held(fitted.predict_steps(d), log.time_s, d.decimation))


def sf_predictions(fitted: Fitted, latitude_deg: float | None
                   ) -> Callable[[ChamberLog], Column]:
    """The SF model's prediction of a log, made once a log (the bias fit and the scores read
    it, off the pairs' plateaus)."""
    seen: dict[int, Column] = {}

    def sf_of(log: ChamberLog) -> Column:
        if id(log) not in seen:
            seen[id(log)] = per_sample_prediction(fitted, log, latitude_deg)
        return seen[id(log)]

    return sf_of
