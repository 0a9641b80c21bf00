"""One-off probes: each reproduces the evidence behind one default (docs/decisions.md)."""

from __future__ import annotations

import json
import time


def finish(rows: list[dict], out: str | None, t0: float) -> int:
    """The probes' end: the rows as JSON to `out` (if given), the wall time printed."""
    if out:
        with open(out, "w") as fh:
            json.dump(rows, fh, indent=1)
    print(f"{time.perf_counter() - t0:.0f} s")
    return 0
