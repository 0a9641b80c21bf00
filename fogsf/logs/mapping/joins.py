"""Several files, one run: `[join.NAME]` tables of the column map (docs/logs.md, "Several
loggers, one run").

The main log (the gyro's) sets the clock. Each join reads another file beside it (a chamber
logger's thermometers at 1 Hz, a table controller's commands as events), maps its columns
as the main map does (its own `time_s`, ISO-8601 text read as epoch seconds), and puts them
on the main log's time stamps: `how = "interpolate"` (a line between the stream's two
samples around each row) or `"hold"` (the stream's last sample at or before the row: a
command, a set point). A row farther than `max_gap_s` from the stream's samples (inside a
dropout of the stream, or outside the time it covers) measures nothing: it keeps a value for
the model to run over (the interpolation, or the held value) but gives no SF, no training
target and no metric, and it is counted. A dropout is never bridged silently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import LogError, is_temperature, time_text
from fogsf.logs.mapping.column_map import plan_map, with_kinds
from fogsf.logs.mapping.join_spec import Join
from fogsf.logs.mapping.time_zone import local_to_utc, parse_tz, whole_hours_off
from fogsf.logs.read.cell_kinds import numeric_cells, row_kinds
from fogsf.logs.read.clock_steps import judge_steps
from fogsf.logs.read.columns import Column
from fogsf.logs.read.dialect import Dialect, find_delimiter, raw_header
from fogsf.logs.read.line_scan import bad_cell_in

CLOCK_CHECK_S = 60.0  # a stream starting or ending this far from the log: said loudly


def join_path(j: Join, log_path: str) -> Path:
    """The joined file: `file` with {stem} (the log's name without extension), beside the
    log."""
    p = Path(log_path)
    return p.parent / j.file.replace("{stem}", p.stem)


def read_stream(j: Join, log_path: str, notes: list[str] | None = None
                ) -> tuple[str, dict[str, np.ndarray]]:
    """(path, {"time_s": ..., our names: ...}) of a joined file, in memory (a stream is
    small: 1 Hz for a day is 86400 rows), sorted rows checked: time increasing, exact
    duplicates dropped, a clock step back mended (`notes` say so)."""
    notes = [] if notes is None else notes

    if j.stream:
        return _field_stream(j, log_path, notes)
    path = join_path(j, log_path)
    p = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise UserError(f"{log_path}: [join.{j.name}] ({j.origin}): no file {p} "
                        f"(file = {j.file!r}; {{stem}} is {Path(log_path).stem!r})") from None
    except (OSError, UnicodeDecodeError) as e:
        raise LogError(p, None, "cannot read", str(e)) from None
    lines = [ln for ln in text.replace("\r\n", "\n").split("\n")]
    while lines and not lines[-1].strip():
        lines.pop()
    if len(lines) < 2:
        raise LogError(p, 1 if lines else None, "empty file", "no data rows to join")
    found: list[str] = []  # how the stream's file was read: not said
    delim = find_delimiter(lines[0], p, Dialect(), found)
    raw = raw_header(lines[0], delim, p)
    plan = plan_map(raw, (("time_s", j.time_s), *j.columns), f"[join.{j.name}]", p)
    plan = with_kinds(plan, row_kinds(lines[1].split(delim)), p, found)
    rows = [numeric_cells(ln, delim, plan.parsed_kinds) or ln for ln in lines[1:]]
    try:
        data = np.loadtxt(rows, delimiter=delim, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        data = None
    if data is None or data.shape != (len(rows), len(raw)):
        for i, ln in enumerate(rows, start=2):
            bad = bad_cell_in(ln, i, raw, p, delim, skip_hint=False)
            if bad is not None:
                raise bad
        raise LogError(p, None, "unreadable", "numbers could not be parsed")
    return p, _checked_stream(j, plan.apply(data, p), p, notes)


def _field_stream(j: Join, log_path: str, notes: list[str]
                  ) -> tuple[str, dict[str, np.ndarray]]:
    """A join's stream of the same field-format file (logs/read/field_formats.py)."""
    from fogsf.logs.read.field_formats import as_table, main_stream

    name, stream = main_stream(log_path, j.stream, f"[join.{j.name}]")
    names, data = as_table(stream)
    p = f"{log_path} [{name}]"
    plan = plan_map(names, (("time_s", j.time_s), *j.columns), f"[join.{j.name}]", p)
    return p, _checked_stream(j, plan.apply(data, p), p, notes)


def _checked_stream(j: Join, built: dict[str, np.ndarray], p: str, notes: list[str]
                    ) -> dict[str, np.ndarray]:
    """A stream's time and joined columns; exact duplicates dropped, time increasing: a
    step back is a re-synchronised clock when the stream's temperature runs on across it
    (the rows before it moved onto the clock after it, said in `notes`), else refused."""
    wanted = {"time_s", *(ours for ours, _ in j.columns)}
    cols = {k: np.asarray(v, dtype=np.float64) for k, v in built.items() if k in wanted}
    t = cols["time_s"]
    dt = np.diff(t)
    dup = np.flatnonzero(dt == 0) + 1
    if dup.size:
        same = np.all([v[dup] == v[dup - 1] for v in cols.values()], axis=0)
        cols = {k: np.delete(v, dup[same]) for k, v in cols.items()}
        t = cols["time_s"]
        dt = np.diff(t)
    temps = [k for k in cols if is_temperature(k)]
    back = [int(i) + 1 for i in np.flatnonzero(dt <= 0)]
    # each step judged on the stream as read, within the rows between its neighbours
    judged = judge_steps(t, cols[temps[0]], back) if temps and back else []
    step = float(np.median(dt[dt > 0])) if (dt > 0).any() else 0.0
    for k, r in enumerate(back):
        i = r - 1
        if dt[i] == 0 or not temps:
            raise LogError(p, i + 3, "time not increasing",
                           f"time_s {time_text(t, i + 1)} after {time_text(t, i)}"
                           + ("" if dt[i] == 0 else " (the stream has no temperature to "
                              "tell a re-synchronised clock from a reboot)"))
        b = judged[k]
        if not b.is_clock_step:
            raise LogError(p, i + 3, "clock restarts",
                           f"time_s {time_text(t, i + 1)} after {time_text(t, i)}: "
                           f"{b.why()}: the logger rebooted and its clock restarted, so "
                           "its later rows cannot be put on the log's clock: give them "
                           "wall-clock stamps, or split the file")
        # a clock set right while logging: the rows before the step were ahead by it
        moved = float((t[i + 1] - step) - t[i])
        t[:i + 1] += moved
        notes.append(f"[join.{j.name}] time steps {dt[i]:+.1f} s at line {i + 3}: "
                     f"{b.why()}: a re-synchronised clock, no sample missed: the rows "
                     f"before it moved {moved:+.1f} s onto the clock after it")
    return cols


@dataclass
class JoinReport:
    """What one join did."""

    name: str
    path: str
    rows: int  # the main log's rows
    covered: int  # rows within max_gap_s of the stream's samples
    gaps: list[tuple[float, float]]  # (start, length) of the stream's gaps > max_gap_s, s
    start_offset_s: float  # stream's first sample - log's first row
    end_offset_s: float  # stream's last sample - log's last row
    max_gap_s: float

    def text(self, t0: float) -> str:
        gaps = "; ".join(f"{g:.1f} s at t0+{a - t0:.1f} s" for a, g in self.gaps[:3])
        more = f" (+{len(self.gaps) - 3} more)" if len(self.gaps) > 3 else ""
        limit = (f"{len(self.gaps)} gap{'s' if len(self.gaps) != 1 else ''} > "
                 f"{self.max_gap_s:g} s{': ' + gaps + more if gaps else ''}"
                 if math.isfinite(self.max_gap_s) else "each value held until the next")
        return (f"join {self.name} ({Path(self.path).name}): {self.covered} of {self.rows} "
                f"rows covered, {self.rows - self.covered} measure nothing; {limit}; the stream "
                f"starts {self.start_offset_s:+.3f} s and ends {self.end_offset_s:+.3f} s "
                "from the log's first and last rows")

    def warning(self) -> str:
        """A short line of its own when the clocks look wrong (a tenth of the rows or more
        uncovered, or an end a minute or more off the log's), naming the likely cause: both
        ends the same whole hours off is a time zone, the same offset at both ends a wrong
        offset in time_s."""
        a, b = self.start_offset_s, self.end_offset_s
        far = max(abs(a), abs(b))
        if self.covered >= 0.9 * self.rows and far < CLOCK_CHECK_S:
            return ""
        head = (f"join {self.name}: CHECK THE CLOCKS: "
                f"{100.0 * (1 - self.covered / self.rows):.0f} % of the rows uncovered, "
                f"the stream's ends {a:+.1f} s and {b:+.1f} s off the log's")
        h = whole_hours_off(a, b, CLOCK_CHECK_S)
        if h is not None:
            return (f"{head}: {h:+d} h at both ends, a time zone: its local time read as UTC? "
                    f"give tz = \"{'+' if h > 0 else '-'}{abs(h):02d}:00\" (or its zone name) "
                    f"in [join.{self.name}]")
        if abs(a - b) < CLOCK_CHECK_S:
            return (f"{head}: about the same at both ends: a wrong offset in time_s, or a "
                    "counter that wrapped?")
        return f"{head}: a wrong offset in time_s, or a counter that wrapped before the first row?"


def zone_check(j: Join, path: str, start_off_s: float, end_off_s: float) -> None:
    """Refuse a stream whose both ends lie the same whole number of hours (within
    CLOCK_CHECK_S) off the log's: a local time read as UTC, or a zone given wrong."""
    h = whole_hours_off(start_off_s, end_off_s, CLOCK_CHECK_S)
    if h is None:
        return
    raise UserError(
        f"{path}: [join.{j.name}] ({j.origin}): time zone: the stream's clock is {h:+d} h off "
        f"the log's at both ends ({start_off_s:+.1f} s, {end_off_s:+.1f} s): local time read "
        f"as UTC? give its zone in [join.{j.name}]: tz = \"Europe/Berlin\" (or an offset, "
        f"\"{'+' if h > 0 else '-'}{abs(h):02d}:00\"), or --allow-clock-offset to join it as "
        "it is")


def apply_joins(cols: dict[str, Column], joins: tuple[Join, ...], path: str,
                notes: list[str], allow_clock_offset: bool = False
                ) -> tuple[dict[str, Column], list[JoinReport]]:
    """The main log's columns with each join's on its clock; the rows a join does not cover
    made not to measure (`valid` 0). What each join did goes to `notes`. A stream a whole
    number of hours off the log at both ends is refused (a time zone) unless
    `allow_clock_offset`."""
    if not joins:
        return cols, []
    t = np.asarray(cols["time_s"][:], dtype=np.float64)
    covered_all = np.ones(t.shape[0], dtype=bool)
    out = dict(cols)
    reports = []
    for j in joins:
        p, s = read_stream(j, path, notes)
        if j.tz is not None:
            s["time_s"] = local_to_utc(s["time_s"], parse_tz(j.tz, f"[join.{j.name}]"))
        ts = s["time_s"]
        if not allow_clock_offset and ts.size and t.size:
            zone_check(j, path, float(ts[0] - t[0]), float(ts[-1] - t[-1]))
        step = float(np.median(np.diff(ts))) if ts.size > 1 else 0.0
        gap = j.max_gap_s if j.max_gap_s is not None else (
            3.0 * step if j.how == "interpolate" else math.inf)
        if j.how == "interpolate":
            k = np.searchsorted(ts, t)
            before = np.abs(t - ts[np.clip(k - 1, 0, ts.size - 1)])
            after = np.abs(ts[np.clip(k, 0, ts.size - 1)] - t)
            # a row measures when both samples around it are within max_gap_s
            inside = (k > 0) & (k < ts.size)
            ok = inside & (before <= gap) & (after <= gap)
            ok |= (t == ts[np.clip(k, 0, ts.size - 1)])
        else:
            k = np.searchsorted(ts, t, side="right") - 1
            ok = (k >= 0) & (t - ts[np.clip(k, 0, ts.size - 1)] <= gap)
        for ours, _ in j.columns:
            if ours in out:
                raise UserError(f"{path}: [join.{j.name}] ({j.origin}) gives {ours}, which "
                                "the main log already has")
            v = s[ours]
            if j.how == "interpolate":
                out[ours] = np.interp(t, ts, v)
            else:
                out[ours] = v[np.clip(k, 0, ts.size - 1)]
        if not ok.any():
            raise UserError(f"{path}: [join.{j.name}] ({j.origin}): the stream covers none of "
                            f"the log's rows: it runs {ts[0] - t[0]:+.3f} .. "
                            f"{ts[-1] - t[0]:+.3f} s from the log's first row, the log "
                            f"0 .. {t[-1] - t[0]:.3f} s; check the clocks (time_s of the "
                            "log and of the join)")
        covered_all &= ok
        gaps = [(float(a), float(b - a)) for a, b in zip(ts[:-1], ts[1:], strict=True)
                if b - a > gap]
        reports.append(JoinReport(j.name, p, int(t.shape[0]), int(ok.sum()), gaps,
                                  float(ts[0] - t[0]), float(ts[-1] - t[-1]), gap))
    if not covered_all.all():
        old = out.get("valid")
        out["valid"] = covered_all.astype(np.float64) if old is None else \
            ((np.asarray(old[:]) != 0.0) & covered_all).astype(np.float64)
    notes.extend(r.text(float(t[0])) for r in reports)
    return out, reports
