"""The bias model: the gyro's bias (deg/h) as a polynomial of the SF model's own features z.

z are the front end's features (T and its lags for the default model); the bias head is
intercept + lin.z + quad.z^2 + cube.z^3 (diagonal). Which polynomial, the structure, is
chosen by the training targets (`bias_structure`: a cubic in T, with a Shupe term, on a coil
node, ..., or the lag bank's full polynomial by ridge with its penalty chosen by GCV,
`bias.structure.fit_gcv`). The Shupe term, a bias proportional to the rate of change of the coil's
temperature, is (T - lag(T, tau)) / tau: a linear combination of z. Targets are the bias
each training log measures (`logs.measure.bias`): a stationary log's model steps (mean of output -
earth rate over each step), a +/- pair's bias at the step under its centre, the columns
averaged there as the pair averages its plateaus (`target_kernel`).

`fit_bias(...)` (`training.bias.fit`) fits; `score_bias(...)` gives the before/after metrics
over a log's bias windows; `with_bias_head` and `bias_only_stream_model`
(`training.bias.artifact`) make the artifacts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.bias import before_after
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.models.reference import expand
from fogsf.models.structures.lag_bank import BankFit
from fogsf.training.bias import choice as bc
from fogsf.training.bias.features import FeatureMap
from fogsf.training.bias.interval import Family, bias_interval, interval_message
from fogsf.training.bias.targets import SFOf, _sf_for, measured_windows
from fogsf.training.interval.transfer import RATE_TOLERANCE, ramp_segments
from fogsf.training.results import BiasMetrics, BiasScore, BiasTransfer, RampRateCheck


@dataclass
class BiasModel:
    """bias (deg/h) = fit.predict(z); `fm` gives z."""

    fm: FeatureMap
    fit: BankFit
    n_targets: int
    sources: list[str]
    choice: bc.BiasChoice | None = None  # the structure and why
    family: Family | None = None  # what the rate-transfer interval needs
    n_shared: int = 0  # z's features the SF model reads (those after are the bias's own)

    def predict_steps(self, z: np.ndarray) -> np.ndarray:
        return self.fit.predict(z)

    def predict(self, log: ChamberLog) -> np.ndarray:
        """Per sample (deg/h), held over each model step as the kernel holds it."""
        fe = self.fm.fe.at_rate(log.sample_dt_s)
        return expand(self.predict_steps(self.fm.z(log)), len(log), fe.decimation)

    def as_dict(self) -> dict:
        return {"intercept_dph": self.fit.intercept, "lin": self.fit.lin.tolist(),
                "quad": self.fit.quad.tolist(), "cube": self.fit.cube.tolist(),
                "ridge_lambda": self.fit.lam, "dof": self.fit.dof,
                "targets": self.n_targets, "sources": self.sources,
                "own_features": list(self.fm.names[self.n_shared:]) if self.n_shared else [],
                "structure": None if self.choice is None else self.choice.as_dict()}


def score_bias(model: BiasModel, log: ChamberLog, window_s: float = 100.0,
               latitude_deg: float | None = None, settle_s: float = SETTLE_S,
               sf_of: SFOf | None = None) -> dict | None:
    """Before (the measured bias, nothing taken off) and after (measured - predicted, the
    prediction averaged over each window's samples) over the log's bias windows, deg/h;
    None for a log that measures no bias."""
    w = measured_windows(log, window_s, latitude_deg, settle_s, sf_of)
    return None if w is None else before_after(w, model.predict(log))


def score_logs(model: BiasModel, train_logs: list[ChamberLog], test_log: ChamberLog | None,
               window_s: float, latitude_deg: float | None, settle_s: float,
               sf_of: SFOf | None = None) -> BiasMetrics:
    """metrics.json's "bias" block: the fit, then test and train scores (one per log)."""
    def scored(log: ChamberLog) -> BiasScore | None:
        s = score_bias(model, log, window_s, latitude_deg, settle_s, sf_of)
        return None if s is None else BiasScore(**s)

    test = scored(test_log) if test_log is not None else None
    transfer = None
    if test_log is not None and test is not None and model.family is not None:
        interval = bias_interval(model.family, test_log, model.predict(test_log), window_s,
                                 latitude_deg, settle_s, _sf_for(test_log, sf_of))
        rr = (ramp_rate_check(train_logs, test_log, model.choice.name)
              if interval is not None and model.choice is not None else None)
        transfer = BiasTransfer(interval, rr)
    return BiasMetrics(model.as_dict(), tuple(scored(lg) for lg in train_logs),
                       tested=test_log is not None, test=test, transfer=transfer)


def ramp_rate_check(train_logs: list[ChamberLog], test_log: ChamberLog, structure: str
                    ) -> RampRateCheck:
    """The fastest ramp (C/min) of the training logs and of the test log, and whether the
    bias's rate term is extrapolated there: a structure with one (every one but the cubic)
    and a test ramp faster than any training ramp by more than the rate tolerance: a slower
    loop's pairs leave the rate term open (benchmarks/probes/README.md, "Bias structure")."""
    def fastest_of(logs: list[ChamberLog]) -> float:
        return max((abs(sg.rate_c_per_min) for lg in logs for sg in ramp_segments(lg)),
                   default=0.0)

    fastest, test = fastest_of(train_logs), fastest_of([test_log])
    return RampRateCheck(fastest, test, bool(structure != "cubic"
                                             and test > fastest * (1 + RATE_TOLERANCE)))


def bias_lines(b: BiasMetrics) -> list[str]:
    """`fogsf train`'s bias table (deg/h) from metrics.json's "bias" block."""
    import textwrap

    row = "  {:<16} {:>9} {:>9} {:>9} {:>9} {:>9}"
    lines = [row.format("bias, deg/h", "max|e|", "p-p", "RMS", "STD", "floor")]
    blocks = ([("test", b.test)] if b.test is not None else []) + [
        (f"train {i}" if len(b.train) > 1 else "train", s)
        for i, s in enumerate(b.train) if s is not None]
    for name, block in blocks:
        for when, m in (("before", block.before), ("after", block.after)):
            lines.append(row.format(f"{name} {when}", f"{m['max_abs_dph']:.4f}",
                                    f"{m['pp_dph']:.4f}", f"{m['rms_dph']:.4f}",
                                    f"{m['std_dph']:.4f}", f"{m['noise_floor_dph']:.4f}"))
    if b.transfer is not None and b.transfer.interval is not None:
        lines += ["  " + ln for ln in textwrap.wrap(interval_message(b.transfer.interval,
                                                                   b.transfer.ramp_rates), 94)]
    if b.model.get("structure"):
        lines += ["  " + ln for ln in textwrap.wrap(bc.choice_message(b.model["structure"]),
                                                     94)]
    src = ", ".join(sorted(set(b.model["sources"])))
    lines.append(f"  bias model: {b.model['targets']} targets ({src}) on the features z; "
                 "before = the measured bias, after = measured - predicted (floor: 1 sigma "
                 "of one window)")
    return lines
