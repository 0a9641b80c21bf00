"""The plots of `fogsf fleet report`: the fleet's as PNG (matplotlib), a unit's as inline SVG.

Every plot has a legend. A line's units are drawn as one collection a kind (in family,
unlike the line, out of spec), not one artist a unit: a plot of 500 units takes the time
of a plot of 5. A unit's own plot is a few polylines written as SVG text (no matplotlib
figure a unit: 500 units' pages in well under a second).
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fogsf.fleet.check import RESIDUAL, CheckResult
from fogsf.fleet.records import UnitRecord, spec_verdict

if TYPE_CHECKING:
    from matplotlib.axes import Axes

IN, OUT, SPEC = "tab:blue", "tab:red", "tab:orange"  # in family, unlike the line, out of spec


def serial_key(sn: str) -> list[object]:
    """Serial numbers in their natural order (SN9 before SN10)."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", sn)]


def recorded_at(u: UnitRecord) -> datetime | None:
    try:
        return datetime.strptime(u.created_utc, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=UTC)
    except (TypeError, ValueError):
        return None


def residual_x(u: UnitRecord) -> tuple[float, str]:
    """The unit's residual over its noise floor: on its test log when it has one, else on
    its training logs; and which."""
    f = u.figures
    for part in ("test", "train"):
        v = f.get(f"{part}_rms_over_floor")
        if isinstance(v, (int, float)) and math.isfinite(v):
            return float(v), part
    return math.nan, "-"


def _kind(u: UnitRecord, flagged: set[str], spec_ppm: float | None) -> str:
    if u.unit in flagged:
        return "unlike the line"
    if spec_ppm is not None and spec_verdict(u, spec_ppm) == "out of spec":
        return "out of spec"
    return "in family"


COLOURS = {"in family": IN, "unlike the line": OUT, "out of spec": SPEC}


def fleet_plots(units: list[UnitRecord], result: CheckResult, out: Path,
                spec_ppm: float | None) -> list[tuple[str, str]]:
    """Write the fleet's plots into `out`; (file name, what it shows) of each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.dates import date2num
    from matplotlib.figure import Figure

    flagged = result.flagged
    kinds = {u.unit: _kind(u, flagged, spec_ppm) for u in units}
    written: list[tuple[str, str]] = []

    def save(fig: Figure, name: str, what: str) -> None:
        fig.tight_layout()
        fig.savefig(out / name, dpi=80)
        plt.close(fig)
        written.append((name, what))

    # SF error against temperature, before and after: one collection a kind
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for part, ax in zip(("before_ppm", "after_ppm"), axes, strict=True):
        for kind, colour in COLOURS.items():
            segs = [np.column_stack([c["temp_c"], c[part]]) for u in units
                    if kinds[u.unit] == kind and (c := u.figures.get("sf_curve") or {})
                    and c.get("temp_c")]
            if segs:
                ax.add_collection(LineCollection(segs, colors=colour, linewidths=0.9,
                                                 alpha=0.9 if kind != "in family" else 0.4,
                                                 label=f"{kind} ({len(segs)})"))
        ax.autoscale()
        ax.set(xlabel="board temperature, C", ylabel="SF error, ppm",
               title="before compensation" if part == "before_ppm" else
               "after (the unit's own model)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    save(fig, "sf_vs_temperature.png", "SF error against temperature, before and after")

    # the units' features as z against the line, the threshold dashed
    names = result.parameters
    fig, ax = plt.subplots(figsize=(11, 4.2))
    if names and result.z:
        for kind, colour in COLOURS.items():
            pts = [(i + 0.3 * (j / max(1, len(units)) - 0.5), z.get(k, math.nan))
                   for j, u in enumerate(units) if kinds[u.unit] == kind
                   and (z := result.z.get(u.unit)) for i, k in enumerate(names)]
            if pts:
                xy = np.array(pts)
                ax.scatter(xy[:, 0], xy[:, 1], s=8 if kind == "in family" else 22,
                           color=colour, label=kind, zorder=2 if kind == "in family" else 3)
        for i, k in enumerate(names):  # each feature's threshold (the residual's one-sided)
            t = result.threshold_residual_z if k == RESIDUAL else result.threshold_z
            if math.isfinite(t):
                for s in ((t,) if k == RESIDUAL else (-t, t)):
                    ax.plot([i - 0.4, i + 0.4], [s, s], color="k", ls="--", lw=0.9,
                            label="threshold" if (i, s) == (0, t) else None)
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([k.split(".", 1)[-1] for k in names], rotation=30, ha="right",
                           fontsize=8)
    else:
        ax.text(0.5, 0.5, result.note or "nothing compared", ha="center", va="center",
                transform=ax.transAxes)
        ax.plot([], [], " ", label="no features compared")
    ax.set(ylabel="z against the other units", title="the units' features against the line")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    save(fig, "parameters.png", "the units' features as z against the line, the threshold")

    # residual against chamber hours
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for kind, colour in COLOURS.items():
        xy = np.array([(u.chamber_hours, residual_x(u)[0]) for u in units
                       if kinds[u.unit] == kind]).reshape(-1, 2)
        if xy.size:
            ax.scatter(xy[:, 0], xy[:, 1], s=12, color=colour, label=kind)
    ax.axhline(1.0, color="gray", lw=0.8, ls=":", label="the noise floor")
    ax.set(xlabel="chamber hours (training logs)", ylabel="RMS SF error left / noise floor",
           title="residual against chamber hours (test log, else training)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, "residual_vs_hours.png", "residual against chamber hours")

    # trends: the test RMS and its interval over serial number and over date
    order = sorted(units, key=lambda u: serial_key(u.unit))
    dated = sorted(((d, u) for u in units if (d := recorded_at(u)) is not None),
                   key=lambda p: (p[0], serial_key(p[1].unit)))
    for name, what, xs_units in (
            ("trend_serial.png", "serial number (natural order)",
             [(float(i), u) for i, u in enumerate(order)]),
            ("trend_date.png", "date recorded (UTC)",
             [(float(date2num(d)), u) for d, u in dated])):
        fig, ax = plt.subplots(figsize=(11, 3.8))
        _trend(ax, xs_units, kinds, spec_ppm, LineCollection)
        if name == "trend_date.png":
            ax.xaxis_date()
            fig.autofmt_xdate()
        else:
            ax.set_xticks(*_serial_ticks(order))
        ax.set(xlabel=what, ylabel="test RMS after, ppm",
               title=f"test RMS and its interval over {what.split(' (')[0]}")
        save(fig, name, f"test RMS and interval over {what}")
    return written


def _serial_ticks(order: list[UnitRecord]) -> tuple[list[int], list[str]]:
    step = max(1, len(order) // 10)
    idx = list(range(0, len(order), step))
    return idx, [order[i].unit[:14] for i in idx]


def _trend(ax: Axes, xs_units: list[tuple[float, UnitRecord]], kinds: dict[str, str],
           spec_ppm: float | None, collection: type) -> None:
    """Test RMS (dots) and the interval stated for it (bars) against x, a kind a colour."""
    for kind, colour in COLOURS.items():
        pts, bars = [], []
        for x, u in xs_units:
            if kinds[u.unit] != kind:
                continue
            iv = u.interval or {}
            rms = iv.get("test_rms_ppm", u.figures.get("test_after_rms_ppm"))
            if isinstance(rms, (int, float)) and math.isfinite(rms):
                pts.append((x, rms))
            lo, hi = iv.get("rms_lo_ppm"), iv.get("rms_hi_ppm")
            if isinstance(lo, (int, float)) and isinstance(hi, (int, float)) and hi > 0:
                bars.append([(x, lo), (x, hi)])
        if bars:
            ax.add_collection(collection(bars, colors=colour, linewidths=1.0,
                                         alpha=0.35))
        if pts:
            xy = np.array(pts)
            ax.scatter(xy[:, 0], xy[:, 1], s=10, color=colour,
                       label=f"{kind}: test RMS (bar: its interval)")
    if spec_ppm is not None:
        ax.axhline(spec_ppm, color="k", ls="--", lw=1.0,
                   label=f"spec {spec_ppm:g} ppm")
    if not ax.get_legend_handles_labels()[0]:  # no unit with a test RMS in ppm
        ax.plot([], [], " ", label="no unit with this")
    ax.autoscale()
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")


def unit_svg(u: UnitRecord) -> str:
    """The unit's SF error against temperature, before and after, as inline SVG; "" when
    the record has no curve."""
    c = u.figures.get("sf_curve") or {}
    t = [float(x) for x in c.get("temp_c", [])]
    if not t:
        return ""
    series = [("before", "#1f77b4", c["before_ppm"]), ("after", "#ff7f0e", c["after_ppm"])]
    ys = [float(v) for _, _, s in series for v in s if math.isfinite(float(v))]
    x0, x1 = min(t), max(max(t), min(t) + 1.0)
    y0, y1 = (min(ys), max(ys)) if ys else (0.0, 1.0)
    y0, y1 = (y0, y1) if y1 > y0 else (y0 - 1.0, y1 + 1.0)
    w, h, left, bottom = 640, 300, 60, 40

    def px(x: float, y: float) -> str:
        return (f"{left + (x - x0) / (x1 - x0) * (w - left - 20):.1f},"
                f"{h - bottom - (y - y0) / (y1 - y0) * (h - bottom - 20):.1f}")

    lines = [f'<polyline fill="none" stroke="{col}" stroke-width="1.5" points="'
             + " ".join(px(x, float(v)) for x, v in zip(t, s, strict=True)
                        if math.isfinite(float(v))) + '"/>' for _, col, s in series]
    legend = "".join(f'<line x1="{w - 150}" x2="{w - 130}" y1="{20 + 16 * i}" '
                     f'y2="{20 + 16 * i}" stroke="{col}" stroke-width="2"/><text '
                     f'x="{w - 125}" y="{24 + 16 * i}">{name}</text>'
                     for i, (name, col, _) in enumerate(series))
    axes = (f'<line x1="{left}" y1="{h - bottom}" x2="{w - 20}" y2="{h - bottom}" '
            f'stroke="#444"/><line x1="{left}" y1="20" x2="{left}" y2="{h - bottom}" '
            f'stroke="#444"/><text x="{left}" y="{h - 22}">{x0:.0f} C</text>'
            f'<text x="{w - 60}" y="{h - 22}">{x1:.0f} C</text>'
            f'<text x="4" y="24">{y1:.0f}</text><text x="4" y="{h - bottom}">{y0:.0f}</text>'
            f'<text x="{w / 2 - 80:.0f}" y="{h - 6}">board temperature, C</text>'
            f'<text x="4" y="{h / 2:.0f}">ppm</text>')
    title = escape(f"SF error against temperature ({u.figures.get('sf_curve_log', '')} log)")
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
            f'font-size="11" role="img" aria-label="{title}"><title>{title}</title>'
            f'{axes}{"".join(lines)}{legend}</svg>')
