"""Scale-factor error from a chamber log: the one place SF is measured.

This module holds the metrics block (`log_metrics`) and the note on a log that starts while
its temperature moves; beside it in logs/measure: `plateaus`, `windows` (the SF windows and
their noise), `units` (the rad/s - deg/s check), `sf_reference` (the SF at 20 C), `pairs`
(the +/- pairs and rate steps) and `model_steps` (the windows on model steps).

Plateaus. The table column gives the commanded rate; a plateau is a run of rows at one
commanded rate that measure (`ChamberLog.measures`). A table takes a moment to reach a newly
commanded rate, so the first `settle_s` seconds of every plateau but the log's first are
left out (SETTLE_S covers a table slewing about 1 s), and of the log's first plateau too
when its gyro shows the table spinning up there (`_spins_up`: a log that starts with its
table command); with `skip_s`, the log's first seconds too. What is left counts from
MIN_PLATEAU_S up.

Windows. A plateau at least `window_s` long is cut into whole non-overlapping windows from
its commanded start (its tail shorter than a window is not a window), and the settle margin
(and a skipped start) is trimmed off the windows it falls in, so that a plateau keeps its
number of windows; a shorter plateau is one window of its settled samples (from
MIN_PLATEAU_S up). On a log at one constant rate nothing is settled and every window is
`window_s` long, as it always was. The apparent SF ratio of a
window is mean(gyro - bias - earth) / mean(table) (nominal SF = 1). The SF error in ppm is
relative to the SF at 20 C (board thermometer) of the training data; after compensation
the residual is measured / predicted - 1, i.e. the window ratio of the corrected output.

+/- pairs. Adjacent plateaus of opposite sign and equal |rate| (`PAIR_RATE_TOL`) give SF
and bias separately (IEEE Std 952): SF = (m1 - m2) / (r1 - r2), bias = (m2 r1 - m1 r2) /
(r1 - r2), refined with the +/- plateaus next to the pair so that an SF drifting with
temperature between its two plateaus does not read as bias (`_pair_fit`). When a log has
pairs, their bias, interpolated in time between pair centres, is taken off the gyro before
any window, target or metric is measured, so that it does not leak into the SF at low rates
(a bias b reads as b / rate in SF). A pair's bias also holds half the SF asymmetry times
its rate (one pair cannot tell them apart), so it is taken off only at its own |rate|: there
each plateau then reads the mean of SF+ and SF- (what one SF correction can compensate);
a |rate| without pairs keeps its bias.

Rate steps. A log with plateaus at two or more |rates| in both directions (a staircase)
gives the SF per rate step, the SF nonlinearity (largest deviation of a rate level's mean
output from the least-squares straight line through all plateaus, ppm of the full-scale
output) and the SF asymmetry ((SF+ - SF-) / mean SF, ppm) as IEEE Std 952 defines them
(`rate_steps`).

The noise floor is the SF error that the gyro's own noise leaves in one window: each window
is cut into `SUB_WINDOWS` sub-windows (fewer in a short one, at least 3), a straight line is
fitted to their ratios (so thermal drift inside the window is not counted as noise), and the
residual spread over sqrt(n) is that window's noise; the floor is the RMS over windows.

Model steps. `step_windows` maps the windows onto model steps (a step belongs to the window
holding its middle sample) and `windows_rms` is the RMS of an error's window means there:
what training validates on and the rate-transfer check measures, so that every command uses
the same windows and the user's --window-s and --settle-s.
"""

from __future__ import annotations

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.measure.sf_reference import reference_sf
from fogsf.logs.measure.windows import SFWindows, sf_windows
from fogsf.logs.read.columns import searchsorted

START_SPAN_S = 300.0  # the start of a log: its first 5 minutes
START_MOVING_C_PER_MIN = 0.05  # faster than this at the start is "moving" (a soak is slower)


def sf_error_ppm(w: SFWindows, ref: float) -> np.ndarray:
    """Window SF error in ppm relative to the reference ratio `ref`."""
    return (w.sf_ratio / ref - 1.0) * 1e6


def noise_floor_ppm(w: SFWindows) -> float:
    """RMS of the windows' noise (windows too short for an estimate left out)."""
    ok = np.isfinite(w.noise_ppm)
    return float(np.sqrt(np.mean(w.noise_ppm[ok] ** 2))) if ok.any() else float("nan")


def metrics_block(err_ppm: np.ndarray, window_s: float, noise_floor: float) -> dict[str, float]:
    """The metrics block (docs/logs.md): max|e|, peak-to-peak, RMS about zero (the reference),
    STD about the mean, the window length and the noise floor, all in ppm (window in s)."""
    e = np.asarray(err_ppm, dtype=np.float64)
    return {
        "max_abs_ppm": float(np.max(np.abs(e))),
        "pp_ppm": float(np.ptp(e)),
        "rms_ppm": float(np.sqrt(np.mean(e**2))),
        "std_ppm": float(np.std(e)),
        "window_s": float(window_s),
        "noise_floor_ppm": float(noise_floor),
    }


def log_metrics(log: ChamberLog, window_s: float = 100.0, ref: float | None = None,
                latitude_deg: float | None = None,
                correction_ppm: np.ndarray | None = None, settle_s: float = SETTLE_S,
                skip_s: float = 0.0) -> dict[str, float]:
    """The metrics block of a log.

    Without a correction: SF error about `ref` (the apparent SF ratio at 20 C; measured on
    this log when not given). With `correction_ppm` (a model's per-sample prediction of the
    SF error vs nominal): the residual measured / predicted - 1 (no reference is used).
    `skip_s`: the log's first seconds are left out (the model still ran over them).
    """
    w = sf_windows(log, window_s, latitude_deg, correction_ppm, settle_s, skip_s)
    if correction_ppm is not None:
        ref = 1.0
    elif ref is None:
        ref = reference_sf(w, log.ref_temp_c)
    return metrics_block(sf_error_ppm(w, ref), window_s, noise_floor_ppm(w))


# --- the start of a log -----------------------------------------------------------------------

def start_ramp_c_per_min(log: ChamberLog, span_s: float = START_SPAN_S) -> float:
    """|dT/dt| of the board temperature over the log's first `span_s` seconds (a straight
    line fitted; the whole log when shorter), C/min."""
    t = log.time_s
    k = searchsorted(t, t[0] + span_s)
    k = max(k, min(len(log), 3))
    if k < 3 or t[k - 1] <= t[0]:
        return 0.0
    return abs(float(np.polyfit(t[:k] - t[0], log.temp_c[:k], 1)[0])) * 60.0


def start_note(log: ChamberLog, skip_s: float = 0.0) -> str | None:
    """One line when the log starts while its board temperature moves; None otherwise."""
    rate = start_ramp_c_per_min(log)
    if rate <= START_MOVING_C_PER_MIN:
        return None
    done = (f"the first {skip_s:g} s are left out of the metrics (--skip-s)" if skip_s > 0
            else "--skip-s S leaves the first S seconds out of the metrics")
    return (f"note: {log.path} starts while the board temperature moves ({rate:.2f} C/min over "
            f"its first {min(START_SPAN_S, log.duration_s):.0f} s): a model's lag states start "
            "at the first sample's temperature, as if the gyro had soaked there, so its output "
            f"is wrong until they catch up; {done}")
