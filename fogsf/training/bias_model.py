"""The bias model: the gyro's bias (deg/h) as a polynomial of the SF model's own features z.

z are the front end's features (T and its lags for the default model); the bias head is
intercept + lin.z + quad.z^2 + cube.z^3 (diagonal). Which polynomial, the structure, is
chosen by the training targets (`bias_structure`: a cubic in T, with a Shupe term, on a coil
node, ..., or the lag bank's full polynomial by ridge with its penalty chosen by GCV,
`bias_structure.fit_gcv`). The Shupe term, a bias proportional to the rate of change of the coil's
temperature, is (T - lag(T, tau)) / tau: a linear combination of z. Targets are the bias
each training log measures (`logs.bias`): a stationary log's model steps (mean of output -
earth rate over each step), a +/- pair's bias at the step under its centre, the columns
averaged there as the pair averages its plateaus (`target_kernel`).

`fit_bias(...)` fits; `score_bias(...)` gives the before/after metrics over a log's bias
windows; `with_bias_head` and `bias_only_stream_model` make the artifacts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.bias import BiasWindows, before_after, bias_windows
from fogsf.logs.chamber_log import ChamberLog, is_stationary
from fogsf.logs.columns import Column
from fogsf.logs.metrics import step_means
from fogsf.logs.plateaus import DPS_TO_DPH, SETTLE_S
from fogsf.models.features import (
    MODEL_STEP_S,
    PHYSICAL_SCALE_C,
    FeatureSpec,
    front_end_for,
    physical_normaliser,
)
from fogsf.models.front_end import FrontEnd
from fogsf.models.lag_bank import BankFit, bank_spec, n_curved
from fogsf.models.least_squares import TAU_GRID_S
from fogsf.models.node_fit import ridge_fit
from fogsf.models.physics_nodes import NodeTemperatures, node_spec
from fogsf.models.reference import expand
from fogsf.models.reference import features as ref_features
from fogsf.models.step_inputs import frontend_s
from fogsf.models.stream import StreamModel
from fogsf.models.stream_forms import diagonal_features
from fogsf.training import bias_structure as bs
from fogsf.training.bias_interval import bias_interval, family, interval_message
from fogsf.training.transfer import RATE_TOLERANCE, ramp_segments

MIN_TARGETS = 3  # model steps (or pairs) the fit needs at the least
# A stationary log's step with fewer valid samples than this share of a step (the log's
# last, partial step; one cut by invalid rows) is no target: the fit weighs every step
# alike, and a mean of a few samples holds the angle random walk of a few samples (one
# sample at 10 Hz: 12 deg/h off, which alone set a held-out score)
MIN_STEP_SHARE = 0.5
# A bias head on turning logs whose SF model carries a hysteresis play does not take `lead`:
# its own filter and feature beside the play's would take three such models past the
# Cortex-M4F image's 24 KB of flash (`make bench`, docs/firmware.md)
LEAD_LEFT_OUT = ("lead left out: the SF model carries a hysteresis play, and three models "
                 "with both overflow the 24 KB M4F image")
LEAD_LEFT_OUT_CROSS = ("lead left out: the SF model's quadratic carries cross terms, and three "
                       "models with both overflow the 24 KB M4F image")


@dataclass(frozen=True)
class FeatureMap:
    """What gives z for a log: the front end and z = feat_w s + feat_b (float32, the
    kernel's order)."""

    fe: FrontEnd
    feat_w: np.ndarray  # [F, 1+K] float32
    feat_b: np.ndarray  # [F] float32
    curved: int  # features (from the first) that carry squares and cubes
    names: tuple[str, ...] = ()  # the features' names, where known

    @property
    def weights(self) -> dict[str, np.ndarray]:  # what reference.features reads
        return {"feat_w": self.feat_w, "feat_b": self.feat_b}

    def z(self, log: ChamberLog) -> np.ndarray:
        """[n_steps, F] float32: the features of every model step of the log from reset."""
        s = frontend_s(log.temp_c, self.fe.at_rate(log.sample_dt_s))  # a block at a time
        return ref_features(self, s)  # type: ignore[arg-type]


def bank_curved(n_features: int, n_plays: int = 0) -> int:
    """Curved features for z of `n_features`: the bank's rule for the lag bank (its plays'
    features after it linear, as the SF model has them), all else."""
    return n_curved() if n_features - n_plays == bank_spec().n_features else n_features


@dataclass
class BiasModel:
    """bias (deg/h) = fit.predict(z); `fm` gives z."""

    fm: FeatureMap
    fit: BankFit
    n_targets: int
    sources: list[str]
    choice: Any = None  # bias_structure.BiasChoice: the structure and why
    family: Any = None  # bias_interval.Family: what the rate-transfer interval needs
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


def step_targets(log: ChamberLog, w: BiasWindows, decimation: int,
                 latitude_deg: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(step index, bias deg/h) the log gives: every step of a stationary log with at least
    MIN_STEP_SHARE of its samples valid, or each +/- pair at the step under its centre."""
    if w.source == "stationary":
        keep = np.ones(len(log), dtype=bool) if log.valid is None else log.valid
        y = step_means((log.gyro_dps - log.earth(latitude_deg)) * DPS_TO_DPH, decimation, keep)
        length = np.minimum(decimation, len(log) - np.arange(y.size) * decimation)
        count = (length if log.valid is None
                 else step_means(log.valid, decimation) * length)
        idx = np.flatnonzero(np.isfinite(y) & (count >= MIN_STEP_SHARE * decimation))
        return idx, y[idx]
    return w.step_index(decimation), w.bias_dph


def target_kernel(w: BiasWindows | None, step_s: float) -> np.ndarray | None:
    """What a target averages over, as weights on the model steps about it: a +/- pair's bias
    is (m0 + 3 m1 + 3 m2 + m3) / 8 of its four plateaus (`logs.pairs`), each half the pairs'
    span; a stationary log's target is its own step (None)."""
    if w is None or w.source != "pairs":
        return None
    p = max(1, int(round(0.5 * w.window_s / step_s)))
    k = np.repeat([1.0, 3.0, 3.0, 1.0], p)
    return k / k.sum()


def at_targets(x: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """x (steps[, columns]) averaged as the targets average (`target_kernel`), the ends
    held: the design a pair's bias is fitted to (linear features exactly; their squares and
    cubes to within their spread over a few minutes)."""
    if kernel is None:
        return x
    a = np.asarray(x, dtype=np.float64)
    flat = a.reshape(a.shape[0], -1)
    lo, hi = kernel.size // 2, kernel.size - 1 - kernel.size // 2
    out = np.column_stack([np.convolve(np.pad(flat[:, j], (lo, hi), mode="edge"), kernel[::-1],
                                       "valid") for j in range(flat.shape[1])])
    return out.reshape(a.shape).astype(a.dtype)


def fit_bias(fm: FeatureMap | None, logs: list[ChamberLog], window_s: float = 100.0,
             latitude_deg: float | None = None, settle_s: float = SETTLE_S,
             step_s: float = MODEL_STEP_S, candidates: tuple[str, ...] | None = None,
             sf_of: SFOf | None = None, full_quad: bool = False) -> BiasModel | None:
    """The bias model on the logs that measure the bias; None when none does. Its structure
    is chosen by the training targets (`bias_structure`): on `fm`'s features z when the
    bias head shares the SF model's (the node's time constant one of z's lags), on a front
    end of its own when `fm` is None (the time constant by variable projection). `sf_of`:
    the SF model's per-sample prediction of a log, taken off the pairs' plateaus
    (`measured_windows`). `lead` is left out beside an SF model with a play or, `full_quad`,
    with a full quadratic (the bank's cross terms): three such models would not fit 24 KB."""
    fe0 = fm.fe if fm is not None else front_end_for(logs, step_s, ())
    t_rel, zs, rows, ys, folds, groups, sources = [], [], [], [], [], [], []
    kernels: list[np.ndarray | None] = []
    base = group_base = 0
    for lg in logs:
        w = measured_windows(lg, window_s, latitude_deg, settle_s, sf_of)
        fe = fe0.at_rate(lg.sample_dt_s)
        kernels.append(target_kernel(w, fe.step_s))
        # frontend(...).s, a block of samples at a time, averaged as the targets are
        s = at_targets(frontend_s(lg.temp_c, fe), kernels[-1])
        n = s.shape[0]
        if w is not None:
            idx, y = step_targets(lg, w, fe.decimation, latitude_deg)
            ok = idx < n
            idx, y = idx[ok], y[ok]
            rows.append(base + idx)
            ys.append(y)
            folds.append(bs.block_folds(idx, fe.step_s))
            per = (max(1, int(round(bs.SCORE_WINDOW_S / fe.step_s)))
                   if w.source == "stationary" else 1)
            g = idx // per if per > 1 else np.arange(idx.size)
            groups.append(g + group_base)
            group_base += int(g.max(initial=0)) + 1
            sources.append(w.source)
        t_rel.append(s[:, 0].astype(np.float64))
        if fm is not None:
            zs.append(ref_features(fm, s))  # type: ignore[arg-type]
        base += n
    if not ys:
        return None
    y, row = np.concatenate(ys), np.concatenate(rows)
    if y.size < MIN_TARGETS:
        raise UserError(f"the training logs measure the bias {y.size} time(s): too few for "
                        f"a bias model (at least {MIN_TARGETS})")
    fold = np.concatenate(folds)
    group = np.concatenate(groups)
    order = bs.CANDIDATES if candidates is None else candidates
    nodes = NodeTemperatures(t_rel, fe0.step_s)
    free = bs.Columns(nodes.z(())[row, 0], lambda tau: nodes.lag(tau)[row], None,
                      nodes.z(TAU_GRID_S)[row], n_curved())
    if fm is not None:
        z = np.concatenate(zs).astype(np.float64)[row]
        cols, i_t, lags = _shared_columns(fm, z, free)
        fast = min(lags, default=bs.LEAD_FAST_S)
        if fast <= bs.LEAD_FAST_MAX_S:  # lead takes the board's rate from z's fastest lag
            free.lead_fast_s = fast
        if i_t is None:
            order = ("bank",)
        left_out = ""
        if (fm.fe.n_plays or full_quad) and "lead" in order:
            order = tuple(c for c in order if c != "lead")
            left_out = LEAD_LEFT_OUT if fm.fe.n_plays else LEAD_LEFT_OUT_CROSS
        choice, fit = bs.choose(cols, y, fold, group, order)
        choice.left_out = left_out
        fam = family(cols, y, choice.scores, choice.name, group,
                     lambda lg: _shared_columns(fm, fm.z(lg).astype(np.float64),
                                                _free_columns(lg, fe0))[0],
                     lambda lg: fe0.at_rate(lg.sample_dt_s).decimation)
        if choice.name == "lead":  # the coil node's filters added to the SF model's
            return _shared_lead(fm, logs, kernels, row, y, fit, lags, i_t, step_s,
                                (sources, choice, fam))
        return BiasModel(fm, _head(fit, fm, i_t, lags), int(y.size), sources, choice, fam)
    choice, fit = bs.choose(free, y, fold, group, order)
    fam = family(free, y, choice.scores, choice.name, group,
                 lambda lg: _free_columns(lg, fe0),
                 lambda lg: fe0.at_rate(lg.sample_dt_s).decimation)
    taus = fit.taus_s
    if choice.name == "lead":
        own = lead_feature_map(logs, step_s, taus[1], float(fit.w), taus[0])
        z = np.concatenate([at_targets(own.z(lg), k) for lg, k in zip(logs, kernels, strict=True)]
                           ).astype(np.float64)[row]
        return BiasModel(own, _lead_head(z, y, taus, float(fit.w)), int(y.size), sources,
                         choice, fam)
    own = (bank_feature_map(logs, step_s) if choice.name == "bank"
           else node_feature_map(logs, step_s, taus))
    z = np.concatenate([at_targets(own.z(lg), k) for lg, k in zip(logs, kernels, strict=True)]
                       ).astype(np.float64)[row]
    cols, i_t, lags = _shared_columns(own, z)
    refit = bs.fit_candidate(choice.name, cols, np.arange(y.size), y)
    return BiasModel(own, _head(refit, own, i_t, lags), int(y.size), sources, choice, fam)


def _free_columns(log: ChamberLog, fe0: FrontEnd) -> Any:
    """A log's columns at every model step on a front end with no filter of its own (the
    lags computed at any time constant)."""
    nodes = NodeTemperatures([frontend_s(log.temp_c, fe0.at_rate(log.sample_dt_s))[:, 0]
                              .astype(np.float64)], fe0.step_s)
    return bs.Columns(nodes.z(())[:, 0], nodes.lag, None, nodes.z(TAU_GRID_S), n_curved())


def _shared_columns(fm: FeatureMap, z: np.ndarray, own: Any = None
                    ) -> tuple[Any, int | None, dict[float, int]]:
    """The candidates' columns on z (targets' rows): T and z's lags by time constant;
    `own`, the same rows' columns at any time constant (what `lead` reads)."""
    i_t, by_filter = bs.pure_columns(fm.feat_w)
    lags = {float(fm.fe.filter_tau_s[k]): i for k, i in by_filter.items()}
    t = z[:, i_t] if i_t is not None else z[:, 0]
    cols = bs.Columns(t, lambda tau: z[:, lags[tau]], tuple(lags), z, fm.curved, own)
    return cols, i_t, lags


def _head(fit: Any, fm: FeatureMap, i_t: int | None, lags: dict[float, int]) -> BankFit:
    if fit.bank is not None:
        return fit.bank
    assert i_t is not None
    return bs.as_bank_fit(fit, i_t, [lags[t] for t in fit.taus_s], fm.feat_w.shape[0])


def _lead_head(z: np.ndarray, y: np.ndarray, taus: tuple[float, ...], w: float,
               at: tuple[int, int, int] = (0, 1, 2),
               scale: tuple[tuple[float, float], ...] = ((1.0, 0.0),) * 3,
               n_features: int = 3) -> BankFit:
    """The lead structure's head over z: T, the fast lag and the lead-lag node c at features
    `at` of z, each z_i = a x + b (`scale`, x in the physical unit; c's (1, 0)); c as a cubic
    and its rate of change (`bias_structure.lead_rate`, linear in x) as one column, fitted
    to the targets y; the rate's coefficient spread over the three linear terms."""
    t, fast, c = ((z[:, i] - b) / a for i, (a, b) in zip(at, scale, strict=True))
    rate = bs.lead_rate(t, fast, c, taus, w)
    f = ridge_fit(np.column_stack([c, c * c, c * c * c, rate]), y, bs.SMALL_LAMBDA)
    k1, k2, k3, kr = (float(v) for v in f.coef)
    # rate = T (w / fast + 1 / tau_c) - fast lag (w / fast) - c / tau_c
    lin_x = (kr * (w / taus[0] + 1.0 / taus[1]), -kr * w / taus[0], k1 - kr / taus[1])
    lin, quad, cube = np.zeros(n_features), np.zeros(n_features), np.zeros(n_features)
    intercept = f.intercept
    for k, i, (a, b) in zip(lin_x, at, scale, strict=True):
        lin[i] += k / a
        intercept -= k * b / a
    if scale[2] != (1.0, 0.0):
        raise ValueError("the lead-lag node's feature must be in the physical unit")
    quad[at[2]], cube[at[2]] = k2, k3
    return BankFit(intercept, lin, quad, cube, bs.SMALL_LAMBDA, 5.0)


def _shared_lead(fm: FeatureMap, logs: list[ChamberLog], kernels: list, row: np.ndarray,
                 y: np.ndarray, fit: Any, lags: dict[float, int], i_t: int | None,
                 step_s: float, rest: tuple) -> BiasModel:
    """`lead` as the SF model's bias head: the coil node (and the fast lag, if z has none)
    on filters of their own after the SF model's (`with_rows`); T (and the fast lag) from
    z's own features."""
    fast, tau_c = fit.taus_s
    w = float(fit.w)
    shared_fast = fast in lags
    own = lead_feature_map(logs, step_s, tau_c, w, None if shared_fast else fast,
                           with_t=False)
    wide = with_rows(fm, own)
    z = np.concatenate([at_targets(wide.z(lg), k) for lg, k in zip(logs, kernels, strict=True)]
                       ).astype(np.float64)[row]
    f = fm.feat_w.shape[0]
    assert i_t is not None

    def pure(i: int) -> tuple[float, float]:  # z_i = a x + b, x = s / 50 of its one column
        col = int(np.flatnonzero(fm.feat_w[i])[0])
        return (PHYSICAL_SCALE_C * float(fm.feat_w[i, col]), float(fm.feat_b[i]))

    i_fast = lags[fast] if shared_fast else f
    at = (i_t, i_fast, f if shared_fast else f + 1)
    scale = (pure(i_t), pure(i_fast) if shared_fast else (1.0, 0.0), (1.0, 0.0))
    head = _lead_head(z, y, fit.taus_s, w, at, scale, wide.feat_w.shape[0])
    sources, choice, fam = rest
    return BiasModel(wide, head, int(y.size), sources, choice, fam, f)


def with_rows(fm: FeatureMap, own: FeatureMap) -> FeatureMap:
    """The SF model's features `fm` followed by `own`'s (a bias structure's, on filters of
    its own): the front end runs fm's filters, then own's, then fm's plays; fm's rows read
    none of own's filters and its plays none of them, so fm's z is unchanged."""
    k, k_own, p = fm.fe.filter_alpha.size, own.fe.filter_alpha.size, fm.fe.n_plays
    if own.fe.n_plays or own.fe.decimation != fm.fe.decimation:
        raise ValueError("the bias features' front end differs from the SF model's")
    rows_sf = np.insert(fm.feat_w, [1 + k] * k_own, 0.0, axis=1)
    rows_own = np.zeros((own.feat_w.shape[0], 1 + k + k_own + p), np.float32)
    rows_own[:, 0] = own.feat_w[:, 0]
    rows_own[:, 1 + k:1 + k + k_own] = own.feat_w[:, 1:]
    if len(fm.fe.filter_tau_s) != k:
        raise ValueError("the SF model's filters' time constants are unknown")
    fe = replace(fm.fe, filter_alpha=np.concatenate([fm.fe.filter_alpha, own.fe.filter_alpha]
                                                    ).astype(np.float32),
                 filter_tau_s=(*fm.fe.filter_tau_s, *own.fe.filter_tau_s),
                 play_source_w=tuple((*r[:1 + k], *([0.0] * k_own), *r[1 + k:])
                                     for r in fm.fe.play_source_w))
    return FeatureMap(fe, np.concatenate([rows_sf, rows_own]).astype(np.float32),
                      np.concatenate([fm.feat_b, own.feat_b]).astype(np.float32), fm.curved,
                      (*(fm.names or ("",) * fm.feat_w.shape[0]), *own.names))


def lead_feature_map(logs: list[ChamberLog], step_s: float, tau_c: float, w: float,
                     fast_s: float | None, with_t: bool = True) -> FeatureMap:
    """The lead structure's features on a front end of its own (one physical unit): T (if
    `with_t`), lag(T, fast_s) (if given) and the node w T + (1 - w) lag(T, tau_c), in
    that order."""
    taus = ((fast_s,) if fast_s is not None else ()) + (tau_c,)
    k = len(taus)
    rows: list[tuple[float, ...]] = []
    names: list[str] = []
    if with_t:
        rows.append((1.0,) + (0.0,) * k)
        names.append("T")
    if fast_s is not None:
        rows.append((0.0, 1.0) + (0.0,) * (k - 1))
        names.append(f"lag(T,{fast_s:.0f}s)")
    rows.append((w,) + (0.0,) * (k - 1) + (1.0 - w,))
    names.append(f"node(T,{tau_c:.0f}s,w={w:.3f})")
    spec = FeatureSpec(taus, tuple(rows), tuple(names))
    norm = physical_normaliser(spec)
    return FeatureMap(front_end_for(logs, step_s, taus), norm.feat_w, norm.feat_b,
                      len(rows), spec.names)


def node_feature_map(logs: list[ChamberLog], step_s: float,
                     taus_s: tuple[float, ...]) -> FeatureMap:
    """T and lags of T at `taus_s` (one physical unit) on a front end of their own: a
    bias-only model's features for the `cubic`, `shupe` and `node` structures."""
    norm = physical_normaliser(node_spec(taus_s))
    return FeatureMap(front_end_for(logs, step_s, taus_s), norm.feat_w, norm.feat_b,
                      1 + len(taus_s))


SFOf = Callable[[ChamberLog], Column]  # a log -> the SF model's prediction, ppm per sample


def measured_windows(log: ChamberLog, window_s: float, latitude_deg: float | None,
                     settle_s: float, sf_of: SFOf | None = None) -> BiasWindows | None:
    """The bias windows a log measures (`logs.bias.bias_windows`); with `sf_of`, the SF
    model's prediction taken off the pairs' plateaus first (`PlateauPairs.minus_sf`: the SF
    drifting between a staircase pair's two plateaus would read as bias)."""
    return bias_windows(log, window_s, latitude_deg, settle_s, sf_ppm=_sf_for(log, sf_of))


def _sf_for(log: ChamberLog, sf_of: SFOf | None) -> Column | None:
    """The SF series to take off a log's pairs: none for a stationary log (no pairs)."""
    return None if sf_of is None or is_stationary(log) else sf_of(log)


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
               sf_of: SFOf | None = None) -> dict:
    """metrics.json's "bias" block: the fit, then test and train scores (one per log)."""
    out: dict = {"model": model.as_dict()}
    if test_log is not None:
        out["test"] = score_bias(model, test_log, window_s, latitude_deg, settle_s, sf_of)
        if out["test"] is not None and model.family is not None:
            out["rate_transfer"] = bias_interval(model.family, test_log,
                                                 model.predict(test_log), window_s,
                                                 latitude_deg, settle_s,
                                                 _sf_for(test_log, sf_of))
            if out["rate_transfer"] is not None and model.choice is not None:
                out["rate_transfer"]["ramp_rates"] = ramp_rate_check(
                    train_logs, test_log, model.choice.name)
    out["train"] = {f"log{i}": score_bias(model, lg, window_s, latitude_deg, settle_s, sf_of)
                    for i, lg in enumerate(train_logs)}
    return out


def ramp_rate_check(train_logs: list[ChamberLog], test_log: ChamberLog, structure: str
                    ) -> dict:
    """The fastest ramp (C/min) of the training logs and of the test log, and whether the
    bias's rate term is extrapolated there: a structure with one (every one but the cubic)
    and a test ramp faster than any training ramp by more than the rate tolerance. From a
    loop at 1 up / 0.7 down C/min, a 1.5 C/min test ramp leaves 0.134 deg/h median with a
    Shupe term (evaluation gyros 20000-20031); from 1 up / 2 down, 0.064 (docs/train.md,
    "Bias")."""
    def fastest_of(logs: list[ChamberLog]) -> float:
        return max((abs(sg.rate_c_per_min) for lg in logs for sg in ramp_segments(lg)),
                   default=0.0)

    fastest, test = fastest_of(train_logs), fastest_of([test_log])
    return {"train_fastest_c_per_min": fastest, "test_fastest_c_per_min": test,
            "rate_term_extrapolated": bool(structure != "cubic"
                                           and test > fastest * (1 + RATE_TOLERANCE))}


def check_mixed(logs: list[ChamberLog]) -> bool:
    """True when every training log is stationary (a bias-only model); refused when some
    are and some are not."""
    flags = [is_stationary(lg) for lg in logs]
    if any(flags) and not all(flags):
        still = ", ".join(lg.path for lg, f in zip(logs, flags, strict=True) if f)
        raise UserError(f"{still}: stationary (the table stopped throughout): such logs "
                        "train a bias-only model, given alone; the SF model with its bias "
                        "head trains on logs with the table turning (+/- pairs give the bias)")
    return all(flags)


def bank_feature_map(logs: list[ChamberLog], step_s: float) -> FeatureMap:
    """The lag bank's z (T and its lags, one physical unit) with its own front end: the
    bias-only model's features, and the bias's for SF models without a firmware form."""
    spec = bank_spec()
    norm = physical_normaliser(spec)
    return FeatureMap(front_end_for(logs, step_s, spec.taus_s), norm.feat_w, norm.feat_b,
                      n_curved())


def feature_map_of(stream_model: StreamModel | None, logs: list[ChamberLog],
                   step_s: float) -> FeatureMap:
    """The SF model's own z when it has a firmware form (the bias head reads the same
    state), else the lag bank's."""
    if stream_model is None:
        return bank_feature_map(logs, step_s)
    w = stream_model.weights
    return FeatureMap(stream_model.front_end, w["feat_w"], w["feat_b"],
                      bank_curved(stream_model.n_features, stream_model.n_plays))


def bias_lines(b: dict) -> list[str]:
    """`fogsf train`'s bias table (deg/h) from metrics.json's "bias" block."""
    import textwrap

    row = "  {:<16} {:>9} {:>9} {:>9} {:>9} {:>9}"
    lines = [row.format("bias, deg/h", "max|e|", "p-p", "RMS", "STD", "floor")]
    blocks = ([("test", b["test"])] if b.get("test") else []) + [
        (f"train {k[3:]}" if len(b["train"]) > 1 else "train", v)
        for k, v in b["train"].items() if v is not None]
    for name, block in blocks:
        for when in ("before", "after"):
            m = block[when]
            lines.append(row.format(f"{name} {when}", f"{m['max_abs_dph']:.4f}",
                                    f"{m['pp_dph']:.4f}", f"{m['rms_dph']:.4f}",
                                    f"{m['std_dph']:.4f}", f"{m['noise_floor_dph']:.4f}"))
    if b.get("rate_transfer"):
        lines += ["  " + ln for ln in textwrap.wrap(interval_message(b["rate_transfer"]), 94)]
    if b["model"].get("structure"):
        lines += ["  " + ln for ln in textwrap.wrap(bs.choice_message(b["model"]["structure"]),
                                                     94)]
    src = ", ".join(sorted(set(b["model"]["sources"])))
    lines.append(f"  bias model: {b['model']['targets']} targets ({src}) on the features z; "
                 "before = the measured bias, after = measured - predicted (floor: 1 sigma "
                 "of one window)")
    return lines


def with_bias_head(sm: StreamModel, model: BiasModel) -> StreamModel:
    """The artifact with the bias model as its bias head (float32, deg/h); the bias model
    must read the artifact's own z (`feature_map_of(sm, ...)`), or that z followed by
    features of its own (`with_rows`), which the artifact then gains."""
    if model.fm.feat_w.shape[0] > sm.n_features:
        sm = _widened(sm, model.fm)
    if model.fm.feat_w.tobytes() != sm.weights["feat_w"].tobytes():
        raise ValueError("the bias model reads other features than the artifact")
    f = model.fit
    weights = dict(sm.weights)
    weights.update({"bias_b": np.array([f.intercept], np.float32),
                    "bias_w": f.lin.astype(np.float32),
                    "bias_quad_w": f.quad.astype(np.float32),
                    "bias_cube_w": f.cube.astype(np.float32)})
    out = replace(sm, weights=weights, bias_head=True, extra=dict(sm.extra))
    out.validate()
    return out


def _widened(sm: StreamModel, fm: FeatureMap) -> StreamModel:
    """The artifact with `fm`'s filters and features after its own (`with_rows`): every SF
    weight on them zero, the LSTM reading the features it read, so sf_ppm is the same."""
    f, k = sm.n_features, sm.n_filters
    f2, k2 = fm.feat_w.shape[0], len(fm.fe.filter_tau_s)
    if (list(fm.fe.filter_tau_s[:k]) != list(sm.filter_tau_s) or fm.fe.filter_alpha[:k].tobytes()
            != sm.weights["filter_alpha"].tobytes() or fm.feat_w[:f].tobytes()
            != np.insert(sm.weights["feat_w"], [1 + k] * (k2 - k), 0.0, axis=1).tobytes()
            or fm.feat_b[:f].tobytes() != sm.weights["feat_b"].tobytes()
            or list(fm.fe.play_width_c) != list(sm.play_width_c)
            or fm.fe.decimation != sm.decimation):
        raise ValueError("the bias model's features do not extend the artifact's")
    w = dict(sm.weights)
    pad = np.zeros(f2 - f, np.float32)
    w.update({"filter_alpha": fm.fe.filter_alpha, "feat_w": fm.feat_w, "feat_b": fm.feat_b,
              "skip_w": np.concatenate([w["skip_w"], pad])})
    if sm.poly_head:
        w["cube_w"] = np.concatenate([w["cube_w"], pad])
        w["quad_w"] = (np.concatenate([w["quad_w"], pad]) if sm.quad_diag
                       else np.pad(w["quad_w"], ((0, f2 - f), (0, f2 - f))))
    extra = dict(sm.extra)
    if isinstance(extra.get("feature_names"), list) and len(fm.names) == f2:
        extra["feature_names"] = [*extra["feature_names"], *fm.names[f:]]
    out = replace(sm, weights=w, filter_tau_s=list(fm.fe.filter_tau_s), n_features=f2,
                  lstm_inputs=sm.n_lstm_inputs, extra=extra,
                  play_source_w=[list(r) for r in fm.fe.play_source_w])
    out.validate()
    return out


def bias_only_stream_model(model: BiasModel) -> StreamModel:
    """A bias-only artifact: the bias head on the bank's z, and an SF part that is exactly
    zero (a 1 x 1 LSTM reading z[0:1] with zero weights, zero head: sf_ppm = 0); its feature
    map as its diagonal (`feat_diag`) where it is one, as `fogsf train` writes SF models."""
    fm, f = model.fm, model.fm.feat_w.shape[0]
    zeros = {"lstm0_w": (4, 1), "lstm0_r": (4, 1), "lstm0_b": (8,), "head_w": (1,),
             "head_b": (1,), "skip_w": (f,), "out_offset": (1,)}
    weights = {k: np.zeros(s, np.float32) for k, s in zeros.items()}
    weights.update({"filter_alpha": np.asarray(fm.fe.filter_alpha, np.float32),
                    "feat_w": fm.feat_w, "feat_b": fm.feat_b,
                    "out_scale": np.ones(1, np.float32)})
    sm = StreamModel(model="bias", decimation=fm.fe.decimation, t_ref_c=fm.fe.t_ref_c,
                     t_min_c=fm.fe.t_min_c, t_max_c=fm.fe.t_max_c,
                     stuck_samples=fm.fe.stuck_samples,
                     filter_tau_s=list(fm.fe.filter_tau_s), n_features=f, layers=1, hidden=1,
                     weights=weights, sample_dt_s=fm.fe.sample_dt_s, lstm_inputs=1,
                     extra={"structure": "bias-only"})
    return diagonal_features(with_bias_head(sm, model))
