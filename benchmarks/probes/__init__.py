"""One-off probes: each reproduces the evidence behind one default (docs/decisions.md)."""

from __future__ import annotations

import json
import time

import numpy as np


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
