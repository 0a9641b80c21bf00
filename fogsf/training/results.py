"""What `fogsf train` measured, as typed values: the scores of a sample-log model
(`TrainMetrics`), of a bias-only model (`BiasOnlyMetrics`), their bias blocks, and of a
plateau model (`PlateauMetrics`). `training.metrics_file` alone turns them into metrics.json
and reads them back.

The leaf blocks stay the dicts their measuring modules give (`log_metrics`, `bias_metrics`,
`bias_interval`, the structure and hysteresis records): metrics.json holds them as they are.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fogsf.training.interval.transfer import RampSegment, RateTransfer

Block = dict[str, float]  # one metrics block (`log_metrics`, `bias_metrics`): name -> figure
Record = dict[str, Any]  # a record another module builds and metrics.json holds unchanged


@dataclass(frozen=True)
class SFScore:
    """One log's SF error, ppm: before compensation (about the reference SF) and after."""

    before: Block
    after: Block


@dataclass(frozen=True)
class BiasScore:
    """One log's bias, deg/h, over its `windows` bias windows (`source`: stationary or
    +/- pairs): before (as measured) and after (measured - predicted)."""

    source: str
    windows: int
    before: Block
    after: Block


@dataclass(frozen=True)
class RampRateCheck:
    """The fastest ramp (C/min) of the training logs and of the test log, and whether the
    bias's rate term is extrapolated on the test log."""

    train_fastest_c_per_min: float
    test_fastest_c_per_min: float
    rate_term_extrapolated: bool


@dataclass(frozen=True)
class BiasTransfer:
    """The bias's rate-transfer interval on the test log (`bias.interval.bias_interval`'s
    record; None when the log gives it nothing) and, with it, the ramp-rate check."""

    interval: Record | None
    ramp_rates: RampRateCheck | None = None


@dataclass(frozen=True)
class BiasMetrics:
    """metrics.json's "bias" block. `tested`: a test log was given; `test` is then None when
    it measures no bias. `transfer`: present when the test was scored and the model carries
    the family the interval needs. `train`: one score per training log (None: no bias)."""

    model: Record  # `BiasModel.as_dict()`
    train: tuple[BiasScore | None, ...]
    tested: bool = False
    test: BiasScore | None = None
    transfer: BiasTransfer | None = None


@dataclass(frozen=True)
class TrainMetrics:
    """A sample-log model's metrics.json: the scores (`train`: one per training log), then
    the model's size, front end and choices. `test` and `rate_transfer` come with a test
    log, `bias` when the logs measure the bias, `model_id` and `kept_least_squares_start`
    with a firmware artifact, `prior` from `fogsf train --prior`."""

    model: str
    window_s: float
    settle_s: float
    noise_floor_ppm: float  # the test log's, else the first training log's
    train: tuple[SFScore, ...]
    train_ramp_rates_c_per_min: tuple[float, ...]
    train_ramp_segments: tuple[tuple[RampSegment, ...], ...]
    params: int
    weights_bytes: int
    features: tuple[str, ...]
    filter_tau_s: tuple[float, ...]
    decimation: int
    model_step_s: float
    sample_rate_hz: float
    ref_sf_ratio: float
    exportable: bool
    train_seconds: float
    seed: int
    val_chunk: tuple[float, float]
    test: SFScore | None = None
    rate_transfer: RateTransfer | None = None
    bias: BiasMetrics | None = None
    structure_choice: Record | None = None
    hysteresis_choice: Record | None = None
    model_id: str | None = None
    kept_least_squares_start: bool | None = None
    prior: Record | None = None


@dataclass(frozen=True)
class BiasOnlyMetrics:
    """A bias-only model's metrics.json (stationary logs alone: no SF measured)."""

    model: str
    window_s: float
    settle_s: float
    bias: BiasMetrics
    params: int
    weights_bytes: int
    features: tuple[str, ...]
    filter_tau_s: tuple[float, ...]
    decimation: int
    model_step_s: float
    sample_rate_hz: float
    train_seconds: float
    seed: int
    model_id: str
    exportable: bool = True


@dataclass(frozen=True)
class TableScore:
    """One table's plateaus before (the raw output) and after correction, RMS deg/h against
    the rate each sensed."""

    path: str
    plateaus: int
    before_dph: float
    after_dph: float


@dataclass(frozen=True)
class PlateauMetrics:
    """What `fogsf train` on plateau tables writes to metrics.json and prints."""

    model: str
    model_id: str
    rate_form: str
    rate_part: bool
    rate_part_measured: bool  # the tables hold two |rates| or more
    full_scale_dps: float
    temp_range_c: tuple[float, float]
    heldout_dph: float  # the chosen form on held-out plateaus (the choice's folds)
    linear_heldout_dph: float  # the best linear SF on the same folds
    folds: int
    train: list[TableScore]
    test: TableScore | None
    exportable: bool = True
