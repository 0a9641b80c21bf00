"""What the design's prior needs from one unit, as a JSON-able dict (the fleet database
keeps it, so the database alone is enough for the prior).

`summarize_unit(train_logs, model_dir)`:
- `series`: the unit's training logs at the model rate (`unit_fit.StepSeries.as_dict`: the
  board temperature's block means and the measured SF target per step, float32): the
  sufficient data to refit the unit at whatever structure the design's prior settles on
  (node count, time constants started from the fleet's);
- `fits`: its physics-node fits at 1, 2 and 3 nodes (`unit_fit.UnitFit.as_dict`: log time
  constants and law coefficients, their estimation covariance, the residual variance);
- `slow`: what `fleet check`'s slow-part features read (`slow_part.unit_slow`: the program,
  the effective time constant, the SF curve in 5 min means; older records lack it and the
  check computes it from `series`);
- `hours`, `steps`, `model_step_s`; from MODEL_DIR/metrics.json (when there) the structure
  the default chose, the model id and the test's figures.
"""

from __future__ import annotations

import json
from pathlib import Path

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.logio import read_log
from fogsf.models.features import MODEL_STEP_S
from fogsf.prior.design_prior import K_CHOICES
from fogsf.prior.slow_part import unit_slow
from fogsf.prior.unit_fit import StepSeries, fit_unit, step_series

SUMMARY_VERSION = 1


def summarize_unit(train_logs: list[ChamberLog] | list[str] | list[Path],
                   model_dir: str | Path | None = None,
                   step_s: float = MODEL_STEP_S, latitude_deg: float | None = None) -> dict:

    logs = [_as_log(lg) for lg in train_logs]
    series = step_series(logs, step_s, latitude_deg)
    out: dict = {"summary_version": SUMMARY_VERSION, "model_step_s": series.step_s,
                 "hours": series.hours, "steps": int(series.y.size),
                 "series": series.as_dict(),
                 "fits": {str(k): fit_unit(series, k).as_dict() for k in K_CHOICES},
                 "slow": unit_slow(series)}
    metrics = Path(model_dir) / "metrics.json" if model_dir is not None else None
    if metrics is not None and metrics.is_file():
        m = json.loads(metrics.read_text())
        out["model"] = {"model_id": m.get("model_id"),
                        "structure": (m.get("structure_choice") or {}).get("chosen"),
                        "noise_floor_ppm": m.get("noise_floor_ppm")}
    return out


def _as_log(lg: ChamberLog | str | Path) -> ChamberLog:
    if isinstance(lg, ChamberLog):
        return lg

    return read_log(lg)


def series_of(summary: dict):  # noqa: ANN201 - unit_fit.StepSeries, imported late
    """The unit's step series back from its summary."""

    return StepSeries.from_dict(summary["series"])
