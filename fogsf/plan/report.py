"""Rank the programs, say what each makes identifiable, write the table, figure and CSV."""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsf.plan.evaluate import in_program
from fogsf.plan.programs import Program, write_program_csv

LONG_SOAK_S = 3 * 3600.0  # what diagnose needs to tell a slow node from a drift


@dataclass
class Scored:
    program: Program
    median: float  # test RMS / noise floor over (gyro, envelope rate)
    p90: float
    off_median: float | None  # the same over the rates not in the program only
    off_p90: float | None
    per_rate: dict[float, tuple[float, float]]  # rate -> (median, p90) over gyros
    n: int
    interval_x_floor: float | None = None  # median over the interval gyros


def identifiable(p: Program) -> list[str]:
    """What the program lets the tools tell apart (rules from the simulator's effects and
    diagnose's confounding cases, not measured per program)."""
    out = []
    holds = [(a, b) for run in p.runs for a, b in itertools.pairwise(run) if a[1] == b[1]]
    temps = [pt[1] for run in p.runs for pt in run]
    inner = [a for a, _ in holds if min(temps) < a[1] < max(temps)]
    if len(set(p.rates_c_per_min)) >= 2:
        out.append("lag structure (two or more ramp rates)")
    elif inner:
        out.append("lag structure (step responses at inner levels)")
    slopes = [np.sign(b[1] - a[1]) for run in p.runs for a, b in itertools.pairwise(run)]
    if 1 in slopes and -1 in slopes:
        out.append("temp_rate vs lag (up- and down-ramps)")
    soak = max((b[0] - a[0] for a, b in holds), default=0.0)
    if soak >= LONG_SOAK_S:
        out.append("extra_lag vs aging / bias drift (a soak of at least 3 h)")
    return out


def _stats(x: list[float]) -> tuple[float | None, float | None]:
    if not x:
        return None, None
    return _median_p90(x)


def _median_p90(x: list[float]) -> tuple[float, float]:
    return float(np.median(x)), float(np.percentile(x, 90))


def score(programs: list[Program], results: list[dict], axes: int = 1) -> list[Scored]:
    """Median and p90 over gyros and envelope rates, best first (by p90, then median). With
    `axes` > 1 each group of that many consecutive gyros is one IMU (one gyro an axis, all in
    the same chamber program) and counts once, by its worst axis at each rate."""
    out = []
    for p in programs:
        each = [r["ratios"][p.name] for r in results]
        rows = [{k: max(g[k] for g in each[i:i + axes]) for k in each[i]}
                for i in range(0, len(each) - axes + 1, axes)]
        rates = sorted({k for row in rows for k in row})
        per_rate = {k: _median_p90([row[k] for row in rows]) for k in rates}  # k in some row
        med, p90 = _stats([v for row in rows for v in row.values()])
        off = _stats([row[k] for row in rows for k in rates if not in_program(p, k)])
        out.append(Scored(p, med, p90,  # type: ignore[arg-type]  # None only without results
                          off[0], off[1], per_rate, len(rows) * len(rates)))
    return sorted(out, key=lambda s: (s.p90, s.median))


def table_md(scored: list[Scored], paper: Scored | None, top: int) -> str:
    head = ("| rank | program | hours | median | p90 | off-program median / p90 | "
            "interval (x floor) | identifiable |\n|---|---|---|---|---|---|---|---|\n")
    rows = []
    for i, s in enumerate(scored[:top]):
        rows.append(_row(str(i + 1), s))
    if paper is not None:
        rows.append(_row("ref", paper))
    return head + "\n".join(rows) + "\n"


def _row(rank: str, s: Scored) -> str:
    iv = "-" if s.interval_x_floor is None else f"{s.interval_x_floor:.2f}"
    ident = "; ".join(identifiable(s.program)) or "-"
    off = "-" if s.off_median is None else f"{s.off_median:.2f} / {s.off_p90:.2f}"
    return (f"| {rank} | {s.program.name} | {s.program.hours:.2f} | {s.median:.2f} | "
            f"{s.p90:.2f} | {off} | {iv} | {ident} |")


def as_json(s: Scored) -> dict:
    return {"name": s.program.name, "hours": s.program.hours,
            "rates_c_per_min": list(s.program.rates_c_per_min),
            "runs": [[list(pt) for pt in run] for run in s.program.runs],
            "median": s.median, "p90": s.p90, "off_program_median": s.off_median,
            "off_program_p90": s.off_p90, "n": s.n,
            "per_rate": {f"{k:.4g}": {"median": m, "p90": q} for k, (m, q) in s.per_rate.items()},
            "interval_x_floor": s.interval_x_floor, "identifiable": identifiable(s.program)}


def write_outputs(out: Path, scored: list[Scored], paper: Scored | None, meta: dict) -> None:
    """program.csv (the best), table.md, plan.json and plan.png in `out`."""
    out.mkdir(parents=True, exist_ok=True)
    best = scored[0]
    for k, run in enumerate(best.program.runs):
        write_program_csv(out / ("program.csv" if k == 0 else f"program_{k + 1}.csv"), run)
    (out / "table.md").write_text(table_md(scored, paper, len(scored)))
    (out / "plan.json").write_text(json.dumps(
        {**meta, "best": as_json(best), "paper": as_json(paper) if paper else None,
         "programs": [as_json(s) for s in scored]}, indent=1))
    _figure(out / "plan.png", best, paper)


def _figure(path: Path, best: Scored, paper: Scored | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    shown = [(best, "best: " + best.program.name, "C0")]
    if paper is not None:
        shown.append((paper, paper.program.name, "C1"))
    for s, label, colour in shown:
        t0 = 0.0
        for k, run in enumerate(s.program.runs):
            t = np.array([pt[0] for pt in run]) + t0
            a.plot(t / 3600.0, [pt[1] for pt in run], color=colour,
                   label=label if k == 0 else None)
            t0 = t[-1]
        rates = sorted(s.per_rate)
        b.plot(rates, [s.per_rate[r][0] for r in rates], "o-", color=colour,
               label=f"{label}: median")
        b.plot(rates, [s.per_rate[r][1] for r in rates], "s--", color=colour,
               label="p90")
    a.set_xlabel("chamber hours")
    a.set_ylabel("chamber temperature [C]")
    a.set_title("temperature program")
    a.legend(fontsize=7)
    b.axhline(1.0, color="k", lw=0.8)
    b.set_xscale("log")
    ticks = sorted(best.per_rate)
    b.set_xticks(ticks, [f"{r:.2g}" for r in ticks])
    b.minorticks_off()
    b.set_xlabel("test ramp rate [C/min] (test loops up and down)")
    b.set_ylabel("predicted RMS / noise floor")
    b.set_title("predicted residual of the default compensation")
    b.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
