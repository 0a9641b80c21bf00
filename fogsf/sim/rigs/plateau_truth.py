"""The truth of a rig run per plateau and per +/- pair, for benches (docs/simulate.md, "Rig
protocols"): `plateaus` gives the samples of each plateau of non-zero commanded rate that
measures, with the truth's means over them; `pairs` joins adjacent plateaus of equal |rate|
and opposite sign, the truth's means over both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fogsf.sim.rigs.protocols import RigRun


@dataclass(frozen=True)
class Plateau:
    """Samples [start, stop) at one commanded rate, after the settle margin, and the
    truth's means over them."""

    start: int
    stop: int
    rate_dps: float  # commanded
    sf_ppm: float
    bias_dph: float
    temp_c: float  # the log's thermometer


def plateaus(run: RigRun, axis: str = "", settle_s: float = 2.0, min_s: float = 5.0
             ) -> list[Plateau]:
    """The log's plateaus of non-zero commanded rate that measure (enabled, no stall) for
    at least min_s after settle_s; a stall ends a plateau."""
    ax, dt = run.axes[axis], run.protocol.dt_s
    key = np.where(run.measures, run.command_dps, 0.0)
    edges = np.concatenate([[0], np.flatnonzero(np.diff(key)) + 1, [key.shape[0]]])
    skip, need = int(round(settle_s / dt)), int(round(min_s / dt))
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        rate = float(key[a])
        # a stall's recovery rows are flagged: settle only after a commanded change
        start = a + (skip if a == 0 or run.command_dps[a - 1] != rate else 0)
        if rate == 0.0 or b - start < need:
            continue
        out.append(Plateau(int(start), int(b), rate, float(ax.result.sf_ppm[start:b].mean()),
                           float(ax.result.bias_dps[start:b].mean() * 3600.0),
                           float(ax.temp_c[start:b].mean())))
    return out


@dataclass(frozen=True)
class PairTruth:
    """A +/- pair of adjacent plateaus of equal |rate| and the truth's means over both."""

    plus: Plateau
    minus: Plateau
    rate_dps: float  # |rate|
    sf_ppm: float
    bias_dph: float
    temp_c: float


def pairs(plats: Sequence[Plateau]) -> list[PairTruth]:
    """Adjacent plateaus of equal |rate| and opposite sign, each used once, in order."""
    out, i = [], 0
    while i + 1 < len(plats):
        p, q = plats[i], plats[i + 1]
        if p.rate_dps == -q.rate_dps and q.start - p.stop <= p.stop - p.start:
            plus, minus = (p, q) if p.rate_dps > 0 else (q, p)
            n1, n2 = p.stop - p.start, q.stop - q.start
            w = (n1, n2)
            out.append(PairTruth(plus, minus, abs(p.rate_dps),
                                 float(np.average([p.sf_ppm, q.sf_ppm], weights=w)),
                                 float(np.average([p.bias_dph, q.bias_dph], weights=w)),
                                 float(np.average([p.temp_c, q.temp_c], weights=w))))
            i += 2
        else:
            i += 1
    return out
