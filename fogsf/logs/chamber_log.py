"""A chamber log in memory (`ChamberLog`), the refusal every reader raises (`LogError`), and
the rules' constants: the columns, the sample-rate range and tolerances, the temperature
range, the earth rate."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.measure.exact_stats import mean_in_order, median, step_blocks
from fogsf.logs.read.columns import (
    Column,
    LazyColumn,
    any_true,
    blocks,
    col_max,
    col_min,
    derived,
    is_lazy,
    stand_in,
)

REQUIRED = ("time_s", "temp_c", "table_rate_dps", "gyro_dps")
OPTIONAL = ("earth_rate_dps", "chamber_c", "valid")
NOMINAL_DT_S = 0.1  # the paper's 10 Hz: the period given to a log of a single sample
# Sample rates a log may have (Hz): a 1 Hz logger to a 4 kHz gyro output
RATE_RANGE_HZ = (1.0, 4000.0)
# A step between samples must lie within nominal dt * (1 +/- DT_TOLERANCE) (0.08..0.12 s at
# 10 Hz): a missed sample (twice the step) is refused as a gap, any other step beyond it as
# jitter.
DT_TOLERANCE = 0.2
GAP_STEPS = 1.5  # a step this many nominal steps long or longer is a gap (a missed sample)
RATE_SLACK = 0.01  # a median step up to 1 % beyond RATE_RANGE_HZ is a clock a little off
TEMP_RANGE_C = (-60.0, 100.0)
# time_s this large is a clock's epoch (ROS, Unix: 1.7e9 s), not seconds since power-on:
# messages show such times from the first sample
EPOCH_S = 1e6


class LogError(UserError):
    """A chamber log that breaks a rule; the message names file, line and rule."""

    def __init__(self, path: str, line: int | None, rule: str, detail: str) -> None:
        self.path = path
        self.line = line
        self.rule = rule
        self.detail = detail
        where = f"{path}: line {line}" if line is not None else path
        super().__init__(f"{where}: {rule}: {detail}")


@dataclass
class ChamberLog:
    """One chamber run. Arrays are float64 and all of one length."""

    time_s: np.ndarray
    temp_c: np.ndarray
    table_rate_dps: np.ndarray
    gyro_dps: np.ndarray
    earth_rate_dps: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    path: str = "<memory>"
    # how the file was read when not in the plain format (BOM, delimiter, column mapping)
    read_notes: tuple[str, ...] = ()
    # what the reader found likely wrong (clocks that disagree): each a line of its own
    read_warnings: tuple[str, ...] = ()
    # the nominal sample period (s): set by the reader and the simulator; None: the median
    # step of time_s (0.1 s for a log of one sample)
    nominal_dt_s: float | None = None
    # per sample, True where the row measures (the `valid` column or expression); None: every
    # row. Rows that do not measure stay in the log (the model runs over them as firmware
    # would) but give no SF, no training target and no metric; see `measures`.
    valid: np.ndarray | None = None
    # the cosine between the sensitive axis and the local vertical (up): the earth rate from
    # a latitude is scaled by it (`--axis-cosine`); an earth_rate_dps column is used as given
    axis_cosine: float = 1.0
    # the board temperature whose SF is the reference of the SF error (--ref-temp-c; a log
    # that never comes near it takes the nearest it holds: sf_reference.reference_sf)
    ref_temp_c: float = 20.0
    # how the rows lie in time (logs/read/sampling.py `Sampling`: jitter, drops, gaps, resets);
    # None: not surveyed (a log made in memory)
    sampling: Any = None

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    @property
    def sample_dt_s(self) -> float:
        """The nominal sample period, s."""
        if self.nominal_dt_s is not None:
            return float(self.nominal_dt_s)
        return nominal_step_s(self.time_s)

    @property
    def sample_rate_hz(self) -> float:
        return 1.0 / self.sample_dt_s

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if len(self) else 0.0

    @property
    def measures(self) -> np.ndarray:
        """Per sample, True where the row measures the SF: `valid` and a non-zero table rate
        (at rest the SF is undefined)."""
        if is_lazy(self.table_rate_dps):  # a log on disk: computed where it is read
            tab, valid = self.table_rate_dps, self.valid
            return stand_in(derived(len(self), np.dtype(bool), lambda s: (tab[s] != 0.0)
                                    if valid is None else (tab[s] != 0.0) & valid[s]))
        m = self.table_rate_dps != 0.0
        return m if self.valid is None else m & self.valid

    def earth(self, latitude_deg: float | None = None) -> np.ndarray:
        """Earth rate on the sensitive axis: the log's column, else from a latitude, times
        `axis_cosine` (1: a vertical axis).

        With neither, nothing is assumed: the refusal asks for --latitude-deg.
        """
        if self.earth_rate_dps is not None:
            return self.earth_rate_dps
        if latitude_deg is None:
            raise LogError(self.path, None, "no earth rate",
                           "the log has no earth_rate_dps column; pass --latitude-deg")
        value = earth_rate_vertical_dps(latitude_deg) * self.axis_cosine
        if is_lazy(self.time_s):  # a log on disk: the constant, not a copy per sample
            return np.broadcast_to(np.float64(value), (len(self),))
        return np.full(len(self), value)

    def columns(self) -> dict[str, np.ndarray]:
        cols = {
            "time_s": self.time_s,
            "temp_c": self.temp_c,
            "table_rate_dps": self.table_rate_dps,
            "gyro_dps": self.gyro_dps,
        }
        if self.earth_rate_dps is not None:
            cols["earth_rate_dps"] = self.earth_rate_dps
        if self.valid is not None:
            cols["valid"] = self.valid.astype(np.float64)
        cols.update(self.extra)
        return cols

    def slice(self, start: int, stop: int) -> ChamberLog:
        """Samples [start, stop) as a new log (arrays are views)."""
        return ChamberLog(
            time_s=self.time_s[start:stop],
            temp_c=self.temp_c[start:stop],
            table_rate_dps=self.table_rate_dps[start:stop],
            gyro_dps=self.gyro_dps[start:stop],
            earth_rate_dps=None if self.earth_rate_dps is None
            else self.earth_rate_dps[start:stop],
            valid=None if self.valid is None else self.valid[start:stop],
            extra={k: v[start:stop] for k, v in self.extra.items()},
            path=self.path,
            read_notes=self.read_notes,
            read_warnings=self.read_warnings,
            nominal_dt_s=self.sample_dt_s,
            axis_cosine=self.axis_cosine,
            ref_temp_c=self.ref_temp_c,
            sampling=self.sampling,
        )


def nominal_step_s(time_s: Column) -> float:
    """The median step of time_s, as 1 / (a rate of 6 significant digits) so that time
    stamps printed in decimal give 0.1 s, not 0.09999999999990905 (NOMINAL_DT_S for fewer
    than two samples)."""
    if is_lazy(time_s):
        return _nominal_step_on_disk(time_s)
    t = np.asarray(time_s, dtype=np.float64)
    if t.shape[0] < 2:
        return NOMINAL_DT_S
    step = float(np.median(np.diff(t), overwrite_input=True))  # no second log-long copy
    if step > 0 and np.spacing(np.abs(t).max()) > 1e-7 * step:
        # an epoch time base: each stamp is rounded to float64's spacing (0.24 us at 1.7e9
        # s), which the median step keeps; the mean of the steps near it averages that out
        dt = np.diff(t)
        step = float(dt[np.abs(dt - step) <= DT_TOLERANCE * step].mean())
    return 1.0 / float(f"{1.0 / step:.6g}") if step > 0 else step


def _nominal_step_on_disk(t: LazyColumn) -> float:
    """`nominal_step_s` of a time column on disk, a block at a time: the same bits."""
    n = len(t)
    if n < 2:
        return NOMINAL_DT_S

    steps = step_blocks(t)

    step = median(steps, n - 1)
    if step > 0 and np.spacing(max(abs(col_min(t)), abs(col_max(t)))) > 1e-7 * step:
        near = 0
        for dt in steps():
            near += int(np.count_nonzero(np.abs(dt - step) <= DT_TOLERANCE * step))

        def kept() -> Iterator[np.ndarray]:
            for dt in steps():
                yield dt[np.abs(dt - step) <= DT_TOLERANCE * step]

        step = mean_in_order(kept, near)
    return 1.0 / float(f"{1.0 / step:.6g}") if step > 0 else step


def time_text(time_s: Column, i: int) -> str:
    """time_s[i] as a message shows it: as it is, or `t0+12.3` for an epoch time base."""
    if abs(float(time_s[0])) < EPOCH_S:
        return f"{time_s[i]:g}"
    return f"t0+{time_s[i] - time_s[0]:.6g}"


def epoch_text(time_s: Column) -> str:
    """What `t0` is in `time_text`, when it is used ('' otherwise)."""
    if abs(float(time_s[0])) < EPOCH_S:
        return ""
    return f" (t0 = {time_s[0]:.6f} s, the first sample)"


def check_rate_hz(rate_hz: float, option: str = "--sample-rate-hz") -> float:
    """A stated sample rate, refused outside RATE_RANGE_HZ; returned as given."""
    lo, hi = RATE_RANGE_HZ
    if not lo <= rate_hz <= hi:
        raise UserError(f"{option} {rate_hz:g}: allowed {lo:g} .. {hi:g} Hz")
    return rate_hz


def rate_text(dt_s: float) -> str:
    """A sample period as people say it: '10 Hz', '2.5 kHz', '0.5 Hz'."""
    hz = 1.0 / dt_s
    return f"{hz / 1000:.4g} kHz" if hz >= 1000 else f"{hz:.4g} Hz"


EARTH_RATE_DPS = 360.0 / 86164.0905  # sidereal day


def earth_rate_vertical_dps(latitude_deg: float) -> float:
    """Earth rate projected on a vertical (up) sensitive axis at a latitude, in deg/s (an
    axis at an angle to the vertical sees it times the cosine of that angle)."""
    return EARTH_RATE_DPS * math.sin(math.radians(latitude_deg))


def is_temperature(name: str) -> bool:
    return name in ("temp_c", "chamber_c") or (name.startswith("temp_") and name.endswith("_c"))


def is_stationary(log: ChamberLog) -> bool:
    """True when the table is stopped on every row (and the log has rows to keep)."""
    if not len(log):
        return False
    if is_lazy(log.table_rate_dps):  # a log on disk: a block at a time
        return (not any(bool((x != 0.0).any()) for _, x in blocks(log.table_rate_dps))
                and (log.valid is None or any_true(log.valid)))
    keep = np.ones(len(log), dtype=bool) if log.valid is None else log.valid
    return not np.any(log.table_rate_dps != 0.0) and bool(keep.any())


def stationary_refusal(log: ChamberLog) -> UserError:
    """What an SF figure says of a stationary log: what the log can give instead."""
    return UserError(f"{log.path}: the table is stopped for the whole log, so it measures "
                     "the bias, not the SF: `fogsf inspect` shows its bias and `fogsf train` "
                     "fits a bias-only model on it; the SF needs a log with the table turning")
