"""One-off probes: each reproduces the evidence behind one default (docs/decisions.md)."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import log_metrics
from fogsf.models.features import FrontEnd, prepare
from fogsf.models.reference import expand
from fogsf.models.structures.physics_nodes import NodeTemperatures


def ratio(log: ChamberLog, pred: np.ndarray) -> float:
    """Test RMS / noise floor of `log` with `pred` (ppm, one per sample) taken off."""
    m = log_metrics(log, correction_ppm=pred)
    return m["rms_ppm"] / m["noise_floor_ppm"]


@dataclass
class StepScorer:
    """A test log seen through a training set's front end: its node temperatures at any
    time constant (`nt`), and the score (`ratio`) of a prediction per model step, held over
    each step's samples as the kernel holds it."""

    log: ChamberLog
    nt: NodeTemperatures
    decimation: int

    @classmethod
    def of(cls, log: ChamberLog, fe: FrontEnd) -> StepScorer:
        dt = prepare(log, fe, None, None)
        return cls(log, NodeTemperatures([dt.s[:, 0].astype(np.float64)], fe.step_s),
                   dt.decimation)

    def __call__(self, pred: np.ndarray) -> float:
        return ratio(self.log, expand(pred, len(self.log), self.decimation))


def finish(rows: list[dict], out: str | None, t0: float) -> int:
    """The probes' end: the rows as JSON to `out` (if given), the wall time printed."""
    if out:
        with open(out, "w") as fh:
            json.dump(rows, fh, indent=1)
    print(f"{time.perf_counter() - t0:.0f} s")
    return 0


def spread_cells(rows: list[dict], names: list[str]) -> str:
    """"name:median/p90/worst" of rows[i][name] for each name, on one line."""
    def cell(n: str) -> str:
        v = [r[n] for r in rows]
        return f"{n}:{np.median(v):.2f}/{np.percentile(v, 90):.2f}/{np.max(v):.2f}"

    return " ".join(cell(n) for n in names)
