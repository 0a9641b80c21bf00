"""What the fleet store holds about one unit: its logs, its model, its figures and the summary
the design's prior, `fleet check` and `fleet report` read (the database alone is enough for
them; model folders are outputs).

`unit_record` builds a `UnitRecord` from what `fogsf train` produced (its metrics.json content
and the fitted model) and the logs it read."""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fogsf import __version__
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.metrics import sf_error_ppm
from fogsf.logs.measure.windows import sf_windows
from fogsf.prior.unit_summary import summarize_unit
from fogsf.training.fitted_model import per_sample_prediction
from fogsf.training.interval.transfer import ramp_segments
from fogsf.training.options import TrainOptions

if TYPE_CHECKING:
    from fogsf.logs.chamber_log import ChamberLog
    from fogsf.training.fitted_model import Fitted

# SF error against temperature (the report's curves) in bins of this width, C
SF_CURVE_BIN_C = 2.0
# a log's columns in the store's table `logs`, in `LogRecord.row`'s order
LOG_COLUMNS = ("path, sha256, n_rows, span_s, sample_rate_hz, ramp_rates, temp_min_c, "
               "temp_max_c, role")


@dataclass
class LogRecord:
    """One log a unit was trained or tested on. `role`: "train" or "test"."""

    path: str
    sha256: str
    rows: int
    span_s: float
    sample_rate_hz: float
    ramp_rates_c_per_min: list[float] = field(default_factory=list)
    temp_min_c: float = math.nan
    temp_max_c: float = math.nan
    role: str = "train"

    def row(self) -> tuple:
        """The log as the store's `logs` table holds it (LOG_COLUMNS; a temperature not
        measured as NULL)."""
        return (self.path, self.sha256, int(self.rows), float(self.span_s),
                float(self.sample_rate_hz), json.dumps(self.ramp_rates_c_per_min),
                *(float(x) if x is not None and math.isfinite(x) else None
                  for x in (self.temp_min_c, self.temp_max_c)), self.role)

    @classmethod
    def from_row(cls, r: tuple) -> LogRecord:
        return cls(path=r[0], sha256=r[1], rows=int(r[2]), span_s=float(r[3]),
                   sample_rate_hz=float(r[4]), ramp_rates_c_per_min=json.loads(r[5]),
                   temp_min_c=math.nan if r[6] is None else float(r[6]),
                   temp_max_c=math.nan if r[7] is None else float(r[7]), role=r[8])


@dataclass
class UnitRecord:
    """One unit (serial number `unit`) of the fleet as `fleet add` recorded it.

    fitted_with: the model kind, its structure and the training options; figures: from the
    model's metrics.json (train/test RMS before and after, noise floor, their ratio, the SF
    error against temperature); interval: the test RMS interval `train --test` printed (None
    without a test log); summary: what the design's prior needs
    (`fogsf.prior.unit_summary.summarize_unit`), JSON-able."""

    unit: str
    logs: list[LogRecord]
    model_id: str
    model_dir: str = ""
    fitted_with: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    interval: dict[str, Any] | None = None
    summary: dict[str, Any] = field(default_factory=dict)
    fogsf_version: str = __version__
    created_utc: str = ""

    @property
    def train_logs(self) -> list[LogRecord]:
        return [lg for lg in self.logs if lg.role == "train"]

    @property
    def chamber_hours(self) -> float:
        """Hours of chamber time the unit's training logs took (the line's cost)."""
        return sum(lg.span_s for lg in self.train_logs) / 3600.0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> UnitRecord:
        d = dict(d)
        d["logs"] = [LogRecord(**lg) for lg in d.get("logs", [])]
        return cls(**d)


def file_sha256(path: str | Path) -> str:
    """The file's SHA-256 (hex), read a block at a time."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def log_record(log: ChamberLog, role: str = "train") -> LogRecord:
    """A log as the store keeps it: where it was, its hash, size, span, rate, ramps and
    temperatures (the hash of the file on disk; empty for a log made in memory)."""

    p = Path(log.path)
    sha = file_sha256(p) if p.is_file() else ""
    temp = np.asarray(log.temp_c[:], dtype=np.float64)
    rates = sorted({round(abs(float(s.rate_c_per_min)), 3) for s in ramp_segments(log)})
    return LogRecord(path=str(p.resolve()) if p.is_file() else str(log.path), sha256=sha,
                     rows=len(log), span_s=log.duration_s,
                     sample_rate_hz=log.sample_rate_hz, ramp_rates_c_per_min=rates,
                     temp_min_c=float(np.nanmin(temp)), temp_max_c=float(np.nanmax(temp)),
                     role=role)


def after_blocks(part: dict) -> list[dict]:
    """The before/after blocks of metrics.json's "train" or "test" (one log or several)."""
    if "after" in part:
        return [part]
    return [v for _, v in sorted(part.items())]


def figures_of(metrics: dict) -> dict[str, Any]:
    """The figures the fleet reads from metrics.json: RMS before and after on the training
    and test logs (the training logs' RMS over all of them), noise floor and the ratios."""
    floor = float(metrics.get("noise_floor_ppm", math.nan))
    out: dict[str, Any] = {"noise_floor_ppm": floor, "model": metrics.get("model")}
    for part in ("train", "test"):
        if part not in metrics:
            continue
        blocks = after_blocks(metrics[part])
        for when in ("before", "after"):
            rms = [b[when]["rms_ppm"] for b in blocks]
            out[f"{part}_{when}_rms_ppm"] = float(math.sqrt(np.mean(np.square(rms))))
        out[f"{part}_rms_over_floor"] = (out[f"{part}_after_rms_ppm"] / floor
                                         if floor > 0 else math.nan)
    return out


def interval_of(metrics: dict) -> dict[str, Any] | None:
    """The interval training stated for the test RMS (ppm and x the floor) and whether the
    test RMS fell in it; None without a test log. A unit fitted under the design's prior:
    the prior's (`train --prior --test`, "expected test RMS with the prior's spread"), else
    the rate transfer's (`train --test`); `source` says which."""
    if "test" not in metrics:
        return None
    prior = (metrics.get("prior") or {}).get("interval_ppm")
    rt = metrics.get("rate_transfer")
    if prior:
        (lo, hi), source = (float(x) for x in prior), "prior"
    elif rt:
        (lo, hi), source = (float(x) for x in rt["rms_interval_ppm"]), "rate transfer"
    else:
        return None
    floor = float((rt or {}).get("noise_floor_ppm") or metrics.get("noise_floor_ppm", math.nan))
    rms = float(metrics["test"]["after"]["rms_ppm"])
    return {"rms_lo_ppm": lo, "rms_hi_ppm": hi, "noise_floor_ppm": floor,
            "test_rms_ppm": rms, "held": bool(lo <= rms <= hi) if hi > 0 else None,
            "covered": bool((rt or {}).get("covered", False)), "source": source}


SPEC_VERDICTS = ("within spec", "out of spec", "unsure")


def spec_verdict(rec: UnitRecord, spec_ppm: float) -> str:
    """The unit against a spec of `spec_ppm` test RMS, from the interval training stated
    for it (not its one test's RMS: the interval is what the unit will do on such a run):
    within when the interval's top is at or under the spec, out when its bottom is over
    it, else (the interval straddles it, or there is none: no test log) unsure."""
    iv = rec.interval or {}
    lo, hi = iv.get("rms_lo_ppm"), iv.get("rms_hi_ppm")
    if not (isinstance(lo, (int, float)) and isinstance(hi, (int, float))
            and math.isfinite(lo) and math.isfinite(hi) and hi > 0):
        return "unsure"
    if hi <= spec_ppm:
        return "within spec"
    if lo > spec_ppm:
        return "out of spec"
    return "unsure"


def sf_curve(fitted: Fitted, log: ChamberLog, ref: float, window_s: float,
             latitude_deg: float | None, settle_s: float) -> dict[str, list[float]]:
    """SF error against board temperature on `log`, before (about `ref`) and after the
    model, mean of the windows in SF_CURVE_BIN_C bins (the report's curves)."""

    before = sf_windows(log, window_s, latitude_deg, settle_s=settle_s)
    after = sf_windows(log, window_s, latitude_deg,
                       per_sample_prediction(fitted, log, latitude_deg), settle_s=settle_s)
    e0, e1 = sf_error_ppm(before, ref), sf_error_ppm(after, 1.0)
    bins = np.floor(before.temp_c / SF_CURVE_BIN_C).astype(int)
    out: dict[str, list[float]] = {"temp_c": [], "before_ppm": [], "after_ppm": []}
    for b in np.unique(bins):
        sel = (bins == b) & np.isfinite(e0) & np.isfinite(e1)
        if sel.any():
            out["temp_c"].append(round(float(np.mean(before.temp_c[sel])), 3))
            out["before_ppm"].append(round(float(np.mean(e0[sel])), 3))
            out["after_ppm"].append(round(float(np.mean(e1[sel])), 3))
    return out


# The design's reference program, in board temperature: a soak at -10 C, 1 C/min up to 35 C,
# a soak, 1 C/min down, a soak (1 h each; inside the board temperatures of a chamber's
# usual -20..40 C or wider program, so that no unit's model extrapolates on it). `response`
# reads a unit's model on it: what it predicts there is well determined by the unit's logs
# even where its parameters are not (two slow parts that move together trade their
# coefficients, not the prediction).
REFERENCE_SOAK_S = 3600.0
REFERENCE_RATE_C_PER_MIN = 1.0
REFERENCE_RANGE_C = (-10.0, 35.0)


def reference_points() -> list[tuple[str, float]]:
    """(name, time s) of the reference program's points where the response is read: each
    soak's end, and the ramps at 0, 10 and 25 C."""
    lo, hi = REFERENCE_RANGE_C
    ramp = (hi - lo) / REFERENCE_RATE_C_PER_MIN * 60.0
    s = REFERENCE_SOAK_S
    up = [(f"up {t:+.0f} C", s + (t - lo) / (hi - lo) * ramp) for t in (0.0, 10.0, 25.0)]
    down = [(f"down {t:+.0f} C", 2 * s + ramp + (hi - t) / (hi - lo) * ramp)
            for t in (25.0, 10.0, 0.0)]
    return [(f"soak {lo:+.0f} C", s), *up, (f"soak {hi:+.0f} C", 2 * s + ramp), *down,
            (f"soak {lo:+.0f} C again", 3 * s + 2 * ramp)]


def response(fitted: Fitted, sample_dt_s: float, latitude_deg: float | None
             ) -> dict[str, float]:
    """The model's SF error prediction (ppm) at the reference program's points, less their
    mean (a unit's SF offset is not its law)."""

    lo, hi = REFERENCE_RANGE_C
    ramp = (hi - lo) / REFERENCE_RATE_C_PER_MIN * 60.0
    s = REFERENCE_SOAK_S
    knots_t = [0.0, s, s + ramp, 2 * s + ramp, 2 * s + 2 * ramp, 3 * s + 2 * ramp]
    knots_c = [lo, lo, hi, hi, lo, lo]
    t = np.arange(0.0, knots_t[-1] + sample_dt_s / 2, sample_dt_s)
    temp = np.interp(t, knots_t, knots_c)
    one = np.full(t.shape, 10.0)
    log = ChamberLog(time_s=t, temp_c=temp, table_rate_dps=one, gyro_dps=one,
                     earth_rate_dps=np.zeros_like(t), path="<reference program>",
                     nominal_dt_s=sample_dt_s)
    pred = np.asarray(per_sample_prediction(fitted, log, latitude_deg)[:], dtype=np.float64)
    pts = reference_points()
    vals = np.array([pred[min(len(pred) - 1, int(round(tp / sample_dt_s)))] for _, tp in pts])
    vals -= vals.mean()
    return {name: round(float(v), 3) for (name, _), v in zip(pts, vals, strict=True)}


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def structure_label(metrics: dict, info: dict) -> str:
    """The model's structure in one word: "physics<N>" (N physics nodes), "bank" ("+cross"
    with the cross terms), "node<N>" or the model kind; "+play" with a hysteresis term."""
    kind = metrics.get("model", "?")
    if "physics_nodes" in info:
        s = f"physics{len(info['physics_nodes']['taus_s'])}"
    elif "lag_bank" in info:
        s = "bank" + ("+cross" if info["lag_bank"].get("cross_terms") else "")
    elif kind in ("lag-lstm", "gsa-lstm"):
        s = f"node{max(1, len(metrics.get('filter_tau_s', [])))}"
    else:
        return str(kind)
    if (metrics.get("hysteresis_choice") or {}).get("used"):
        s += "+play"
    return s


def structure_of(rec: UnitRecord) -> str:
    """A recorded unit's structure: its summary's, else what it was fitted with."""
    s = rec.summary.get("structure") or rec.fitted_with.get("structure") or "?"
    return s if isinstance(s, str) else str(s)


def recorded_options(opts: TrainOptions) -> dict[str, Any]:
    """The training options as a record holds them: how a run was computed (workers, a
    cluster, progress bars) is not what it trained."""
    return {k: v for k, v in vars(opts).items()
            if k not in ("progress", "workers", "dask", "extra")}


def fitted_with(metrics: dict, info: dict, options: dict[str, Any]) -> dict[str, Any]:
    """What the model was fitted with: its kind, its structure (`structure_label`), why
    (the structure choice's record, when the logs chose it) and the training options."""
    return {"model": metrics.get("model"), "structure": structure_label(metrics, info),
            "structure_choice": metrics.get("structure_choice"),
            "hysteresis": bool((metrics.get("hysteresis_choice") or {}).get("used", False)),
            "features": metrics.get("features"), "filter_tau_s": metrics.get("filter_tau_s"),
            "options": options}


def unit_record(unit: str, train_logs: list[ChamberLog], test_log: ChamberLog | None,
                metrics: dict, fitted: Fitted, model_dir: str | Path, options: dict[str, Any],
                keep_dir: bool = True) -> UnitRecord:
    """The record of a unit `fogsf train` has just fitted into `model_dir` (`metrics`: its
    metrics.json; `options`: the training options as data). `keep_dir` False: the folder is
    temporary and the record names none."""

    logs = [log_record(lg, "train") for lg in train_logs]
    if test_log is not None:
        logs.append(log_record(test_log, "test"))
    figures = figures_of(metrics)
    curve_log = test_log if test_log is not None else train_logs[0]
    figures["sf_curve_log"] = "test" if test_log is not None else "train"
    # torch: loaded only when a record is built from a trained model
    from fogsf.training.net.loops import SMALL_NET_UNITS, torch_threads

    sm = fitted.stream_model
    with contextlib.ExitStack() as stack:
        if sm is None or sm.layers * sm.hidden <= SMALL_NET_UNITS:  # as training does: one
            stack.enter_context(torch_threads(1))  # thread is fastest for a small net
        figures["response_ppm"] = response(fitted, train_logs[0].sample_dt_s,
                                           options.get("latitude_deg"))
        figures["sf_curve"] = sf_curve(fitted, curve_log, float(metrics["ref_sf_ratio"]),
                                       float(metrics["window_s"]), options.get("latitude_deg"),
                                       float(metrics["settle_s"]))
    return UnitRecord(
        unit=unit, logs=logs, model_id=str(metrics.get("model_id", "")),
        model_dir=str(Path(model_dir).resolve()) if keep_dir else "",
        fitted_with=fitted_with(metrics, fitted.info, options), figures=figures,
        interval=interval_of(metrics),
        summary=summarize_unit(train_logs, model_dir, step_s=float(metrics["model_step_s"]),
                               latitude_deg=options.get("latitude_deg")),
        created_utc=utc_now())
