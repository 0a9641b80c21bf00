"""`fogsf fleet report`: a static HTML report of the fleet that opens from disk.

DIR/index.html: the summary first (units in family, out of family: unlike the line, and
with `spec_ppm` within spec, out of spec, unsure; the units that need a look named), the
plots (`report_plots`: SF error against temperature, the features against the line, the
residual against chamber hours, the test RMS and its interval over serial number and over
date, the spec line when given; a legend on each), then a row per unit, the units out of
family and out of spec first, sortable by any column (one inline script of the report's
own, no user string in it; nothing fetched). units/unit-NNN.html: a page per unit with its
plot (inline SVG). Every string that comes from users (serial numbers, paths, the fleet's
name, the summary) is escaped; file names are made from the unit's index, never from its
name.

DIR is a folder the report owns: it is written only when it does not exist, is empty, or
holds a report fogsf wrote (the marker file MARKER lists every file of that report, and DIR
must hold nothing else: a user's file put inside would be lost otherwise). Anything else
(the database's folder, a models folder) is refused and left untouched. The new report is
written into a fresh sibling folder, swapped in by two renames, and the old report removed
file by file from its own list: never a tree deleted by name, and a killed report leaves
the previous one whole.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Callable
from html import escape
from pathlib import Path

from fogsf.errors import UserError
from fogsf.fleet.check import CheckResult, unit_features
from fogsf.fleet.records import UnitRecord, spec_verdict
from fogsf.fleet.report_plots import fleet_plots, residual_x, serial_key, unit_svg

__all__ = ["MARKER", "check_out_dir", "residual_x", "write_report"]

CSS = """body{font-family:sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;
text-align:right}td.l,th.l{text-align:left}tr.flag{background:#fde2e2}
tr.spec{background:#fdf0dc}table.sortable th{cursor:pointer;background:#f0f0f0}
th[aria-sort=ascending]::after{content:" \\25B2"}th[aria-sort=descending]::after{content:" \\25BC"}
img{max-width:100%;border:1px solid #ddd;margin:4px 0}code{font-size:90%}
.note{color:#555}pre{background:#f6f6f6;padding:8px;overflow-x:auto}"""

# The index's one script: sorts a table.sortable by the clicked column (a cell's data-v
# when it has one, as a number in a th.num column, else its text), and stamps the page's
# load time (ms) on <html data-loaded-ms> (the report's tests read it). Fixed text: no user
# string ever enters it.
SORT_JS = """(function () {
  document.querySelectorAll("table.sortable").forEach(function (t) {
    var heads = t.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, col) {
      th.addEventListener("click", function () {
        var asc = th.getAttribute("aria-sort") !== "ascending";
        var num = th.classList.contains("num");
        Array.prototype.forEach.call(heads, function (h) { h.removeAttribute("aria-sort"); });
        th.setAttribute("aria-sort", asc ? "ascending" : "descending");
        var key = function (r) {
          var c = r.cells[col], v = c.hasAttribute("data-v") ? c.getAttribute("data-v")
                                                              : c.textContent;
          if (!num) { return v; }
          v = parseFloat(v);
          return isNaN(v) ? Infinity : v;
        };
        var rows = Array.prototype.map.call(t.tBodies[0].rows, function (r, i) {
          return [key(r), i, r];
        });
        rows.sort(function (a, b) {  // stable: equal keys keep their order
          var c = a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : 0;
          return c === 0 ? a[1] - b[1] : (asc ? c : -c);
        });
        var frag = document.createDocumentFragment();
        rows.forEach(function (x) { frag.appendChild(x[2]); });
        t.tBodies[0].appendChild(frag);
      });
    });
  });
  window.addEventListener("load", function () {
    document.documentElement.setAttribute("data-loaded-ms",
                                          String(Math.round(performance.now())));
  });
})();"""


def _e(x: object) -> str:
    return escape(str(x), quote=True)


def _num(x: object, spec: str = ".2f") -> str:
    return format(x, spec) if isinstance(x, (int, float)) and math.isfinite(x) else "-"


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


def _page(title: str, body: str, script: str = "") -> str:
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{_e(title)}</title><style>{CSS}</style></head>\n<body>\n{body}\n"
            + (f"<script>{script}</script>\n" if script else "") + "</body></html>\n")


def _attention(u: UnitRecord, why: dict[str, str], spec: dict[str, str]) -> int:
    """The table's first order: out of family, out of spec, unsure, then the rest."""
    if u.unit in why:
        return 0
    return {"out of spec": 1, "unsure": 2}.get(spec.get(u.unit, ""), 3)


def _summary(units: list[UnitRecord], result: CheckResult, spec_ppm: float | None,
             spec: dict[str, str], pages: dict[str, str]) -> str:
    why = {o.unit: o.why for o in result.outliers}
    n = Counter(spec.values())
    counts = [("units", len(units)), ("in family", len(units) - len(why)),
              ("out of family (unlike the line)", len(why))]
    if spec_ppm is not None:
        counts += [(f"out of spec ({spec_ppm:g} ppm test RMS)", n["out of spec"]),
                   ("within spec", n["within spec"]), ("unsure", n["unsure"])]
    cells = "".join(f"<tr><th class=\"l\">{_e(k)}</th><td>{v}</td></tr>" for k, v in counts)
    look = [u for u in units if u.unit in why or spec.get(u.unit) == "out of spec"]
    items = "\n".join(
        f"<li><a href=\"{pages[u.unit]}\">{_e(u.unit)}</a>: "
        + "; ".join(([f"unlike the line: {_e(why[u.unit])}"] if u.unit in why else [])
                    + (["out of spec"] if spec.get(u.unit) == "out of spec" else []))
        + "</li>" for u in look)
    check = _e(result.message()).replace("\n", "<br>\n")
    return f"""<section id="summary"><h2>Summary</h2>
<table class="counts">{cells}</table>
<h3>Out of family or out of spec ({len(look)})</h3>
{f'<ul>{items}</ul>' if look else '<p>none</p>'}
<p class="note">{check}</p></section>"""


def _index(units: list[UnitRecord], result: CheckResult, title: str, pages: dict[str, str],
           plots: list[tuple[str, str]], spec_ppm: float | None) -> str:
    why = {o.unit: o.why for o in result.outliers}
    spec = {} if spec_ppm is None else {u.unit: spec_verdict(u, spec_ppm) for u in units}
    rank = {u.unit: i for i, u in enumerate(sorted(units, key=lambda u: serial_key(u.unit)))}
    rows = []
    for u in sorted(units, key=lambda u: (_attention(u, why, spec), rank[u.unit])):
        r, part = residual_x(u)
        bad = u.unit in why
        iv = u.interval or {}
        cls = "flag" if bad else "spec" if spec.get(u.unit) == "out of spec" else ""
        rows.append(
            f"<tr class=\"{cls}\"><td class=\"l\" data-v=\"{rank[u.unit]}\"><a href=\""
            f"{pages[u.unit]}\">{_e(u.unit)}</a></td><td class=\"l\">{_e(u.created_utc)}</td>"
            f"<td>{u.chamber_hours:.1f}</td><td>{_num(r)} ({part})</td>"
            f"<td>{_num(iv.get('test_rms_ppm'))}</td>"
            f"<td data-v=\"{_num(iv.get('rms_hi_ppm'), '.6g')}\">{_num(iv.get('rms_lo_ppm'))}-"
            f"{_num(iv.get('rms_hi_ppm'))}</td><td>{_e(interval_x(u))}</td>"
            + ("" if spec_ppm is None else f"<td class=\"l\">{_e(spec[u.unit])}</td>")
            + f"<td class=\"l\">{_e(verdict(u, bad))}</td>"
            f"<td class=\"l\">{'yes: ' + _e(why[u.unit]) if bad else 'no'}</td></tr>")
    spec_head = "" if spec_ppm is None else f"<th class=\"l\">spec {spec_ppm:g} ppm</th>"
    imgs = "\n".join(f"<figure><img src=\"{name}\" alt=\"{_e(what)}\"></figure>"
                     for name, what in plots)
    return _page(f"fleet {title}", f"""<h1>Fleet <code>{_e(title)}</code></h1>
{_summary(units, result, spec_ppm, spec, pages)}
<h2>Plots</h2>
{imgs}
<h2>Units</h2>
<p class="note">Out of family and out of spec first; click a column's head to sort by it.
Residual: RMS SF error left by the unit's own model over the noise floor (x), on its test
log (else its training logs); interval: where training said the test RMS would fall
(ppm, and x the floor).</p>
<table class="sortable"><thead><tr><th class="l num">unit</th><th class="l">recorded (UTC)
</th><th class="num">chamber h</th><th class="num">residual x</th>
<th class="num">test RMS ppm</th><th class="num">interval ppm</th><th>interval x</th>
{spec_head}<th class="l">verdict</th><th class="l">unlike the line</th></tr></thead>
<tbody>
{chr(10).join(rows)}
</tbody></table>
""", SORT_JS)


def _unit_page(u: UnitRecord, result: CheckResult, spec_ppm: float | None) -> str:
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
    spec = ("" if spec_ppm is None else
            f"<p>spec {spec_ppm:g} ppm test RMS: <b>{_e(spec_verdict(u, spec_ppm))}</b></p>")
    return _page(f"unit {u.unit}", f"""<p><a href="../index.html">&larr; the fleet</a></p>
<h1>Unit <code>{_e(u.unit)}</code></h1>
<p>verdict: <b>{_e(verdict(u, flagged))}</b>{'; ' + _e(why[u.unit]) if flagged else ''}</p>
{spec}
<p>chamber hours {u.chamber_hours:.2f}; residual {_num(r)} x the floor ({part});
interval {_e(interval_x(u))} x; model <code>{_e(u.model_id)}</code>
{'in <code>' + _e(u.model_dir) + '</code>' if u.model_dir else '(folder not kept)'};
fogsf {_e(u.fogsf_version)}, recorded {_e(u.created_utc)} UTC</p>
{unit_svg(u)}
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


def write_report(units: list[UnitRecord], result: CheckResult, out: Path, title: str,
                 spec_ppm: float | None = None) -> Path:
    """Write the report into `out`, a folder it owns (the module's rule: a folder it did not
    write is refused, the previous report replaced whole); returns index.html."""
    out = Path(out)

    def write(tmp: Path) -> None:
        (tmp / "units").mkdir()
        plots = fleet_plots(units, result, tmp, spec_ppm)
        pages = {}
        for i, u in enumerate(units):
            name = f"unit-{i:03d}.html"
            (tmp / "units" / name).write_text(_unit_page(u, result, spec_ppm),
                                              encoding="utf-8")
            pages[u.unit] = f"units/{name}"
        (tmp / "index.html").write_text(_index(units, result, title, pages, plots, spec_ppm),
                                        encoding="utf-8")

    write_owned(out, write)
    return out / "index.html"


# --- the folder the report owns -------------------------------------------------------------

MARKER = ".fogsf-report"


def _files(folder: Path) -> set[str]:
    """Every entry under `folder`, as paths relative to it (folders end with /)."""
    out: set[str] = set()
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        out.update(f"{(rel / d).as_posix()}/" for d in dirs)
        out.update((rel / f).as_posix() for f in files)
    return out


def _own_listing(out: Path) -> set[str] | None:
    """What the report in `out` wrote, from its marker; None when `out` is not a report
    fogsf wrote (no marker, or a marker that is not ours)."""
    try:
        listed = json.loads((out / MARKER).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return {str(f) for f in listed} if isinstance(listed, list) else None


def check_out_dir(out: Path) -> None:
    """Refuse `out` unless the report may write there (see the module's rule)."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} exists and is not a folder")
    if not out.exists():
        return
    have = _files(out)
    if not have:
        return
    own = _own_listing(out)
    if own is None:
        raise UserError(f"--out {out} is a folder the report did not write ({len(have)} "
                        f"entries, no {MARKER} file): nothing written; give a new or "
                        "empty folder")
    foreign = sorted(have - own - {MARKER})
    if foreign:
        raise UserError(f"--out {out} holds files the report did not write ({foreign[0]}"
                        + (f" and {len(foreign) - 1} more" if len(foreign) > 1 else "")
                        + "): nothing written; move them or give another folder")


def _remove_listed(folder: Path, listed: set[str]) -> None:
    """Remove the files `listed` and then the emptied folders; anything else stays (and
    so does its folder)."""
    for rel in sorted(listed, key=len, reverse=True):  # files and subfolders before parents
        target = folder / rel
        try:
            target.rmdir() if rel.endswith("/") else target.unlink()
        except OSError:
            pass
    try:
        folder.rmdir()
    except OSError:
        pass


def write_owned(out: Path, write: Callable[[Path], None]) -> None:
    """`write(tmp)` fills a fresh folder beside `out`, which then replaces `out` whole
    (check_out_dir first: the swap assumes `out` is ours, empty or absent)."""
    check_out_dir(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.tmp-"))
    try:
        write(tmp)
        listing = sorted(_files(tmp))
        (tmp / MARKER).write_text(json.dumps({"fogsf_report": 1, "files": listing}, indent=1)
                                  + "\n", encoding="utf-8")
        os.chmod(tmp, 0o755)  # mkdtemp's 0700 would hide the report from the line
        check_out_dir(out)  # again: nothing may have moved in while the plots were drawn
        if out.exists() and _files(out):
            old = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.old-"))
            os.replace(out, old)  # onto the empty folder mkdtemp made: ours alone
            os.replace(tmp, out)
            _remove_listed(old, (_own_listing(old) or set()) | {MARKER})
        else:
            os.replace(tmp, out)  # rename onto an empty folder or none
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # the folder mkdtemp made for this run
        raise
