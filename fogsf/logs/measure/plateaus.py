"""Plateaus of a chamber log: runs of one commanded table rate over the rows that measure,
without the settle margin after each change (`--settle-s`) and at least MIN_PLATEAU_S long;
the constants every SF and bias measure shares (logs/measure/metrics.py, logs/measure/pairs.py)."""

from __future__ import annotations

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.read.columns import Column, is_lazy, searchsorted

T_REF_C = 20.0
SETTLE_S = 2.0  # left out after each change of commanded rate (covers a ~1 s table slew)
MIN_PLATEAU_S = 5.0  # a settled plateau shorter than this measures nothing
DPS_TO_DPH = 3600.0
# per-sample work is done this many samples at a time (2 MB a float64 column): memory beyond
# the log's own columns does not grow with its length; every result is the same bits
BLOCK_SAMPLES = 1 << 18


def plateaus(table_rate_dps: Column, measures: Column | None = None
             ) -> list[tuple[int, int]]:
    """[start, stop) index ranges over which the table rate does not change; with `measures`
    (`ChamberLog.measures`), only the measuring runs inside them."""
    r = table_rate_dps if is_lazy(table_rate_dps) else np.asarray(table_rate_dps)
    if len(r) == 0:
        return []
    found = [np.zeros(1, dtype=np.int64)]
    for a in range(0, len(r) - 1, BLOCK_SAMPLES):  # no log-long temporaries
        x = r[a:a + BLOCK_SAMPLES + 1]
        change = np.abs(np.diff(x)) > 1e-9 * np.maximum(np.abs(x[1:]), 1.0)
        if measures is not None:
            m = np.asarray(measures[a:a + BLOCK_SAMPLES + 1])
            change |= m[1:] != m[:-1]
        found.append(a + np.flatnonzero(change) + 1)
    edges = np.concatenate([*found, [len(r)]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)
            if measures is None or measures[a]]


def _samples(seconds: float, dt: float) -> int:
    return int(np.ceil(seconds / dt - 1e-6)) if seconds > 0 else 0


def _plateau_starts(log: ChamberLog, settle_s: float, skip_s: float
                    ) -> list[tuple[int, int, int]]:
    """(commanded start, first counted sample, stop) of every measuring plateau: the first
    counted sample is `settle_s` after the start (but on the log's first plateau, which
    follows no change) and not before the log's first `skip_s` seconds."""
    if settle_s < 0 or skip_s < 0:
        raise UserError("--settle-s and --skip-s must be >= 0")
    settle = _samples(settle_s, log.sample_dt_s)
    first = 0
    if skip_s > 0 and len(log):
        first = searchsorted(log.time_s, log.time_s[0] + skip_s - 1e-9)
    return [(a, max(a + settle if a > 0 or _spins_up(log, b, settle) else a, first), b)
            for a, b in plateaus(log.table_rate_dps, log.measures)]


SPIN_UP_TOL = 1e-3  # the log's first seconds read the table this far (0.1 %) off: a spin-up


def _spins_up(log: ChamberLog, stop: int, settle: int) -> bool:
    """Whether the log's first plateau [0, stop) begins with the table still spinning up (a
    log that starts with its table command): the gyro's mean over the first `settle`
    samples differs from the next ten margins' by more than SPIN_UP_TOL of the rate. A table
    already turning when the log starts reads the same there (noise and thermal SF change
    are ppm), so such a log keeps its first samples, as it always did."""
    if settle == 0 or stop < 2 * settle:
        return settle > 0
    head = float(log.gyro_dps[:settle].mean())
    rest = float(log.gyro_dps[settle:min(stop, 11 * settle)].mean())
    return abs(head - rest) > SPIN_UP_TOL * abs(float(log.table_rate_dps[0]))


def settled_plateaus(log: ChamberLog, settle_s: float = SETTLE_S, skip_s: float = 0.0
                     ) -> list[tuple[int, int]]:
    """The measuring plateaus without their first `settle_s` seconds (but the log's first
    plateau, which follows no change), without the log's first `skip_s` seconds, and at least
    MIN_PLATEAU_S long."""
    shortest = max(1, _samples(MIN_PLATEAU_S, log.sample_dt_s))
    return [(a, b) for _, a, b in _plateau_starts(log, settle_s, skip_s) if b - a >= shortest]


def measuring_mask(log: ChamberLog, settle_s: float = SETTLE_S, skip_s: float = 0.0
                   ) -> np.ndarray:
    """Per sample, True inside a settled plateau: the samples SF and targets come from."""
    m = np.zeros(len(log), dtype=bool)
    for a, b in settled_plateaus(log, settle_s, skip_s):
        m[a:b] = True
    return m
