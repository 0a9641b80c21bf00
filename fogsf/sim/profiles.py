"""Chamber programs and rate-table schedules, as time series at the sample rate.

A chamber program is a piecewise-linear (time, temperature) path: soak, ramp (up or down
at any rate, with soaks before and after), up-down cycles, steps with soaks, or any program
read from a CSV of (time_s, temp_c). A table schedule is constant, alternating +/- or a
sequence of rate levels; rates change between samples (a rate table settles in well under
one 0.1 s sample at these rates).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.sim.config import ProfileConfig, TableConfig


def _ramp_s(a: float, b: float, rate_c_per_min: float) -> float:
    if rate_c_per_min <= 0:
        raise UserError(f"profile: ramp rate must be > 0 C/min, got {rate_c_per_min:g}")
    return abs(b - a) / rate_c_per_min * 60.0


def breakpoints(p: ProfileConfig) -> np.ndarray:
    """The program as an (n, 2) array of (time_s, temp_c), time from 0, non-decreasing."""
    pts: list[tuple[float, float]] = []

    def go(temp: float, after_s: float) -> None:
        t = pts[-1][0] + after_s if pts else 0.0
        pts.append((t, temp))

    if p.kind == "soak":
        if p.duration_s <= 0:
            raise UserError("profile soak: duration_s must be > 0")
        go(p.start_c, 0.0)
        go(p.start_c, p.duration_s)
    elif p.kind == "ramp":
        go(p.start_c, 0.0)
        if p.soak_before_s > 0:
            go(p.start_c, p.soak_before_s)
        go(p.stop_c, _ramp_s(p.start_c, p.stop_c, p.rate_c_per_min))
        if p.soak_after_s > 0:
            go(p.stop_c, p.soak_after_s)
    elif p.kind == "cycle":
        if p.cycles < 1:
            raise UserError("profile cycle: cycles must be >= 1")
        go(p.start_c, 0.0)
        if p.soak_before_s > 0:
            go(p.start_c, p.soak_before_s)
        for _ in range(p.cycles):
            for a, b in ((p.start_c, p.stop_c), (p.stop_c, p.start_c)):
                go(b, _ramp_s(a, b, p.rate_c_per_min))
                if p.soak_s > 0:
                    go(b, p.soak_s)
    elif p.kind == "steps":
        if not p.levels_c:
            raise UserError("profile steps: give levels_c (e.g. --levels-c -40,-20,0,20,40)")
        go(p.levels_c[0], 0.0)
        go(p.levels_c[0], p.soak_s)
        for a, b in zip(p.levels_c[:-1], p.levels_c[1:], strict=True):
            go(b, _ramp_s(a, b, p.rate_c_per_min))
            go(b, p.soak_s)
    elif p.kind == "program":
        arr = np.asarray(p.points, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 2:
            raise UserError("profile program: points must be at least two (time_s, temp_c) rows")
        if not np.all(np.isfinite(arr)):
            raise UserError("profile program: points must be finite numbers")
        if np.any(np.diff(arr[:, 0]) <= 0):
            raise UserError("profile program: time_s must be strictly increasing")
        return np.column_stack([arr[:, 0] - arr[0, 0], arr[:, 1]])
    else:
        raise UserError(f"profile: unknown kind {p.kind!r}")
    return np.asarray(pts, dtype=np.float64)


def chamber_series(p: ProfileConfig, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, chamber_c) sampled every dt_s over the whole program."""
    bp = breakpoints(p)
    duration = float(p.total_s) if p.total_s > 0 else float(bp[-1, 0])
    n = int(np.floor(duration / dt_s + 1e-9)) + 1
    if n < 2:
        raise UserError(f"profile: the program lasts {duration:g} s, too short to sample")
    t = np.arange(n, dtype=np.float64) * dt_s
    temp = np.interp(t, bp[:, 0], bp[:, 1])
    lo, hi = float(temp.min()), float(temp.max())
    if lo < -60.0 or hi > 100.0:
        raise UserError(f"profile: chamber temperatures {lo:g}..{hi:g} C leave -60..100 C")
    return t, temp


def read_program(path: str | Path) -> list[list[float]]:
    """A chamber program CSV: two columns (time_s, temp_c), optional header row."""
    rows: list[list[float]] = []
    try:
        with open(path, encoding="utf-8", newline="") as f:
            for i, row in enumerate(csv.reader(f), start=1):
                cells = [c.strip() for c in row if c.strip()]
                if not cells or cells[0].startswith("#"):
                    continue
                try:
                    vals = [float(c) for c in cells]
                except ValueError:
                    if not rows and i == 1:
                        continue  # header
                    raise UserError(f"{path}: line {i}: not numbers: {row}") from None
                if len(vals) != 2:
                    raise UserError(f"{path}: line {i}: expected time_s,temp_c, got {row}")
                rows.append(vals)
    except OSError as e:
        raise UserError(f"{path}: cannot read: {e.strerror or e}") from None
    if len(rows) < 2:
        raise UserError(f"{path}: a chamber program needs at least two (time_s, temp_c) rows")
    return rows


def table_series(tb: TableConfig, t_s: np.ndarray) -> np.ndarray:
    """The table rate (deg/s) at each sample time."""
    if tb.kind == "constant":
        rates = [tb.rate_dps]
    elif tb.kind == "alternating":
        rates = [tb.rate_dps, -tb.rate_dps]
    elif tb.kind == "levels":
        rates = list(tb.rates_dps)
        if not rates:
            raise UserError("table levels: give rates_dps (e.g. --rates-dps 10,50,100)")
    else:
        raise UserError(f"table: unknown kind {tb.kind!r}")
    if any(r == 0 or not np.isfinite(r) for r in rates):
        raise UserError("table: every rate must be finite and non-zero (the SF is undefined "
                        "at rest)")
    if len(rates) == 1:
        return np.full(t_s.shape, float(rates[0]))
    if tb.dwell_s <= 0:
        raise UserError("table: dwell_s must be > 0")
    # Index by sample count, not by float division of time, so plateaus are exact.
    dt = float(t_s[1] - t_s[0]) if t_s.shape[0] > 1 else 1.0
    per = max(1, int(round(tb.dwell_s / dt)))
    idx = (np.arange(t_s.shape[0]) // per) % len(rates)
    return np.asarray(rates, dtype=np.float64)[idx]
