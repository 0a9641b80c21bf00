"""Time stamps coarser than the sample period (a 10 Hz logger printing whole seconds): most
steps of time_s are 0, so neither the rate nor the order of the rows can be read from them.
Refused in one line naming the rate the row count gives; with `--sample-rate-hz` the rows are
timed at that rate from the first stamp instead, when they stay within the stamps' rounding
of them (a dropped or doubled row would not)."""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import LogError
from fogsf.logs.read.columns import Column, blocks

# More than this share of zero steps is a clock printed coarser than its rate, not a row
# written twice (those, when exact, are dropped; otherwise refused at their line); so are
# more than MIN_REPEATS of them, so that a short log's one repeated row is refused at its line
REPEAT_SHARE = 0.01
MIN_REPEATS = 5


def zero_steps(t: Column) -> int:
    """The number of steps of `t` that are exactly 0, a block at a time."""
    count, last = 0, None
    for _, x in blocks(t):
        x = np.asarray(x, dtype=np.float64)
        if last is not None and x.size:
            count += int(x[0] == last)
        count += int(np.count_nonzero(np.diff(x) == 0.0))
        if x.size:
            last = float(x[-1])
    return count


def rounded_stamps(cols: dict[str, Column], path: str, rate_hz: float | None,
                   notes: list[str]) -> dict[str, Column]:
    """`cols` as they are when their time stamps are not rounded coarser than the rows; else
    refused (no `rate_hz`), or re-timed at `rate_hz` from the first stamp (said in `notes`)."""
    t = cols["time_s"]
    n = len(t)
    if n < 3:
        return cols
    zeros = zero_steps(t)
    if zeros <= max(REPEAT_SHARE * (n - 1), MIN_REPEATS):
        return cols
    tt = np.asarray(t[:], dtype=np.float64)
    span = float(tt[-1] - tt[0])
    steps = np.diff(tt)
    pos = steps[steps > 0]
    res = float(pos.min()) if pos.size else 0.0  # the stamps' resolution: their smallest step
    if span <= 0.0 or not np.isfinite(span):
        raise LogError(path, None, "repeated time stamps",
                       f"time_s does not advance: {zeros} of {n - 1} steps are 0 and the last "
                       f"stamp is {tt[-1]:g} after a first of {tt[0]:g}: map a time column "
                       "(--columns time_s=...)")
    est_hz = (n - 1) / span
    guess = float(f"{est_hz:.2g}")
    if rate_hz is None:
        raise LogError(path, None, "repeated time stamps",
                       f"{zeros} of {n - 1} steps of time_s are 0 (stamps rounded to "
                       f"{res:g} s?): {n} rows in {span:g} s is about {est_hz:.4g} Hz; give "
                       f"the logger's rate, e.g. --sample-rate-hz {guess:g}, and the rows are "
                       "timed at it from the first stamp")
    new = tt[0] + np.arange(n, dtype=np.float64) / rate_hz
    off = new - tt
    worst = int(np.argmax(np.abs(off)))
    if abs(off[worst]) > res + 1.0 / rate_hz:  # rounded or truncated stamps, a step of slack
        raise LogError(path, worst + 2, "repeated time stamps",
                       f"time_s is rounded ({zeros} of {n - 1} steps are 0), and rows timed at "
                       f"--sample-rate-hz {rate_hz:g} from the first stamp are {off[worst]:+.4g} "
                       f"s off this row's stamp {tt[worst]:g}, more than its {res:g} s rounding: "
                       f"rows dropped or doubled, or another rate (the row count gives "
                       f"{est_hz:.4g} Hz)")
    notes.append(f"time_s rounded to {res:g} s ({zeros} of {n - 1} steps 0): rows timed at "
                 f"--sample-rate-hz {rate_hz:g} from the first stamp (within "
                 f"{np.abs(off).max():.3g} s of every stamp)")
    return {**cols, "time_s": new}
