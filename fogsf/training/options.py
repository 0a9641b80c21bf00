"""The options of one training run (`fogsf train`'s, as data): what `run_training` and the
modules it calls read."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.models.features import MODEL_STEP_S

MODELS = ("poly", "polyrate", "mlp", "lstm", "lag-lstm", "gsa-lstm")
DEFAULT_MODEL = "lag-lstm"  # what `fogsf train` fits without --model
# lag-lstm: chosen by the training logs, physics nodes, the lag bank, one / two effective nodes
STRUCTURES = ("auto", "physics", "bank", "node")


@dataclass
class TrainOptions:
    model: str
    model_step_s: float = MODEL_STEP_S  # one model step per this many seconds of samples
    seed: int = 0
    val_chunk: tuple[float, float] = (0.4, 0.6)
    window_s: float = 100.0
    settle_s: float = SETTLE_S  # left out after each change of table rate (logs.measure.metrics)
    latitude_deg: float | None = None
    rate_tau_s: float = 120.0
    poly_degree: int = 3
    node: tuple[float, float] | None = None  # (tau_s, w) of T_eff; None: identified
    nodes: int = 1  # nodes of lag-lstm's node (1-2) or physics (1-3) structure
    structure: str = "auto"  # lag-lstm: "auto" (chosen by the logs), "physics", "bank", "node"
    # lag-lstm (bank, physics): a play (hysteresis) term: "auto" (when the training logs'
    # held-out blocks say it helps, `training.structure.hysteresis`), "on", "off"
    hysteresis: str = "auto"
    layers: int | None = None
    hidden: int | None = None
    batch_size: int | None = None
    lr: float | None = None
    iters: int | None = None
    lstm_window: int | None = None  # model steps per LSTM training window (default 256)
    # the lag bank's LSTM reads z[0:N] (T first, then the fastest lags); None: BANK_LSTM_INPUTS
    lstm_inputs: int | None = None
    gsa_agents: int = 8
    gsa_iters: int = 8
    gsa_fitness_iters: int = 80
    gsa_space: str = "extended"  # "paper": Table 1's four only
    gsa_paper_constants: bool = False  # G0=100, alpha=20 as in the paper; else SHORT_BUDGET
    workers: int | None = None
    dask: str | None = None
    progress: bool = True
    transfer_check: bool = True  # with a test log: the rate-transfer check and its interval
    ref_sf: float | None = None  # reference SF of the before-metrics; None: measured at 20 C
    extra: dict = field(default_factory=dict)


def check_options(opts: TrainOptions, train_logs: list[ChamberLog]) -> None:
    """A UserError for options that cannot train (before any fitting)."""
    if opts.model not in MODELS:
        raise UserError(f"unknown model {opts.model!r}; choose one of {', '.join(MODELS)}")
    if not train_logs:
        raise UserError("give at least one training log (--train)")
    if opts.nodes not in ((1, 2, 3) if opts.structure == "physics" else (1, 2)):
        raise UserError("--nodes must be 1 or 2 (1-3 with --structure physics)")
    if opts.structure not in STRUCTURES:
        raise UserError(f"--structure must be one of {', '.join(STRUCTURES)}")
    if opts.hysteresis not in ("auto", "on", "off"):
        raise UserError("--hysteresis must be one of auto, on, off")
    if opts.node is not None and opts.nodes != 1:
        raise UserError("--node gives one effective node; drop it or use --nodes 1")
    if opts.lstm_inputs is not None and not (opts.model == "lag-lstm"
                                             and opts.structure != "node"):
        raise UserError("--lstm-inputs narrows the LSTM of the lag bank or the physics "
                        "nodes: it needs --model lag-lstm without --structure node")
    if not (math.isfinite(opts.model_step_s) and opts.model_step_s > 0):
        raise UserError(f"--model-step-s must be > 0, got {opts.model_step_s!r}")
    lo, hi = opts.val_chunk
    if not 0.0 <= lo < hi <= 1.0 or hi - lo > 0.5:
        raise UserError("--val-chunk LO:HI must satisfy 0 <= LO < HI <= 1, at most half")
