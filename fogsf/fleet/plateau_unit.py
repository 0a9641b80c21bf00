"""A unit calibrated on a rate table's plateau tables (`fogsf fleet add --train TABLE`): the
plateau model `fogsf train` fits on them (the SF as a function of rate and temperature), and
the record the store keeps of it.

Its summary is the tables' static figures as `fogsf inspect` reads them (per temperature
group: SF, bias, nonlinearity, asymmetry; the SF's and the bias's drift with temperature),
before and after the model. It has no SF response over time: the design's prior and
`fleet check` (both built on responses to a temperature history) leave such units out."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.fleet.records import LogRecord, UnitRecord, file_sha256, utc_now
from fogsf.logs.measure.table_figures import TableFigures, table_figures
from fogsf.logs.plateau_table import PlateauTable
from fogsf.models.stream import StreamModel
from fogsf.training.rate.plateau_train import correct_rows
from fogsf.training.results import PlateauMetrics, TableScore

PLATEAU = "plateau"  # a plateau unit's structure (the store's `structure` column)


def is_plateau_unit(rec: UnitRecord) -> bool:
    return rec.summary.get("structure") == PLATEAU


def table_log(table: PlateauTable, role: str) -> LogRecord:
    """A table as the store keeps a log: its rows are plateaus, its span the tables' first
    start to the last end; a table has no sample rate (0) and no chamber ramps."""
    p = Path(table.path)
    span = float(table.time_s[-1] + table.duration_s[-1] - table.time_s[0])
    return LogRecord(path=str(p.resolve()) if p.is_file() else table.path,
                     sha256=file_sha256(p) if p.is_file() else "", rows=len(table),
                     span_s=span, sample_rate_hz=0.0, ramp_rates_c_per_min=[],
                     temp_min_c=float(np.min(table.temp_c)),
                     temp_max_c=float(np.max(table.temp_c)), role=role)


def _figures(tables: list[PlateauTable], model: StreamModel, latitude_deg: float | None,
             axis_cosine: float) -> tuple[TableFigures, TableFigures]:
    """The tables' static figures (their measuring rows) before and after the model."""
    keep = [t.measures for t in tables]
    r = np.concatenate([t.table_rate_dps[k] for t, k in zip(tables, keep, strict=True)])
    earth = np.concatenate([t.earth(latitude_deg, axis_cosine)[k]
                            for t, k in zip(tables, keep, strict=True)])
    g = np.concatenate([t.gyro_dps[k] for t, k in zip(tables, keep, strict=True)])
    temp = np.concatenate([t.temp_c[k] for t, k in zip(tables, keep, strict=True)])
    corrected, _ = correct_rows(model, temp, g)
    return table_figures(r, g - earth, temp), table_figures(r, corrected - earth, temp)


def _largest(values: list[float | None]) -> float | None:
    """The largest |value| with its sign (None when there is none)."""
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return max(vals, key=abs) if vals else None


def plateau_summary(before: TableFigures, metrics: PlateauMetrics) -> dict[str, Any]:
    """What `fleet list` and the report show of a plateau unit: the raw tables' SF drift,
    nonlinearity and asymmetry (the largest of the temperature groups'), bias drift and
    mean bias, and the per-group figures."""
    groups = [g.as_dict() for g in before.groups]
    bias = [g["bias_dph"] for g in groups if g["bias_dph"] is not None]
    return {"structure": PLATEAU, "rate_form": metrics.rate_form,
            "full_scale_dps": metrics.full_scale_dps,
            "temp_range_c": list(metrics.temp_range_c),
            "sf_drift_ppm_per_c": before.sf_drift_ppm_per_c,
            "sf_nonlinearity_ppm_fs": _largest([g["sf_nonlinearity_ppm_fs"] for g in groups]),
            "sf_asymmetry_ppm": _largest([g["sf_asymmetry_ppm"] for g in groups]),
            "bias_drift_dph_per_c": before.bias_drift_dph_per_c,
            "bias_dph": float(np.mean(bias)) if bias else None,
            "groups": groups}


def _scores(scores: list[TableScore]) -> tuple[float, float]:
    """(before, after) RMS deg/h over the tables' plateaus together."""
    n = sum(s.plateaus for s in scores)
    before = math.sqrt(sum(s.plateaus * s.before_dph ** 2 for s in scores) / n)
    return before, math.sqrt(sum(s.plateaus * s.after_dph ** 2 for s in scores) / n)


def plateau_record(unit: str, train: list[PlateauTable], test: PlateauTable | None,
                   model: StreamModel, metrics: PlateauMetrics, model_dir: str | Path,
                   options: dict[str, Any], keep_dir: bool = True) -> UnitRecord:
    """The record of a unit whose plateau model (`model`, its artifact) `fogsf train` has
    fitted and written to `model_dir` (`keep_dir` False: the folder is temporary, the record
    names none)."""
    before, after = _figures(train, model, options.get("latitude_deg"),
                             float(options.get("axis_cosine", 1.0)))
    figures: dict[str, Any] = {"model": PLATEAU, "heldout_dph": metrics.heldout_dph,
                               "linear_heldout_dph": metrics.linear_heldout_dph,
                               "plateaus": sum(s.plateaus for s in metrics.train)}
    figures["train_before_rms_dph"], figures["train_after_rms_dph"] = _scores(metrics.train)
    if metrics.test is not None:
        figures["test_before_rms_dph"], figures["test_after_rms_dph"] = _scores([metrics.test])
    # the report's SF curve: each temperature group's SF error before the model about the SF
    # at the tables' middle temperature (as a sample log's is about its reference's), after
    pairs = [(b.temp_c, b.sf_ppm, a.sf_ppm) for b, a in zip(before.groups, after.groups,
                                                             strict=True)
             if math.isfinite(b.sf_ppm) and math.isfinite(a.sf_ppm)]
    t, b, a = (np.array([x[k] for x in pairs]) for k in range(3))
    ref = float(np.interp(0.5 * (t.min() + t.max()), t, b)) if pairs else 0.0
    figures["sf_curve_log"] = "train"
    figures["sf_curve"] = {"temp_c": np.round(t, 3).tolist(),
                           "before_ppm": np.round(b - ref, 3).tolist(),
                           "after_ppm": np.round(a, 3).tolist()}
    logs = [table_log(t, "train") for t in train]
    logs += [table_log(test, "test")] if test is not None else []
    return UnitRecord(
        unit=unit, logs=logs, model_id=metrics.model_id,
        model_dir=str(Path(model_dir).resolve()) if keep_dir else "",
        fitted_with={"model": PLATEAU, "structure": PLATEAU, "rate_form": metrics.rate_form,
                     "rate_part": metrics.rate_part, "options": options},
        figures=figures, interval=None, summary=plateau_summary(before, metrics),
        created_utc=utc_now())
