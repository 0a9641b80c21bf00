"""Chamber programs that `fogsf plan` compares: templates, limits, the paper's protocol.

A program is one or more chamber runs, each a piecewise-linear (time_s, temp_c) path that
`fogsf simulate --program` reads and a chamber controller can load. Candidates are built
from templates over a grid of ramp rates and soak lengths, inside the user's limits:
- `up`: one up-ramp at one rate (the paper's kind of run);
- `loop`: up at r1, soak, down at r2, soak (a hysteresis loop at two rates);
- `loop3`: up r1, soak, down r2, soak, up r3, soak (three ramps);
- `steps`: a staircase up and back down in equal steps at the fastest ramp, a soak at
  every level (step responses and the static curve at once);
each starting with a short soak at the low end (the warm start) and ending with a soak,
since the transients at the ramp ends are where lag structures differ most.
"""

from __future__ import annotations

import csv
import itertools
from dataclasses import dataclass, field
from pathlib import Path

from fogsf.errors import UserError

START_SOAK_S = 900.0
SOAKS_S = (1800.0, 3600.0)
STEP_LEVELS = (2, 3, 4)  # steps from one end to the other
STEP_SOAKS_S = (1200.0, 1800.0, 2700.0, 3600.0)
RATE_GRID = (0.5, 1.0, 1.5, 2.0, 3.0)  # C/min, cut at --max-ramp
SLOPE_TOL = 1e-6  # C/min: ramp rates are checked against the limit with this slack


@dataclass(frozen=True)
class Limits:
    """What the chamber and the budget allow."""

    lo_c: float
    hi_c: float
    max_ramp_c_per_min: float
    hours: float

    def __post_init__(self) -> None:
        if not self.hi_c - self.lo_c >= 10.0:
            raise UserError(f"--range: need at least 10 C between the ends, got "
                            f"{self.lo_c:g}:{self.hi_c:g}")
        if not self.lo_c < 20.0 < self.hi_c:
            raise UserError("--range must contain 20 C (the SF reference temperature)")
        if not 0.05 <= self.max_ramp_c_per_min <= 20.0:
            raise UserError(f"--max-ramp must be 0.05-20 C/min, got {self.max_ramp_c_per_min:g}")
        if not 0.5 <= self.hours <= 72.0:
            raise UserError(f"--hours must be 0.5-72, got {self.hours:g}")


@dataclass(frozen=True)
class Program:
    """A chamber program: one or more runs of (time_s, temp_c) points."""

    name: str
    runs: tuple[tuple[tuple[float, float], ...], ...]
    rates_c_per_min: tuple[float, ...] = field(default=())

    @property
    def hours(self) -> float:
        return sum(r[-1][0] for r in self.runs) / 3600.0


def _path(lo: float, hi: float, legs: list[tuple[str, float]]) -> tuple[tuple[float, float], ...]:
    """Points of a program from the low end: legs ("ramp", rate C/min) or ("soak", s)."""
    t, temp = 0.0, lo
    pts = [(0.0, lo)]
    for kind, v in legs:
        if kind == "soak":
            t += v
        else:
            target = hi if temp == lo else lo
            t += abs(hi - lo) / v * 60.0
            temp = target
        pts.append((t, temp))
    return tuple(pts)


def paper_protocol(limits: Limits) -> Program:
    """The paper's protocol over the user's range: a 0.5 C/min and a 1 C/min up-ramp, two
    runs (4.5 h over -40..50 C)."""
    runs = tuple(_path(limits.lo_c, limits.hi_c, [("ramp", r)]) for r in (0.5, 1.0))
    p = Program("paper: up 0.5 + up 1 (two runs)", runs, (0.5, 1.0))
    bad = violations(p, limits)
    if bad:  # a reference, shown anyway: say that it breaks the limits
        p = Program(f"paper: up 0.5 + up 1 (two runs; outside your limits: {bad[0]})", runs,
                    (0.5, 1.0))
    return p


def candidates(limits: Limits) -> list[Program]:
    """Every template over the rate grid and soaks that fits the limits, shortest first
    among equals (names say what each is)."""
    rates = [r for r in RATE_GRID if r <= limits.max_ramp_c_per_min + SLOPE_TOL]
    if not rates:
        rates = [limits.max_ramp_c_per_min]
    lo, hi = limits.lo_c, limits.hi_c
    out: list[Program] = []
    s0 = ("soak", START_SOAK_S)
    for r in rates:
        for s in SOAKS_S:
            out.append(Program(f"up {r:g}, soak {s / 60:.0f} min",
                               (_path(lo, hi, [s0, ("ramp", r), ("soak", s)]),), (r,)))
    for r1, r2 in itertools.product(rates, repeat=2):
        if r1 == r2:
            continue
        for s in SOAKS_S:
            legs = [s0, ("ramp", r1), ("soak", s), ("ramp", r2), ("soak", s)]
            out.append(Program(f"loop up {r1:g} / down {r2:g}, soaks {s / 60:.0f} min",
                               (_path(lo, hi, legs),), (r1, r2)))
    for r1, r2, r3 in itertools.product(rates, repeat=3):
        if len({r1, r2, r3}) < 3 or r1 > r3:
            continue
        s = SOAKS_S[0]
        legs = [s0, ("ramp", r1), ("soak", s), ("ramp", r2), ("soak", s), ("ramp", r3),
                ("soak", s)]
        out.append(Program(f"loop3 up {r1:g} / down {r2:g} / up {r3:g}, soaks {s / 60:.0f} min",
                           (_path(lo, hi, legs),), (r1, r2, r3)))
    fast = max(rates)
    for k in STEP_LEVELS:
        for s in STEP_SOAKS_S:
            out.append(Program(f"steps {k} up and down at {fast:g}, soaks {s / 60:.0f} min",
                               (_staircase(lo, hi, k, fast, s),), (fast,)))
    return [p for p in out if not violations(p, limits)]


def _staircase(lo: float, hi: float, k: int, rate: float, soak_s: float
               ) -> tuple[tuple[float, float], ...]:
    levels = [lo + (hi - lo) * i / k for i in range(k + 1)]
    path = levels + levels[-2::-1]
    pts, t = [(0.0, lo), (soak_s, lo)], soak_s
    for a, b in itertools.pairwise(path):
        t += abs(b - a) / rate * 60.0
        pts.append((t, b))
        t += soak_s
        pts.append((t, b))
    return tuple(pts)


def violations(p: Program, limits: Limits) -> list[str]:
    """What in `p` breaks the limits (empty: it respects them)."""
    bad = []
    if p.hours > limits.hours + 1e-9:
        bad.append(f"lasts {p.hours:.2f} h > {limits.hours:g} h")
    for run in p.runs:
        for (t0, a), (t1, b) in itertools.pairwise(run):
            if not (limits.lo_c - 1e-9 <= a <= limits.hi_c + 1e-9):
                bad.append(f"{a:g} C outside the range")
            if t1 <= t0:
                bad.append("time not increasing")
            elif abs(b - a) / (t1 - t0) * 60.0 > limits.max_ramp_c_per_min + SLOPE_TOL:
                bad.append(f"ramp {abs(b - a) / (t1 - t0) * 60.0:.3g} C/min > max")
        if not (limits.lo_c - 1e-9 <= run[-1][1] <= limits.hi_c + 1e-9):
            bad.append(f"{run[-1][1]:g} C outside the range")
    return bad


def write_program_csv(path: Path, run: tuple[tuple[float, float], ...]) -> None:
    """One run as `time_s,temp_c` rows (what `fogsf simulate --program` reads)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time_s", "temp_c"])
        for t, temp in run:
            w.writerow([f"{t:.1f}", f"{temp:.3f}"])
