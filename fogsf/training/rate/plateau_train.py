"""`fogsf train` on plateau tables (docs/train.md, "Plateau tables"): the tables read into
`PlateauRows`, the model fitted, each table's plateaus corrected as the kernel corrects a
sample (`correct_rows`), and the figures of the run as `PlateauMetrics`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.plateau_table import PlateauTable
from fogsf.models import reference
from fogsf.models.stream import StreamModel
from fogsf.training.metrics_file import write_metrics
from fogsf.training.rate.plateau_model import PlateauFit, PlateauRows, fit_plateau_model
from fogsf.training.results import PlateauMetrics, TableScore

DPS_TO_DPH = 3600.0


def rows_of(tables: list[PlateauTable], latitude_deg: float | None, axis_cosine: float
            ) -> PlateauRows:
    """The measuring rows of `tables`, in the order given: the rate each sensed is the
    table's plus the earth's on the axis."""
    keep = [t.measures for t in tables]
    return PlateauRows(
        np.concatenate([t.gyro_dps[k] for t, k in zip(tables, keep, strict=True)]),
        np.concatenate([(t.table_rate_dps + t.earth(latitude_deg, axis_cosine))[k]
                        for t, k in zip(tables, keep, strict=True)]),
        np.concatenate([t.temp_c[k] for t, k in zip(tables, keep, strict=True)]))


def check_static(model: StreamModel, where: str) -> None:
    """A plateau table has no time series: only a model without lag filters or plays (whose
    output at a temperature does not depend on the history) corrects its rows."""
    if model.n_filters or model.n_plays:
        raise UserError(f"{where}: the model has {model.n_filters} lag filter(s) and "
                        f"{model.n_plays} play(s), which need the temperature's history; a "
                        "plateau table holds means only: replay a sample log, or train on "
                        "plateau tables")


def correct_rows(model: StreamModel, temp_c: np.ndarray, gyro_dps: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(corrected deg/s, flags) per row: each row as the kernel corrects a sample at that
    temperature from reset (its priming step), what a static model outputs at any time."""
    out = np.empty(len(temp_c))
    flags = np.zeros(len(temp_c), np.uint32)
    for i in range(len(temp_c)):
        r = reference.replay(model, temp_c[i:i + 1], gyro_dps[i:i + 1])
        out[i], flags[i] = r.corrected_dps[0], r.flags[0]
    return out, flags


def rms_dph(err_dps: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(err_dps))) * DPS_TO_DPH)


def score_table(model: StreamModel, table: PlateauTable, latitude_deg: float | None,
                axis_cosine: float) -> TableScore:
    rows = rows_of([table], latitude_deg, axis_cosine)
    corrected, _ = correct_rows(model, rows.temp_c, rows.gyro_dps)
    return TableScore(table.path, len(rows), rms_dph(rows.gyro_dps - rows.rate_dps),
                      rms_dph(corrected - rows.rate_dps))


def train_plateaus(train: list[PlateauTable], test: PlateauTable | None,
                   latitude_deg: float | None, axis_cosine: float
                   ) -> tuple[PlateauFit, PlateauMetrics]:
    """Fit on `train`, score on every table."""
    rows = rows_of(train, latitude_deg, axis_cosine)
    fit = fit_plateau_model(rows)
    model = fit.model
    metrics = PlateauMetrics(
        "plateau", model.model_id, fit.form.describe(), fit.form.has_rate_part,
        fit.rate_part_allowed, fit.full_scale_dps,
        (float(rows.temp_c.min()), float(rows.temp_c.max())), fit.heldout_dph,
        fit.linear_score_dph, fit.choice.folds,
        [score_table(model, t, latitude_deg, axis_cosine) for t in train],
        score_table(model, test, latitude_deg, axis_cosine) if test is not None else None)
    return fit, metrics


def save_plateau_model(fit: PlateauFit, metrics: PlateauMetrics, out: Path) -> None:
    write_metrics(out, metrics)
    fit.model.save(out)


def metrics_lines(m: PlateauMetrics) -> list[str]:
    """What `fogsf train` prints."""
    lo, hi = m.temp_range_c
    lines = [f"plateau model: {m.rate_form}; {lo:.1f} .. {hi:.1f} C, full scale "
             f"{m.full_scale_dps:g} deg/s"]
    if not m.rate_part_measured:
        lines.append("  rate part off: the tables hold one |rate| only, which cannot tell a "
                     "rate term from the SF")
    lines.append(f"  held-out plateaus ({m.folds} folds): {m.heldout_dph:.2f} deg/h RMS "
                 f"(a linear SF: {m.linear_heldout_dph:.2f})")
    for s in m.train:
        lines.append(f"  train {s.path}: {s.plateaus} plateaus, {s.before_dph:.2f} -> "
                     f"{s.after_dph:.2f} deg/h RMS")
    if m.test is not None:
        lines.append(f"  test  {m.test.path}: {m.test.plateaus} plateaus, "
                     f"{m.test.before_dph:.2f} -> {m.test.after_dph:.2f} deg/h RMS")
    return lines
