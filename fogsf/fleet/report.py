"""`fogsf fleet report`: a static HTML report of the fleet that opens from disk.

DIR/index.html (a row per unit: chamber hours, residual, interval, verdict, outlier flag),
three plots beside it as PNG files (SF error against temperature before and after, the
units' features with the outliers marked, residual against chamber hours) and a page per
unit (units/unit-NNN.html with its own plot). No server, no script, nothing fetched: the
pages are HTML and images only. Every string that comes from users (serial numbers, paths,
the fleet's name, the summary) is escaped; file names are made from the unit's index,
never from its name. DIR is a folder the report owns (report_dir.py): one it did not write
is refused; the new report is written beside it and swapped in, so a killed report leaves
the previous one whole.
"""

from __future__ import annotations

import json
import math
from html import escape
from pathlib import Path

from fogsf.fleet.check import RESIDUAL, CheckResult, unit_features
from fogsf.fleet.records import UnitRecord
from fogsf.fleet.report_dir import write_owned

CSS = """body{font-family:sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;
text-align:right}td.l,th.l{text-align:left}tr.flag{background:#fde2e2}
img{max-width:100%;border:1px solid #ddd;margin:4px 0}code{font-size:90%}
.note{color:#555}pre{background:#f6f6f6;padding:8px;overflow-x:auto}"""


def _e(x: object) -> str:
    return escape(str(x), quote=True)


def _num(x: object, spec: str = ".2f") -> str:
    return format(x, spec) if isinstance(x, (int, float)) and math.isfinite(x) else "-"


def _mpl_text(s: str) -> str:
    """A user string as plain text in a matplotlib label ($ would start mathtext)."""
    return s.replace("$", r"\$")


def residual_x(u: UnitRecord) -> tuple[float, str]:
    """The unit's residual over its noise floor: on its test log when it has one, else on
    its training logs; and which."""
    f = u.figures
    for part in ("test", "train"):
        v = f.get(f"{part}_rms_over_floor")
        if isinstance(v, (int, float)) and math.isfinite(v):
            return float(v), part
    return math.nan, "-"


def interval_x(u: UnitRecord) -> str:
    iv = u.interval
    floor = (iv or {}).get("noise_floor_ppm")
    if not iv or not floor:
        return "-"
    return f"{iv['rms_lo_ppm'] / floor:.2f}-{iv['rms_hi_ppm'] / floor:.2f}"


def verdict(u: UnitRecord, flagged: bool) -> str:
    if flagged:
        return "unlike the line"
    iv = u.interval
    if not iv:
        return "no test log"
    rms, lo, hi = iv["test_rms_ppm"], iv["rms_lo_ppm"], iv["rms_hi_ppm"]
    if hi > 0 and rms > hi:
        return "worse than its interval"
    if rms < lo:
        return "better than its interval"
    return "within its interval"


def _plots(units: list[UnitRecord], result: CheckResult, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    flagged = result.flagged
    # SF error against temperature, before and after
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4.2))
    for u in units:
        c = u.figures.get("sf_curve") or {}
        if not c.get("temp_c"):
            continue
        bad = u.unit in flagged
        kw = {"color": "tab:red" if bad else "tab:blue", "alpha": 0.9 if bad else 0.5,
              "lw": 1.6 if bad else 1.0}
        a0.plot(c["temp_c"], c["before_ppm"], **kw)
        a1.plot(c["temp_c"], c["after_ppm"], **kw)
    a0.set(title="before compensation", xlabel="board temperature, C", ylabel="SF error, ppm")
    a1.set(title="after (the unit's own model)", xlabel="board temperature, C",
           ylabel="SF error, ppm")
    for a in (a0, a1):
        a.grid(alpha=0.3)
    fig.suptitle("SF error against temperature, each unit (red: unlike the line)")
    fig.tight_layout()
    fig.savefig(out / "sf_vs_temperature.png", dpi=90)
    plt.close(fig)

    # the units' features (z against the line), outliers marked
    names = result.parameters
    fig, ax = plt.subplots(figsize=(11, 4.2))
    if names and result.z:
        for j, u in enumerate(units):
            zz = result.z.get(u.unit)
            if not zz:
                continue
            bad = u.unit in flagged
            xs = [i + (j - len(units) / 2) * 0.02 for i in range(len(names))]
            ax.scatter(xs, [zz.get(k, math.nan) for k in names], s=30 if bad else 12,
                       color="tab:red" if bad else "tab:blue", zorder=3 if bad else 2,
                       label=_mpl_text(u.unit) if bad else None)
        thr = result.threshold_z
        for i, k in enumerate(names):  # each feature's threshold (the residual's one-sided)
            t = result.threshold_residual_z if k == RESIDUAL else thr
            if math.isfinite(t):
                for s in ((t,) if k == RESIDUAL else (-t, t)):
                    ax.plot([i - 0.4, i + 0.4], [s, s], color="tab:red", ls="--", lw=0.9)
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([k.split(".", 1)[-1] for k in names], rotation=30, ha="right",
                           fontsize=8)
        if flagged:
            ax.legend(fontsize=8, loc="upper right")
    else:
        ax.text(0.5, 0.5, result.note or "nothing compared", ha="center", va="center",
                transform=ax.transAxes)
    ax.set(ylabel="z against the other units", title="the units' features (red: unlike the "
           "line; dashed: the threshold)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "parameters.png", dpi=90)
    plt.close(fig)

    # residual against chamber hours
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for u in units:
        r, _ = residual_x(u)
        bad = u.unit in flagged
        ax.scatter([u.chamber_hours], [r], color="tab:red" if bad else "tab:blue",
                   s=30 if bad else 16)
    ax.axhline(1.0, color="gray", lw=0.8, ls=":")
    ax.set(xlabel="chamber hours (training logs)", ylabel="RMS SF error left / noise floor",
           title="residual against chamber hours (test log, else training)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "residual_vs_hours.png", dpi=90)
    plt.close(fig)


def _unit_plot(u: UnitRecord, path: Path) -> bool:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = u.figures.get("sf_curve") or {}
    if not c.get("temp_c"):
        return False
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(c["temp_c"], c["before_ppm"], "o-", ms=3, label="before")
    ax.plot(c["temp_c"], c["after_ppm"], "o-", ms=3, label="after")
    ax.set(xlabel="board temperature, C", ylabel="SF error, ppm",
           title=f"SF error against temperature ({u.figures.get('sf_curve_log', '')} log)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def _page(title: str, body: str) -> str:
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{_e(title)}</title><style>{CSS}</style></head>\n<body>\n{body}\n"
            "</body></html>\n")


def _index(units: list[UnitRecord], result: CheckResult, title: str, pages: list[str]) -> str:
    why = {o.unit: o.why for o in result.outliers}
    rows = []
    for u, page in zip(units, pages, strict=True):
        r, part = residual_x(u)
        bad = u.unit in why
        rows.append(
            f"<tr class=\"{'flag' if bad else ''}\"><td class=\"l\"><a href=\"{page}\">"
            f"{_e(u.unit)}</a></td><td>{u.chamber_hours:.1f}</td><td>{_num(r)} ({part})</td>"
            f"<td>{_e(interval_x(u))}</td><td class=\"l\">{_e(verdict(u, bad))}</td>"
            f"<td class=\"l\">{'yes: ' + _e(why[u.unit]) if bad else 'no'}</td></tr>")
    check = _e(result.message()).replace("\n", "<br>\n")
    return _page(f"fleet {title}", f"""<h1>Fleet <code>{_e(title)}</code></h1>
<p>{len(units)} units. Residual: RMS SF error left by the unit's own model over the noise
floor (x), on its test log (else its training logs); interval: where fogsf train --test
said that RMS would fall (x the floor).</p>
<h2>Units unlike the line</h2><p class="note">{check}</p>
<table><tr><th class="l">unit</th><th>chamber h</th><th>residual x</th><th>interval x</th>
<th class="l">verdict</th><th class="l">unlike the line</th></tr>
{chr(10).join(rows)}
</table>
<h2>Plots</h2>
<img src="sf_vs_temperature.png" alt="SF error against temperature, before and after">
<img src="parameters.png" alt="the units' features with the outliers marked">
<img src="residual_vs_hours.png" alt="residual against chamber hours">
""")


def _unit_page(u: UnitRecord, result: CheckResult, img: str | None) -> str:
    why = {o.unit: o.why for o in result.outliers}
    r, part = residual_x(u)
    logs = "\n".join(
        f"<tr><td class=\"l\">{_e(lg.role)}</td><td class=\"l\"><code>{_e(lg.path)}</code>"
        f"</td><td class=\"l\"><code>{_e(lg.sha256[:16])}</code></td><td>{lg.rows}</td>"
        f"<td>{lg.span_s / 3600:.2f}</td><td>{_num(lg.sample_rate_hz, 'g')}</td>"
        f"<td>{_e(', '.join(f'{x:g}' for x in lg.ramp_rates_c_per_min))}</td>"
        f"<td>{_num(lg.temp_min_c, '.1f')} .. {_num(lg.temp_max_c, '.1f')}</td></tr>"
        for lg in u.logs)
    feats, _ = unit_features(u)
    zz = result.z.get(u.unit, {})
    frows = "\n".join(f"<tr><td class=\"l\">{_e(k)}</td><td>{_num(v, '.4g')}</td>"
                      f"<td>{_num(zz.get(k), '+.2f')}</td></tr>" for k, v in feats.items())
    figs = {k: v for k, v in u.figures.items() if k not in ("sf_curve", "response_ppm")}
    flagged = u.unit in why
    return _page(f"unit {u.unit}", f"""<p><a href="../index.html">&larr; the fleet</a></p>
<h1>Unit <code>{_e(u.unit)}</code></h1>
<p>verdict: <b>{_e(verdict(u, flagged))}</b>{'; ' + _e(why[u.unit]) if flagged else ''}</p>
<p>chamber hours {u.chamber_hours:.2f}; residual {_num(r)} x the floor ({part});
interval {_e(interval_x(u))} x; model <code>{_e(u.model_id)}</code>
{'in <code>' + _e(u.model_dir) + '</code>' if u.model_dir else '(folder not kept)'};
fogsf {_e(u.fogsf_version)}, recorded {_e(u.created_utc)} UTC</p>
{f'<img src="{img}" alt="SF error against temperature">' if img else ''}
<h2>Logs</h2><table><tr><th class="l">role</th><th class="l">path</th>
<th class="l">sha256</th><th>rows</th><th>hours</th><th>Hz</th><th>ramps C/min</th>
<th>board C</th></tr>
{logs}</table>
<h2>Features against the line</h2><table><tr><th class="l">feature</th><th>value</th>
<th>z</th></tr>
{frows}</table>
<h2>Figures, structure, parameters</h2>
<p class="note">(the summary's per-step series, which the design's prior refits from, left
out)</p>
<pre>{_e(json.dumps({"figures": figs, "fitted_with": u.fitted_with,
                   "summary": {k: v for k, v in u.summary.items() if k != "series"}},
                  indent=2, sort_keys=True, default=str))}</pre>
""")


def write_report(units: list[UnitRecord], result: CheckResult, out: Path, title: str) -> Path:
    """Write the report into `out`, a folder it owns (report_dir: a folder it did not write
    is refused, the previous report replaced whole); returns index.html."""
    out = Path(out)

    def write(tmp: Path) -> None:
        (tmp / "units").mkdir()
        _plots(units, result, tmp)
        pages = []
        for i, u in enumerate(units):
            name = f"unit-{i:03d}"
            img = f"{name}.png" if _unit_plot(u, tmp / "units" / f"{name}.png") else None
            (tmp / "units" / f"{name}.html").write_text(_unit_page(u, result, img),
                                                         encoding="utf-8")
            pages.append(f"units/{name}.html")
        (tmp / "index.html").write_text(_index(units, result, title, pages), encoding="utf-8")

    write_owned(out, write)
    return out / "index.html"
