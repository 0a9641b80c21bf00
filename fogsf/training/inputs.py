"""What a fit reads: the training logs at the model rate, their normalised features and the
output scaling (`training_inputs`); the lag bank fitted to them by least squares
(`fit_bank_head`), alone a fast compensation for benches and the planner
(`bank_compensation`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import (
    FeatureSpec,
    Normaliser,
    SeqData,
    fit_normaliser,
    front_end_for,
    physical_normaliser,
    prepare,
)
from fogsf.models.front_end import FrontEnd
from fogsf.models.reference import expand
from fogsf.models.structures.lag_bank import BANK_LAMBDA, BankFit, bank_spec, fit_bank, n_curved
from fogsf.training.options import TrainOptions
from fogsf.training.structure.penalty import bank_prior


@dataclass
class TrainingInputs:
    """The logs at the model rate, their normalised features and the output scaling."""

    fe: FrontEnd
    data: list[SeqData]
    norm: Normaliser
    z: list[np.ndarray]
    offset: float
    scale: float


def training_inputs(opts: TrainOptions, logs: list[ChamberLog], spec: FeatureSpec,
                    targets: list[np.ndarray] | None = None,
                    physical: bool = False) -> TrainingInputs:
    """physical: features in one physical unit (`physical_normaliser`), not standardised."""
    fe = front_end_for(logs, opts.model_step_s, spec.taus_s, plays=spec.plays)
    ts = targets if targets is not None else [None] * len(logs)
    data = [prepare(lg, fe, opts.val_chunk, opts.latitude_deg, t, opts.window_s, opts.settle_s)
            for lg, t in zip(logs, ts, strict=True)]
    norm = physical_normaliser(spec) if physical else fit_normaliser(spec, data)
    y = np.concatenate([d.target_ppm[d.train_mask] for d in data])
    return TrainingInputs(fe, data, norm, [norm.apply(d.s) for d in data],
                          float(y.mean()), float(y.std() or 1.0))


def bank_data(ti: TrainingInputs) -> tuple[np.ndarray, np.ndarray]:
    """(z, y): the normalised features and targets of every measured step of the training
    logs, what the lag bank is fitted to."""
    z = np.concatenate([z[d.measured] for z, d in zip(ti.z, ti.data, strict=True)])
    y = np.concatenate([(d.target_ppm[d.measured] - ti.offset) / ti.scale for d in ti.data])
    return z, y


def fit_bank_head(ti: TrainingInputs, lam: float = BANK_LAMBDA, cross: bool = False
                  ) -> BankFit:
    """The lag bank (with its cross terms if `cross`) fitted by ridge (penalty `lam`) to the
    normalised targets of every step of the training logs (the validation part too: it only
    picks the LSTM's iteration, and the bank needs every transient the logs hold)."""
    return fit_bank(*bank_data(ti), lam, curved=n_curved(), cross=cross)


def bank_compensation(logs: list[ChamberLog], opts: TrainOptions | None = None
                      ) -> Callable[[ChamberLog], np.ndarray]:
    """The lag bank at its prior for `logs` (least squares; the default model's fixed part
    wherever the logs hold fewer than PENALTY_MIN_FOLDS held-out parts,
    `training.structure.penalty.bank_prior`) trained on `logs`: a function giving a log's SF
    error prediction (ppm vs nominal) per sample, held over each model step as the kernel
    holds it. Fast (no LSTM), for benches and the planner."""
    ti = training_inputs(opts or TrainOptions(model="lag-lstm"), logs, bank_spec(),
                         physical=True)
    bank = fit_bank_head(ti, bank_prior(logs, step_s=ti.fe.step_s))

    def predict(log: ChamberLog) -> np.ndarray:
        d = prepare(log, ti.fe, None, None)
        steps = bank.predict(ti.norm.apply(d.s)) * ti.scale + ti.offset
        return expand(steps, len(log), d.decimation)

    return predict
