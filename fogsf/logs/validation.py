"""A log's columns as a validated `ChamberLog` (docs/logs.md): exact duplicate rows dropped,
other files joined on its clock, gaps and resets mended into segments, then the rules checked
block by block (time increasing, every step within DT_TOLERANCE of the nominal one, a rate in
RATE_RANGE_HZ, a row that measures, temperatures in TEMP_RANGE_C), each refusal one `LogError`
naming the file, the line and the rule; every read path (CSV, field formats, Parquet, on disk)
ends here."""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import (
    DT_TOLERANCE,
    NOMINAL_DT_S,
    RATE_RANGE_HZ,
    RATE_SLACK,
    REQUIRED,
    TEMP_RANGE_C,
    ChamberLog,
    LogError,
    check_rate_hz,
    epoch_text,
    is_temperature,
    nominal_step_s,
    rate_text,
    time_text,
)
from fogsf.logs.mapping.column_map import ColumnPlan
from fogsf.logs.mapping.joins import apply_joins
from fogsf.logs.read.columns import (
    Column,
    blocks,
    col_max,
    col_min,
    derived,
    is_lazy,
    stand_in,
)
from fogsf.logs.read.dialect import Dialect
from fogsf.logs.read.sampling import default_max_gap_s, judge_resets, mend_segments, survey
from fogsf.logs.read.stamps import rounded_stamps


def _log_of(data: np.ndarray, plan: ColumnPlan, path: str, dialect: Dialect,
            notes: list[str], skipped: np.ndarray | None = None) -> ChamberLog:
    """The parsed cells (every column of the log) as a validated ChamberLog: our columns
    built by the plan, then checked; the rows `skipped` (a cell held no number: --bad-cells
    skip) measure nothing."""
    cols: dict[str, Column] = dict(plan.apply(data, path))
    if skipped is not None:
        old = cols.get("valid")
        keep = ~skipped if old is None else (np.asarray(old[:]) != 0.0) & ~skipped
        cols["valid"] = keep.astype(np.float64)
    return log_from_columns(cols, path, dialect, notes)


def log_from_columns(cols: dict[str, Column], path: str, dialect: Dialect, notes: list[str]
                     ) -> ChamberLog:
    """Our columns (in memory or on disk) as a validated ChamberLog: exact duplicate rows
    dropped, other files joined on its clock, its gaps and resets mended into segments
    (logs/read/sampling.py), then checked."""
    if dialect.sample_rate_hz is not None:
        check_rate_hz(dialect.sample_rate_hz)
    cols = rounded_stamps(cols, path, dialect.sample_rate_hz, notes)
    cols = without_duplicates(cols, notes)
    cols, reports = apply_joins(cols, dialect.joins, path, notes, dialect.allow_clock_offset)
    warnings = tuple(w for w in (r.warning() for r in reports) if w)
    t = cols["time_s"]
    nominal = (1.0 / dialect.sample_rate_hz if dialect.sample_rate_hz is not None
               else nominal_step_s(t))
    max_gap = (dialect.max_gap_s if dialect.max_gap_s is not None
               else default_max_gap_s(nominal))
    if dialect.sample_rate_hz is None:
        check_rate_range(nominal, path)
    sampling = survey(t, nominal, max_gap)
    if dialect.sample_rate_hz is None and sampling.jittered > 0.01 * sampling.steps:
        # a jittered clock: its period is the mean step (each counted in samples), not the
        # median of jittered steps
        nominal = 1.0 / float(f"{1.0 / sampling.mean_step_s:.6g}")
        sampling = survey(t, nominal, max_gap)
    if "temp_c" in cols:
        judge_resets(sampling, t, cols["temp_c"])
    cols = mend_segments(cols, sampling, dialect.gap_states)
    dt = validate(cols, path, dialect.sample_rate_hz, nominal)
    if abs(dt - NOMINAL_DT_S) > 1e-9 * NOMINAL_DT_S:
        notes.append(f"sample rate {1.0 / dt:.6g} Hz ("
                     f"{'--sample-rate-hz' if dialect.sample_rate_hz else 'from time_s'})")
    if sampling.irregular:
        notes.append(sampling.text())
    extra = {k: v for k, v in cols.items()
             if k not in REQUIRED and k not in ("earth_rate_dps", "valid")}
    valid = cols.get("valid")
    if valid is not None:
        v = valid
        valid = derived(len(v), np.dtype(bool), lambda s: v[s] != 0.0) if is_lazy(v) \
            else v != 0.0
    earth = cols.get("earth_rate_dps")
    return ChamberLog(
        time_s=stand_in(cols["time_s"]),
        temp_c=stand_in(cols["temp_c"]),
        table_rate_dps=stand_in(cols["table_rate_dps"]),
        gyro_dps=stand_in(cols["gyro_dps"]),
        earth_rate_dps=None if earth is None else stand_in(earth),
        valid=None if valid is None else stand_in(valid),
        extra={k: stand_in(v) for k, v in extra.items()},
        path=path,
        read_notes=tuple(notes),
        read_warnings=warnings,
        nominal_dt_s=dt,
        sampling=sampling,
    )


def without_duplicates(cols: dict[str, Column], notes: list[str]) -> dict[str, Column]:
    """`cols` without the rows that repeat the row before them exactly (a logger that wrote a
    sample twice), counted in `notes`; a row at the same time with other values stays (and
    is refused as time not increasing). A log with such rows is then held in memory."""
    t = cols["time_s"]
    same: list[np.ndarray] = []
    for a in range(0, max(len(t) - 1, 0), VALIDATE_BLOCK):
        dt = np.diff(np.asarray(t[a:a + VALIDATE_BLOCK + 1]))
        same.append(a + 1 + np.flatnonzero(dt == 0.0))
    rows = np.concatenate(same) if same else np.zeros(0, dtype=np.int64)
    if not rows.size:
        return cols
    for v in cols.values():
        rows = rows[np.asarray(v[rows]) == np.asarray(v[rows - 1])]
    if not rows.size:
        return cols
    notes.append(f"{rows.size} exact duplicate row{'s' if rows.size > 1 else ''} dropped "
                 f"(the first at line {int(rows[0]) + 2})")
    return {k: np.delete(np.asarray(v[:]), rows) for k, v in cols.items()}


def validate(cols: dict[str, Column], path: str, rate_hz: float | None = None,
             nominal: float | None = None) -> float:
    """Refuse a broken log (the rules of docs/logs.md); return its nominal sample period (s):
    1 / rate_hz, else `nominal` (the reader's, logs/read/sampling.py), else time_s's median step."""
    t = cols["time_s"]
    if rate_hz is not None:
        check_rate_hz(rate_hz)
        nominal = 1.0 / rate_hz
    elif nominal is None:
        nominal = nominal_step_s(t)
    if t.shape[0] >= 2:
        first_off: tuple[int, float] | None = None  # (index, step) of the first step off
        for a in range(0, t.shape[0] - 1, VALIDATE_BLOCK):  # no log-long temporaries
            dt = np.diff(t[a:a + VALIDATE_BLOCK + 1])
            nonincr = np.flatnonzero(dt <= 0)
            if nonincr.size:
                i = a + int(nonincr[0])
                raise LogError(path, i + 3, "time not increasing",
                               f"time_s {time_text(t, i + 1)} after {time_text(t, i)}"
                               f"{epoch_text(t)}")
            if first_off is None:
                off = np.flatnonzero(np.abs(dt - nominal) > DT_TOLERANCE * nominal)
                if off.size:
                    first_off = (a + int(off[0]), float(dt[off[0]]))
        if rate_hz is None:
            check_rate_range(nominal, path)
        if rate_hz is not None and first_off is not None:
            median_step = nominal_step_s(t)
            if abs(median_step - nominal) > DT_TOLERANCE * nominal:
                raise LogError(path, None, "sample rate",
                               f"the median step of time_s is {median_step:.4g} s "
                               f"({rate_text(median_step)}), not {nominal:.4g} s +/- "
                               f"{DT_TOLERANCE:.0%} (--sample-rate-hz {rate_hz:g})"
                               f"{epoch_text(t)}")
    # a log with the table stopped on every row is stationary: it measures the bias (the
    # SF figures refuse it, logs.measure.bias); a log whose every row is invalid measures nothing
    turning = kept = measures = False
    valid = cols.get("valid")
    for a, tab in blocks(cols["table_rate_dps"], size=VALIDATE_BLOCK):  # no log-long copies
        turn = tab != 0.0
        keep = np.ones(turn.shape[0], dtype=bool) if valid is None else \
            np.asarray(valid[a:a + turn.shape[0]]) != 0.0
        turning, kept = turning or bool(turn.any()), kept or bool(keep.any())
        measures = measures or bool((turn & keep).any())
    stationary = kept and not turning
    if not measures and not stationary:
        raise LogError(path, None, "no row measures",
                       "every row has a zero table rate or valid = 0: the SF is measured "
                       "while the table turns, the bias on a log with the table stopped "
                       "throughout")
    lo, hi = TEMP_RANGE_C
    for name, v in cols.items():
        if not is_temperature(name):
            continue
        for a, x in blocks(v, size=VALIDATE_BLOCK):
            out = np.flatnonzero((x < lo) | (x > hi))
            if out.size:
                i = int(out[0])
                raise LogError(path, a + i + 2, "temperature out of range",
                               f"{name} = {x[i]:g} C, allowed {lo:g}..{hi:g} C"
                               + temperature_unit_hint(v))
    return nominal


def temperature_unit_hint(v: Column) -> str:
    """What a temperature column outside TEMP_RANGE_C is likely in, by its range: Kelvin
    (every value 173 .. 400), Fahrenheit (every value -76 .. 212 and more than 1 % of them
    above 100: one spike is not a unit)."""
    lo, hi = col_min(v), col_max(v)
    if 173.0 <= lo and hi <= 400.0:
        return (f" (the column spans {lo:g} .. {hi:g}: Kelvin? map it as "
                "`NAME - 273.15`)")
    hot = sum(int(np.count_nonzero(x > TEMP_RANGE_C[1])) for _, x in blocks(v))
    if -76.0 <= lo and hi <= 212.0 and hot > 0.01 * len(v):
        return (f" (the column spans {lo:g} .. {hi:g}: Fahrenheit? map it as "
                "`(NAME - 32) / 1.8`)")
    return ""


VALIDATE_BLOCK = 1 << 20  # time steps checked at a time


def check_rate_range(nominal: float, path: str) -> None:
    """Refuse a median step outside RATE_RANGE_HZ (+/- RATE_SLACK): time_s not in seconds."""
    lo_hz, hi_hz = RATE_RANGE_HZ
    slack = 1.0 + RATE_SLACK  # a device clock a little off its nominal rate
    if not nominal > 0.0:  # NaN or a step back: time_s mostly decreasing
        raise LogError(path, None, "time not increasing",
                       f"the median step of time_s is {nominal:.6g} s: time_s must increase")
    if not 1.0 / (hi_hz * slack) <= nominal <= slack / lo_hz:
        raise LogError(path, None, "sample rate out of range",
                       f"the median step of time_s is {nominal:.6g} s "
                       f"({1.0 / nominal:.6g} Hz); allowed {lo_hz:g} Hz .. "
                       f"{hi_hz / 1000:g} kHz, +/- {RATE_SLACK:.0%} (time_s in seconds?)")
