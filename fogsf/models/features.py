"""Model inputs and training targets at the model rate (one step per D samples).

Every model sees only what firmware has: the board thermometer, through the front end of the
streaming contract (`models.reference.frontend`: the sanitised temperature, block means of
D samples, first-order lag filters). Features are linear in the front end's
s = [Tm - t_ref, y_1 - t_ref, ..., y_K - t_ref]: raw rows `A` (e.g. T, a filtered dT/dt,
lag-filtered temperatures) normalised on the training data, so that z = feat_w s + feat_b
is exactly what the C kernel computes.

The target of step j is the measured SF error (ppm vs nominal) over the samples that step's
prediction is applied to: [jD, (j+1)D), i.e. the mean of (gyro - bias - earth) / table over
those of them that measure SF (`logs.measure.plateaus.measuring_mask`: settled table-rate plateaus;
the bias is the +/- pairs' when the log has pairs, `logs.measure.pairs.bias_track`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import DT_TOLERANCE, ChamberLog, rate_text
from fogsf.logs.measure.model_steps import step_windows
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.logs.read.columns import col_max, col_min
from fogsf.models.front_end import FrontEnd, decimation_for, filter_alpha
from fogsf.models.step_inputs import frontend_s
from fogsf.models.step_inputs import step_targets as in_blocks

T_REF_C = 20.0
RANGE_MARGIN_C = 5.0  # the valid input range is the training range widened by this
STUCK_S = 3600.0  # 1 h of bitwise-identical readings flags a stuck thermometer
MODEL_STEP_S = 5.0  # the default model step (50 samples at 10 Hz, 500 at 100 Hz)
SEC_PER_MIN = 60.0


@dataclass(frozen=True)
class FeatureSpec:
    """Features as rows of A over s: z_raw = A s, with A [F, 1+K+P] for filters `taus_s`
    and play operators `plays` ((source weights over [T, lag_1..lag_K], width_c) each;
    `models.front_end.FrontEnd`)."""

    taus_s: tuple[float, ...]
    rows: tuple[tuple[float, ...], ...]
    names: tuple[str, ...]
    plays: tuple[tuple[tuple[float, ...], float], ...] = ()

    @property
    def n_features(self) -> int:
        return len(self.rows)

    def matrix(self) -> np.ndarray:
        return np.asarray(self.rows, dtype=np.float64).reshape(
            len(self.rows), 1 + len(self.taus_s) + len(self.plays))

    def describe(self) -> str:
        taus = ", ".join(f"{t:g}" for t in self.taus_s)
        plays = ", ".join(f"play(x{j + 1}, {w:g} C)" for j, (_, w) in enumerate(self.plays))
        parts = [f"filters tau = {taus} s"] if taus else []
        parts += [f"plays {plays}"] if plays else []
        return f"[{', '.join(self.names)}]" + (f" ({'; '.join(parts)})" if parts else "")


def make_features(rate_tau_s: float | None = None) -> FeatureSpec:
    """T (the block mean) and, with `rate_tau_s`, dT/dt in C/min from a lag filter of that
    time constant ((T - y) / tau is the ramp rate once the filter has settled on a ramp):
    the paper's inputs."""
    if rate_tau_s is None:
        return FeatureSpec((), ((1.0,),), ("T",))
    k = SEC_PER_MIN / rate_tau_s
    return FeatureSpec((float(rate_tau_s),), ((1.0, 0.0), (k, -k)), ("T", "dT/dt"))


def effective_node_features(*nodes: tuple[float, float]) -> FeatureSpec:
    """One feature per node (tau_s, w): the effective sensing temperature
    T_eff = w T + (1 - w) lag(T, tau)."""
    k = len(nodes)
    rows = []
    for j, (_, w) in enumerate(nodes):
        r = [float(w)] + [0.0] * k
        r[1 + j] = 1.0 - float(w)
        rows.append(tuple(r))
    names = tuple(f"T_eff(tau={t:.0f}s,w={w:.2f})" for t, w in nodes)
    return FeatureSpec(tuple(float(t) for t, _ in nodes), tuple(rows), names)


@dataclass
class SeqData:
    """One log at the model rate."""

    log: ChamberLog
    s: np.ndarray  # [n_steps, 1+K+P] float32
    target_ppm: np.ndarray  # [n_steps] float64: measured SF error vs nominal (0: unmeasured)
    train_mask: np.ndarray  # [n_steps] bool: measured and outside the validation part
    decimation: int
    step_s: float  # seconds per model step
    measured: np.ndarray  # [n_steps] bool: the step holds a row that measures (settled)
    # [k, 2] step ranges of the SF windows (`logs.measure.model_steps.step_windows`): what the error
    # is averaged over before its RMS (validation, the rate-transfer check)
    windows: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        return int(self.s.shape[0])

    @property
    def val_mask(self) -> np.ndarray:
        """Measured steps of the validation part."""
        return self.measured & ~self.train_mask


def common_sample_dt(logs: list[ChamberLog]) -> float:
    """The one sample period of `logs` (the first log's; logs at another rate, beyond the
    reader's tolerance, are refused: a model is trained at one rate)."""
    dt = logs[0].sample_dt_s
    for lg in logs[1:]:
        if abs(lg.sample_dt_s - dt) > DT_TOLERANCE * dt:
            raise UserError(f"{lg.path} is sampled at {rate_text(lg.sample_dt_s)}, "
                            f"{logs[0].path} at {rate_text(dt)}: train on logs of one sample "
                            "rate (a model trained at one rate runs at any other)")
    return dt


def front_end_for(logs: list[ChamberLog], step_s: float, taus_s: tuple[float, ...],
                  sample_dt_s: float | None = None,
                  plays: tuple[tuple[tuple[float, ...], float], ...] = ()) -> FrontEnd:
    """The front end's constants for models trained on `logs`, one model step per `step_s`
    seconds at the logs' one sample rate (or at `sample_dt_s`), with play operators
    `plays` ((source weights, width_c), `FeatureSpec.plays`)."""
    lo = min(col_min(lg.temp_c) for lg in logs) - RANGE_MARGIN_C
    hi = max(col_max(lg.temp_c) for lg in logs) + RANGE_MARGIN_C
    dt = common_sample_dt(logs) if sample_dt_s is None else sample_dt_s
    d = decimation_for(step_s, dt)
    return FrontEnd(t_ref_c=T_REF_C, t_min_c=min(lo, T_REF_C - 1.0),
                    t_max_c=max(hi, T_REF_C + 1.0), decimation=d,
                    stuck_samples=int(round(STUCK_S / dt)),
                    filter_alpha=filter_alpha(list(taus_s), d, dt), sample_dt_s=dt,
                    filter_tau_s=tuple(float(t) for t in taus_s),
                    play_width_c=tuple(float(w) for _, w in plays),
                    play_source_w=tuple(tuple(float(v) for v in src) for src, _ in plays))


def step_targets(log: ChamberLog, decimation: int, latitude_deg: float | None = None,
                 settle_s: float = SETTLE_S) -> np.ndarray:
    """Mean SF error (ppm vs nominal) over the measuring samples (settled plateaus,
    `measuring_mask`) each model step's output is held for, the +/- pairs' bias taken off;
    NaN for a step without one. Made a block of steps at a time (models/step_inputs.py)."""
    return in_blocks(log, decimation, latitude_deg, settle_s)


def val_mask_for(n_steps: int, val_chunk: tuple[float, float]) -> np.ndarray:
    lo, hi = val_chunk
    j = np.arange(n_steps) / max(n_steps, 1)
    return (j >= lo) & (j < hi)


def prepare(log: ChamberLog, fe: FrontEnd, val_chunk: tuple[float, float] | None = None,
            latitude_deg: float | None = None, targets: np.ndarray | None = None,
            window_s: float = 100.0, settle_s: float = SETTLE_S) -> SeqData:
    """Front end and targets of one log; `val_chunk` (fractions of the run) is held out.
    A log at another sample rate than `fe`'s goes through `fe.at_rate` (the same model
    step in seconds). The SF windows (`window_s`, `settle_s`) are those of every metric."""
    fe = fe.at_rate(log.sample_dt_s)
    s = frontend_s(log.temp_c, fe)  # frontend(...).s, a block of samples at a time
    t = step_targets(log, fe.decimation, latitude_deg, settle_s) if targets is None else targets
    n = s.shape[0]
    val = val_mask_for(n, val_chunk) if val_chunk else np.zeros(n, dtype=bool)
    measured = np.isfinite(t)
    try:
        windows = step_windows(log, fe.decimation, window_s, settle_s)
    except UserError:  # no SF window: a log that only trains (its steps still give targets)
        windows = np.zeros((0, 2), dtype=np.int64)
    return SeqData(log, s, np.where(measured, t, 0.0), ~val & measured, fe.decimation,
                   fe.step_s, measured, windows)


@dataclass(frozen=True)
class Normaliser:
    """z = feat_w s + feat_b (float32), the normalisation folded into the feature map."""

    feat_w: np.ndarray  # [F, 1+K] float32
    feat_b: np.ndarray  # [F] float32

    def apply(self, s: np.ndarray) -> np.ndarray:
        """z per step for training (float32; the kernel's exact order is reference.features)."""
        return (s.astype(np.float64) @ self.feat_w.T.astype(np.float64)
                + self.feat_b).astype(np.float32)


PHYSICAL_SCALE_C = 50.0


def physical_normaliser(spec: FeatureSpec) -> Normaliser:
    """z = A s / 50 C: every feature in the same physical unit (no per-feature scaling), so
    that a ridge penalty treats every lag alike (the lag bank's normalisation)."""
    a = spec.matrix() / PHYSICAL_SCALE_C
    return Normaliser(a.astype(np.float32), np.zeros(a.shape[0], dtype=np.float32))


def fit_normaliser(spec: FeatureSpec, data: list[SeqData]) -> Normaliser:
    """Mean/std of each raw feature over the training steps, folded into A."""
    a = spec.matrix()
    raw = np.concatenate([d.s[d.train_mask].astype(np.float64) @ a.T for d in data])
    if raw.shape[0] < 10:
        raise UserError("too little training data: fewer than 10 model steps outside the "
                        "validation part")
    mu = raw.mean(axis=0)
    sd = raw.std(axis=0)
    sd = np.where(sd > 1e-9, sd, 1.0)
    return Normaliser((a / sd[:, None]).astype(np.float32), (-mu / sd).astype(np.float32))
