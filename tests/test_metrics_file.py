"""metrics.json (training/metrics_file.py): the typed metrics turn into its keys in their
order, and read back into the same metrics (so the same run writes the same bytes)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from fogsf.training.interval.transfer import RampSegment, RateTransfer
from fogsf.training.metrics_file import from_json, read_metrics, to_json, write_metrics
from fogsf.training.results import (
    BiasMetrics,
    BiasOnlyMetrics,
    BiasScore,
    BiasTransfer,
    PlateauMetrics,
    RampRateCheck,
    SFScore,
    TableScore,
    TrainMetrics,
)

SF = SFScore({"rms_ppm": 400.0, "noise_floor_ppm": 8.5}, {"rms_ppm": 13.5, "noise_floor_ppm": 8.6})
BIAS_BLOCK = {"rms_dph": 1.5, "noise_floor_dph": 0.2}
BIAS = BiasScore("pairs", 40, BIAS_BLOCK, BIAS_BLOCK)
BIAS_METRICS = BiasMetrics(
    {"intercept_dph": 1.0, "sources": ["pairs"], "targets": 40}, (BIAS, None), tested=True,
    test=BIAS, transfer=BiasTransfer({"candidates": 6, "rms_interval_dph": [0.1, 0.2]},
                                     RampRateCheck(2.0, 1.0, False)))
TRAIN = TrainMetrics(
    model="lag-lstm", window_s=100.0, settle_s=2.0, noise_floor_ppm=8.5, train=(SF, SF),
    train_ramp_rates_c_per_min=(0.5, 2.0),
    train_ramp_segments=((RampSegment(0.0, 10800.0, 0.5),), (RampSegment(0.0, 2700.0, 2.0),)),
    params=1248, weights_bytes=4992, features=("T", "node(T,1466s)"), filter_tau_s=(1466.0,),
    decimation=50, model_step_s=5.0, sample_rate_hz=10.0, ref_sf_ratio=0.9999,
    exportable=True, train_seconds=11.2, seed=0, val_chunk=(0.4, 0.6), test=SF,
    rate_transfer=RateTransfer([0.5, 2.0], 1.0, True, 408, 29, 26.8, 46.5),
    bias=BIAS_METRICS, structure_choice={"chosen": "physics1"},
    hysteresis_choice={"used": False}, model_id="7a603a95fb7e1aef",
    kept_least_squares_start=True)
TAIL = ["params", "weights_bytes", "features", "filter_tau_s", "decimation", "model_step_s",
        "sample_rate_hz", "ref_sf_ratio", "exportable", "train_seconds", "seed", "val_chunk"]


def _round_trip(m: TrainMetrics | BiasOnlyMetrics | PlateauMetrics) -> dict:
    content = json.loads(json.dumps(to_json(m)))
    again = to_json(from_json(content))
    assert json.dumps(again, indent=2) == json.dumps(content, indent=2)
    return content


def test_a_sample_log_models_keys_keep_their_order_and_read_back() -> None:
    d = _round_trip(TRAIN)
    assert list(d) == ["model", "window_s", "settle_s", "noise_floor_ppm", "test",
                       "rate_transfer", "train", "train_ramp_rates_c_per_min",
                       "train_ramp_segments", "bias", *TAIL, "structure_choice",
                       "hysteresis_choice", "model_id", "kept_least_squares_start"]
    assert list(d["train"]) == ["log0", "log1"]
    assert list(d["bias"]) == ["model", "test", "rate_transfer", "train"]
    assert d["bias"]["rate_transfer"]["ramp_rates"]["train_fastest_c_per_min"] == 2.0
    assert d["bias"]["train"]["log1"] is None
    assert from_json(d) == replace(TRAIN, rate_transfer=from_json(d).rate_transfer)


def test_without_a_test_log_the_floor_follows_the_training_scores() -> None:
    m = replace(TRAIN, train=(SF,), test=None, rate_transfer=None, bias=None,
                structure_choice=None, hysteresis_choice=None, model_id=None,
                kept_least_squares_start=None, exportable=False)
    d = _round_trip(m)
    assert list(d) == ["model", "window_s", "settle_s", "train", "train_ramp_rates_c_per_min",
                       "train_ramp_segments", "noise_floor_ppm", *TAIL]
    assert list(d["train"]) == ["before", "after"]  # one log: its block, not log0
    prior = _round_trip(replace(m, prior={"used": True}))
    assert list(prior)[-1] == "prior"


def test_a_bias_test_log_without_windows_is_written_as_null() -> None:
    b = BiasMetrics({"sources": []}, (BIAS,), tested=True)
    d = _round_trip(BiasOnlyMetrics(
        model="bias", window_s=100.0, settle_s=2.0, bias=b, params=27, weights_bytes=108,
        features=("T",), filter_tau_s=(), decimation=50, model_step_s=5.0,
        sample_rate_hz=10.0, train_seconds=2.5, seed=0, model_id="abc"))
    assert d["bias"] == {"model": {"sources": []}, "test": None,
                         "train": {"log0": to_json_bias_score()}}
    assert list(d)[:2] == ["model", "bias_only"]


def to_json_bias_score() -> dict:
    return {"source": "pairs", "windows": 40, "before": BIAS_BLOCK, "after": BIAS_BLOCK}


def test_plateau_metrics_write_and_read_back(tmp_path: Path) -> None:
    m = PlateauMetrics("plateau", "id", "linear", False, False, 150.0, (36.0, 57.0), 1.0, 2.0,
                       13, [TableScore("a.csv", 96, 6310.0, 0.8)], None)
    _round_trip(m)
    path = write_metrics(tmp_path / "m", m)
    assert path.name == "metrics.json" and read_metrics(tmp_path / "m") == m
    assert not list((tmp_path / "m").glob("*.tmp"))
