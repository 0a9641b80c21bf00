"""The nets' hyper-parameters, torch-free: the options' defaults per model and the configs
the training loops (`training.net.loops`) read, so that `fogsf train --help` and the
least-squares models never load torch."""

from __future__ import annotations

from dataclasses import dataclass

from fogsf.training.options import TrainOptions


@dataclass
class LSTMConfig:
    layers: int = 2
    hidden: int = 200
    batch_size: int = 32
    lr: float = 0.02
    iters: int = 300
    window: int = 256  # model steps per training window
    burn_in: int = 16
    eval_every: int = 20
    seed: int = 0
    time_limit_s: float | None = None
    poly_head: bool = False  # carry the least-squares polynomial of the features exactly
    cubes: bool = True  # with poly_head: cubic terms too
    lstm_inputs: int | None = None  # the first LSTM layer reads z[:N]; None: every feature
    quad_diag: bool = False  # the polynomial head's quadratic is diagonal (the lag bank's)


@dataclass
class MLPConfig:
    hidden: tuple[int, ...] = (32, 32)
    lr: float = 0.01
    epochs: int = 1500
    eval_every: int = 25
    seed: int = 0


def lstm_defaults(model: str) -> dict:
    if model == "lstm":  # the paper's Table 1
        return {"layers": 2, "hidden": 200, "batch_size": 32, "lr": 0.02, "iters": 300}
    # lag-lstm, gsa-lstm: the physics least-squares polynomial of T_eff carried exactly in
    # the head, the LSTM learns the residual
    return {"layers": 1, "hidden": 16, "batch_size": 32, "lr": 0.01, "iters": 400,
            "poly_head": True}


def lstm_config(opts: TrainOptions, **over: object) -> LSTMConfig:
    """The model's defaults, the options' LSTM settings over them, then `over`."""
    d = lstm_defaults(opts.model)
    for k in ("layers", "hidden", "batch_size", "lr", "iters"):
        if getattr(opts, k) is not None:
            d[k] = getattr(opts, k)
    if opts.lstm_window is not None:
        d["window"] = opts.lstm_window
    d.update(over)
    return LSTMConfig(seed=opts.seed, **d)
