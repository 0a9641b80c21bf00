"""Irregular sampling, gaps and clock resets (docs/logs.md, "Irregular sampling, gaps and
bursts").

A logger's steps are not all the nominal one (the median step): a step within 20 % of it is
regular; a longer or shorter one up to `max_gap_s` is jitter, or dropped samples when it is
1.5 nominal steps or more (round(step / nominal) - 1 samples missed). These rows stay as
logged: `replay` runs the kernel on them as firmware would; training puts each log on a
regular grid of true times first (`on_grid`, `common_rate`), so that logs of different rates
train together and a model step is its seconds, not a count of rows.

A step longer than `max_gap_s` (default: `default_max_gap_s`) is a gap: the log is a run of
segments, and the gap is filled with rows that measure nothing (valid 0, `logged` 0) at the
nominal rate, so that the model's states cross it in time:
- "carry" (the default): the temperature interpolated over the gap (the gyro stayed powered,
  the logger dropped: a dropout, a burst logger between bursts);
- "restart": the temperature of the next segment's first row held over the gap (the gyro
  was off: its states settle where the power-on rule starts them, fully when the gap is
  several of the model's time constants long).
A clock that steps back by more than `max_gap_s` is judged by the temperature across it
(logs/read/clock_steps.py): a clock step (re-synchronised while logging: the temperature runs
on) has its later rows timed on from the row before; a reset (the logger rebooted: the
temperature jumps, the clock lands near 0, or a soak cannot tell) starts a new segment,
placed `RESET_GAP_S` after the last row and joined by the "restart" rule.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import DT_TOLERANCE, GAP_STEPS, ChamberLog, rate_text
from fogsf.logs.read.clock_steps import StepBack, judge_steps
from fogsf.logs.read.columns import Column

RESET_GAP_S = 3600.0  # a reset's segment starts this long after the last row (states settle)
# cells (rows x columns) a log's gaps may add: 2 GB of float64, 50 million rows of a
# five-column log; a wide log (a ROS message's every field) gets fewer rows
MAX_FILL_CELLS = 250_000_000
GAP_STATES = ("carry", "restart")


def default_max_gap_s(nominal_s: float) -> float:
    """What is a gap without --max-gap-s: 1 s, or 10 nominal steps at a rate under 10 Hz."""
    return max(1.0, 10.0 * nominal_s)


@dataclass
class Sampling:
    """How a log's rows lie in time (what `inspect` reports)."""

    nominal_s: float
    steps: int = 0
    jittered: int = 0  # steps off the nominal by more than DT_TOLERANCE, not drops
    worst_step_s: float = 0.0  # the step farthest from the nominal (jitter or drop)
    dropped: int = 0  # samples missed in steps of GAP_STEPS nominal steps or more
    drop_steps: int = 0
    gaps: list[tuple[int, float]] = field(default_factory=list)  # (row after, length s)
    resets: list[int] = field(default_factory=list)  # rows where the clock restarted
    clock_steps: list[int] = field(default_factory=list)  # rows where it was set back
    steps_back: list[StepBack] = field(default_factory=list)  # both, judged (`judge_resets`)
    filled_rows: int = 0
    # the first row of each segment in the log as read (gaps filled): [0] without gaps
    segment_starts: list[int] = field(default_factory=lambda: [0])
    max_gap_s: float = 0.0
    gap_states: str = "carry"
    # the mean step within segments, each counted as round(step / nominal) samples: the
    # clock's true period under jitter (the median step is one jittered step)
    mean_step_s: float = 0.0

    @property
    def irregular(self) -> bool:
        return bool(self.jittered or self.dropped or self.gaps or self.resets
                    or self.clock_steps)

    def text(self) -> str:
        parts = [f"nominal {rate_text(self.nominal_s)}"]
        if self.jittered:
            parts.append(f"{self.jittered} of {self.steps} steps off it by more than "
                         f"{DT_TOLERANCE:.0%}")
        if self.dropped:
            parts.append(f"{self.dropped} dropped samples in {self.drop_steps} steps")
        if self.jittered or self.dropped:
            parts.append(f"the step farthest from it {self.worst_step_s:.4g} s")
        if self.gaps:
            rule = ("states carried over them, the temperature interpolated"
                    if self.gap_states == "carry" else
                    "states restarted, the next segment's temperature held")
            parts.append(f"{len(self.gaps)} gap{'s' if len(self.gaps) > 1 else ''} > "
                         f"{self.max_gap_s:g} s (--max-gap-s; the longest "
                         f"{max(g for _, g in self.gaps):.1f} s): {len(self.gaps) + 1} "
                         f"segments, {rule}")
        for b in self.steps_back[:3]:
            parts.append(b.text(b.row + 2, RESET_GAP_S))
        if len(self.steps_back) > 3:
            parts.append(f"{len(self.clock_steps)} clock steps and {len(self.resets)} "
                         "reboots in all")
        if self.filled_rows:
            parts.append(f"{self.filled_rows} rows filled in that measure nothing "
                         "(logged = 0)")
        return "sampling: " + "; ".join(parts)


def survey(t: Column, nominal_s: float, max_gap_s: float, block: int = 1 << 20) -> Sampling:
    """The steps of `t` (in memory or on disk, read a block at a time) against the nominal
    one."""
    s = Sampling(nominal_s, max_gap_s=max_gap_s)
    n = int(t.shape[0]) if hasattr(t, "shape") else len(t)
    worst = -1.0
    span = count = 0.0
    for a in range(0, max(n - 1, 0), block):
        dt = np.diff(np.asarray(t[a:a + block + 1], dtype=np.float64))
        s.steps += int(dt.shape[0])
        s.resets += [a + int(i) + 1 for i in np.flatnonzero(dt < -max_gap_s)]
        s.gaps += [(a + int(i) + 1, float(dt[i])) for i in np.flatnonzero(dt > max_gap_s)]
        inside = (dt > 0) & (dt <= max_gap_s)
        span += float(dt[inside].sum())
        count += float(np.maximum(np.round(dt[inside] / nominal_s), 1.0).sum())
        drop = inside & (dt >= GAP_STEPS * nominal_s)
        s.drop_steps += int(drop.sum())
        s.dropped += int(np.maximum(np.round(dt[drop] / nominal_s) - 1, 1).sum())
        off = inside & ~drop & (np.abs(dt - nominal_s) > DT_TOLERANCE * nominal_s)
        s.jittered += int(off.sum())
        if (off | drop).any():
            dev = np.where(off | drop, np.abs(dt - nominal_s), -1.0)
            i = int(np.argmax(dev))
            if dev[i] > worst:
                worst, s.worst_step_s = float(dev[i]), float(dt[i])
    s.mean_step_s = span / count if count else nominal_s
    return s


def judge_resets(s: Sampling, t: Column, temp: Column) -> None:
    """Split the clock's steps back (`s.resets` as surveyed) into clock steps and reboots
    by the temperature across each (logs/read/clock_steps.py)."""
    if not s.resets:
        return
    s.steps_back = judge_steps(t, temp, list(s.resets))
    s.clock_steps = [b.row for b in s.steps_back if b.is_clock_step]
    s.resets = [b.row for b in s.steps_back if not b.is_clock_step]


def mend_segments(cols: dict[str, Column], s: Sampling, gap_states: str,
                  ) -> dict[str, Column]:
    """`cols` with each reset's segment moved after the last row (RESET_GAP_S on) and each
    gap filled with rows at the nominal rate that measure nothing: the temperature carried
    (interpolated) or restarted (the next row's held); the gyro and table rate interpolated
    (never measured); a `logged` column (1: a row of the file)."""
    s.gap_states = gap_states
    if not s.gaps and not s.resets and not s.clock_steps:
        return cols
    c = {k: np.asarray(v[:], dtype=np.float64) for k, v in cols.items()}
    t = c["time_s"]
    stepped = set(s.clock_steps)
    for r in sorted([*s.resets, *s.clock_steps]):
        # later rows shifted: a reboot's segment starts RESET_GAP_S after the last row, a
        # clock step's rows follow the row before by one nominal step (none was missed)
        t[r:] += (t[r - 1] + (s.nominal_s if r in stepped else RESET_GAP_S)) - t[r]
    if not s.gaps and not s.resets:
        return dict(c)
    dt = np.diff(t)
    cuts = np.flatnonzero(dt > s.max_gap_s) + 1
    n_fill = [max(int(np.floor((t[i] - t[i - 1]) / s.nominal_s - 1e-9)), 0) for i in cuts]
    if sum(n_fill) * (len(c) + 1) > MAX_FILL_CELLS:
        longest = max(float(t[i] - t[i - 1]) for i in cuts)
        raise UserError(f"the log's gaps would take {sum(n_fill)} rows of {len(c) + 1} "
                        f"columns to fill at {rate_text(s.nominal_s)} (the longest gap "
                        f"{longest:.6g} s: a time stamp off?): raise --max-gap-s, or split "
                        "the log")
    restart = set(s.resets)
    out: dict[str, list[np.ndarray]] = {k: [] for k in c}
    out["logged"] = []
    a = 0
    for i, n in zip(cuts, n_fill, strict=True):
        for k, v in c.items():
            out[k].append(v[a:i])
        out["logged"].append(np.ones(i - a))
        tt = t[i - 1] + s.nominal_s * np.arange(1, n + 1)
        hold = gap_states == "restart" or int(i) in restart
        for k, v in c.items():
            if k == "time_s":
                out[k].append(tt)
            elif k == "valid":
                out[k].append(np.zeros(n))
            elif hold and k != "table_rate_dps":
                out[k].append(np.full(n, v[i]))
            else:
                out[k].append(np.interp(tt, [t[i - 1], t[i]], [v[i - 1], v[i]]))
        out["logged"].append(np.zeros(n))
        a = int(i)
    for k, v in c.items():
        out[k].append(v[a:])
    out["logged"].append(np.ones(t.shape[0] - a))
    merged: dict[str, Column] = {k: np.concatenate(v) for k, v in out.items()}
    s.segment_starts = [0, *(int(i) + int(sum(n_fill[:j + 1]))
                             for j, i in enumerate(cuts))]
    if "valid" not in merged:
        merged["valid"] = np.concatenate(out["logged"])
    s.filled_rows = int(sum(n_fill))
    return merged


def on_grid(log: ChamberLog, dt_s: float) -> ChamberLog:
    """`log` on a regular grid of period `dt_s` from its first row, by true time: each grid
    row the mean of the rows within half a period of it (valid when every row there is, at
    one table rate), or, where there is none (a dropped sample), the line between its
    neighbours (valid when both are, at one table rate). For training: a model step is then
    its seconds."""
    t = np.asarray(log.time_s[:], dtype=np.float64)
    n = int(np.floor((t[-1] - t[0]) / dt_s + 1e-9)) + 1
    grid = t[0] + dt_s * np.arange(n)
    k = np.clip(np.round((t - t[0]) / dt_s).astype(np.int64), 0, n - 1)
    count = np.bincount(k, minlength=n).astype(np.float64)
    have = count > 0

    def binned(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x[:], dtype=np.float64)
        m = np.bincount(k, weights=x, minlength=n) / np.maximum(count, 1.0)
        if not have.all():
            m[~have] = np.interp(grid[~have], grid[have], m[have])
        return m

    tab = binned(log.table_rate_dps)
    meas = (np.ones(t.shape[0]) if log.valid is None
            else np.asarray(log.valid[:], dtype=np.float64))
    tab_lo = np.full(n, np.inf)
    tab_hi = np.full(n, -np.inf)
    raw_tab = np.asarray(log.table_rate_dps[:], dtype=np.float64)
    np.minimum.at(tab_lo, k, raw_tab)
    np.maximum.at(tab_hi, k, raw_tab)
    all_meas = np.bincount(k, weights=meas, minlength=n) == count
    valid = have & all_meas & (tab_lo == tab_hi)
    tab = np.where(have & (tab_lo != tab_hi), 0.0, tab)  # a row between two commands
    if not have.all():  # a dropped sample: the line between its neighbours, which measures
        # when both do at one table rate
        idx = np.arange(n)
        prev = np.maximum.accumulate(np.where(have, idx, 0))
        nxt = np.minimum.accumulate(np.where(have, idx, n - 1)[::-1])[::-1]
        bridge = ~have & valid[prev] & valid[nxt] & (tab[prev] == tab[nxt])
        tab = np.where(~have, np.where(bridge, tab[prev], 0.0), tab)
        valid = valid | bridge
    return replace(
        log, time_s=grid, temp_c=binned(log.temp_c), table_rate_dps=tab,
        gyro_dps=binned(log.gyro_dps),
        earth_rate_dps=None if log.earth_rate_dps is None else binned(log.earth_rate_dps),
        valid=valid, extra={k2: binned(v) for k2, v in log.extra.items()},
        nominal_dt_s=dt_s, read_notes=(*log.read_notes, f"on a {rate_text(dt_s)} grid "
                                       "of true times for training"))


def common_rate(logs: list[ChamberLog]) -> list[ChamberLog]:
    """Training logs on one rate: when their rates differ (beyond the reader's 20 %) or any
    is irregular (jitter, dropped samples), each is put on a grid at the lowest of their
    rates (`on_grid`); otherwise they are returned as they are."""
    if not logs:
        return logs
    dts = [lg.sample_dt_s for lg in logs]
    slow = max(dts)
    same = all(abs(d - dts[0]) <= DT_TOLERANCE * dts[0] for d in dts)
    irregular = any(lg.sampling is not None and (lg.sampling.jittered or lg.sampling.dropped)
                    for lg in logs)
    if same and not irregular:
        return logs
    return [on_grid(lg, slow) for lg in logs]


def burst_window_s(logged: np.ndarray | None, dt_s: float, default_s: float) -> float | None:
    """The SF window a log written in bursts (runs of logged rows between unlogged gaps)
    holds: its median burst's length, when that is shorter than `default_s`; None for a
    log without gaps or with bursts as long as the default window. A 5 s burst every 5 min
    (a thermal-vacuum logger) gives 5 s windows, one a burst."""
    if logged is None:
        return None
    mask = np.asarray(logged) != 0
    if mask.all() or not mask.any():
        return None
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    lengths = (edges[1::2] - edges[::2]) * dt_s
    burst = float(np.floor(np.median(lengths) * 10.0 + 1e-6) / 10.0)
    return burst if 0.0 < burst < default_s else None
