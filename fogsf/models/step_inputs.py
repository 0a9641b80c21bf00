"""The front end's per-step output and the training targets of a log of any length, a block
of samples at a time: the same bits as `reference.frontend(...).s` and `step_targets` over
the whole log, without their per-sample arrays (a 24 h log at 100 Hz is 8.6 M samples; a
model step holds hundreds).

The front end's sanitising carries one number from block to block (the last finite
temperature, clamped), and blocks start on a model step's first sample, so each step's
float32 sequential mean is that of the whole-log computation; the lag filters then run
over the step means (one per step). The targets' per-step means are made over blocks that
start on a step too.
"""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.model_steps import step_means
from fogsf.logs.measure.plateaus import SETTLE_S, settled_plateaus
from fogsf.logs.measure.windows import _signal_at, _signal_parts
from fogsf.logs.read import columns
from fogsf.models.f32 import F32
from fogsf.models.front_end import FrontEnd
from fogsf.models.reference import state_of


def _block_steps(decimation: int) -> int:
    """Model steps read at a time: about READ_SAMPLES samples."""
    return max(1, columns.READ_SAMPLES // decimation)


def step_temperatures(temp_c: columns.Column, fe: FrontEnd) -> np.ndarray:
    """Tm per model step (float32), as `reference.block_means(sanitise_temperature(...))`."""
    n, d = len(temp_c), fe.decimation
    if n == 0:
        return np.zeros(0, dtype=np.float32)
    t_min, t_max, t_ref = F32(fe.t_min_c), F32(fe.t_max_c), F32(fe.t_ref_c)
    carry: np.float32 | None = None  # the last finite sample, clamped

    def sanitised(a: int, b: int) -> np.ndarray:
        nonlocal carry
        with np.errstate(over="ignore", invalid="ignore"):
            raw = np.ascontiguousarray(temp_c[a:b], dtype=np.float32)
        finite = np.isfinite(raw)
        clamped = np.where(raw < t_min, t_min, np.where(raw > t_max, t_max, raw))
        idx = np.arange(raw.shape[0])
        last = np.maximum.accumulate(np.where(finite, idx, -1))
        before = t_ref if carry is None else carry
        tc = np.where(last >= 0, clamped[np.maximum(last, 0)], before).astype(np.float32)
        good = np.flatnonzero(finite)
        if good.size:
            carry = clamped[good[-1]]
        return tc

    n_steps = (n - 1) // d + 1
    tm = np.empty(n_steps, dtype=np.float32)
    tm[0] = sanitised(0, 1)[0]
    per = _block_steps(d)
    for k in range(1, n_steps, per):  # steps k .. k + per - 1: samples 1 + (k - 1) d ...
        k1 = min(n_steps, k + per)
        a, b = 1 + (k - 1) * d, 1 + (k1 - 1) * d
        blocks = sanitised(a, b).reshape(k1 - k, d)
        acc = np.cumsum(blocks, axis=1, dtype=np.float32)[:, -1]  # sequential, like C
        tm[k:k1] = acc / F32(d)
    return tm


def frontend_s(temp_c: columns.Column, fe: FrontEnd) -> np.ndarray:
    """`reference.frontend(temp_c, fe).s`: [Tm - t_ref, y_1 - t_ref, ..., p_1 - t_ref, ...]
    per step."""
    return state_of(step_temperatures(temp_c, fe), fe)


def step_targets(log: ChamberLog, decimation: int, latitude_deg: float | None = None,
                 settle_s: float = SETTLE_S) -> np.ndarray:
    """Mean SF error (ppm vs nominal) over the measuring samples (settled plateaus) each
    model step's output is held for, the +/- pairs' bias taken off; NaN for a step without
    one (features.step_targets' figures, a block of steps at a time)."""
    n = len(log)
    plateaus = np.asarray(settled_plateaus(log, settle_s), dtype=np.int64).reshape(-1, 2)
    parts = _signal_parts(log, latitude_deg, None, settle_s, True)
    n_steps = (n - 1) // decimation + 1 if n else 0
    out = np.empty(n_steps)
    per = _block_steps(decimation) * decimation
    for a in range(0, n, per):
        b = min(n, a + per)
        m = np.zeros(b - a, dtype=bool)
        for x, y in plateaus[(plateaus[:, 1] > a) & (plateaus[:, 0] < b)]:
            m[max(x, a) - a:min(y, b) - a] = True
        table = np.where(m, np.asarray(log.table_rate_dps[a:b]), 1.0)
        ratio = np.where(m, _signal_at(log, parts, slice(a, b)) / table, 0.0)
        out[a // decimation:a // decimation + (b - a - 1) // decimation + 1] = (
            step_means(ratio, decimation, m) - 1.0) * 1e6
    return out
