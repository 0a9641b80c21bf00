"""The bias model fitted to the training logs (`fit_bias`): the targets each log measures,
the structure chosen by them (`training.bias.choice`) on the SF model's features z or on a
front end of its own, and the chosen candidate as the bias head's diagonal polynomial over z;
the `lead` structure's head, its lead-lag node's cubic and rate term spread over z's linear
terms, with its filters after the SF model's where the head shares the SF model's z."""

from __future__ import annotations

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import SETTLE_S
from fogsf.models.features import MODEL_STEP_S, PHYSICAL_SCALE_C, front_end_for
from fogsf.models.front_end import FrontEnd
from fogsf.models.reference import features as ref_features
from fogsf.models.step_inputs import frontend_s
from fogsf.models.structures.lag_bank import BankFit, n_curved
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import ridge_fit
from fogsf.models.structures.physics_nodes import NodeTemperatures
from fogsf.training.bias import choice as bc
from fogsf.training.bias import structure as bs
from fogsf.training.bias.features import (
    FeatureMap,
    bank_feature_map,
    lead_feature_map,
    node_feature_map,
    with_rows,
)
from fogsf.training.bias.interval import family
from fogsf.training.bias.model import BiasModel
from fogsf.training.bias.targets import (
    SFOf,
    at_targets,
    measured_windows,
    step_targets,
    target_kernel,
)

MIN_TARGETS = 3  # model steps (or pairs) the fit needs at the least
# A bias head on turning logs whose SF model carries a hysteresis play does not take `lead`:
# its own filter and feature beside the play's would take three such models past the
# Cortex-M4F image's 24 KB of flash (`make bench`, docs/firmware.md)
LEAD_LEFT_OUT = ("lead left out: the SF model carries a hysteresis play, and three models "
                 "with both overflow the 24 KB M4F image")
LEAD_LEFT_OUT_CROSS = ("lead left out: the SF model's quadratic carries cross terms, and three "
                       "models with both overflow the 24 KB M4F image")


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
            folds.append(bc.block_folds(idx, fe.step_s))
            per = (max(1, int(round(bc.SCORE_WINDOW_S / fe.step_s)))
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
        choice, fit = bc.choose(cols, y, fold, group, order)
        choice.left_out = left_out
        fam = family(cols, y, choice.scores, choice.name, group,
                     lambda lg: _shared_columns(fm, fm.z(lg).astype(np.float64),
                                                _free_columns(lg, fe0))[0],
                     lambda lg: fe0.at_rate(lg.sample_dt_s).decimation)
        if choice.name == "lead":  # the coil node's filters added to the SF model's
            return _shared_lead(fm, logs, kernels, row, y, fit, lags, i_t, step_s,
                                (sources, choice, fam))
        return BiasModel(fm, _head(fit, fm, i_t, lags), int(y.size), sources, choice, fam)
    choice, fit = bc.choose(free, y, fold, group, order)
    fam = family(free, y, choice.scores, choice.name, group,
                 lambda lg: _free_columns(lg, fe0),
                 lambda lg: fe0.at_rate(lg.sample_dt_s).decimation)
    taus = fit.taus_s
    if choice.name == "lead":
        assert fit.w is not None  # a lead fit has its weight
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


def _free_columns(log: ChamberLog, fe0: FrontEnd) -> bs.Columns:
    """A log's columns at every model step on a front end with no filter of its own (the
    lags computed at any time constant)."""
    nodes = NodeTemperatures([frontend_s(log.temp_c, fe0.at_rate(log.sample_dt_s))[:, 0]
                              .astype(np.float64)], fe0.step_s)
    return bs.Columns(nodes.z(())[:, 0], nodes.lag, None, nodes.z(TAU_GRID_S), n_curved())


def _shared_columns(fm: FeatureMap, z: np.ndarray, own: bs.Columns | None = None
                    ) -> tuple[bs.Columns, int | None, dict[float, int]]:
    """The candidates' columns on z (targets' rows): T and z's lags by time constant;
    `own`, the same rows' columns at any time constant (what `lead` reads)."""
    i_t, by_filter = bs.pure_columns(fm.feat_w)
    lags = {float(fm.fe.filter_tau_s[k]): i for k, i in by_filter.items()}
    t = z[:, i_t] if i_t is not None else z[:, 0]
    cols = bs.Columns(t, lambda tau: z[:, lags[tau]], tuple(lags), z, fm.curved, own)
    return cols, i_t, lags


def _head(fit: bs.CandidateFit, fm: FeatureMap, i_t: int | None, lags: dict[float, int]) -> BankFit:
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
    and its rate of change (`bias.structure.lead_rate`, linear in x) as one column, fitted
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
                 y: np.ndarray, fit: bs.CandidateFit, lags: dict[float, int], i_t: int | None,
                 step_s: float, rest: tuple) -> BiasModel:
    """`lead` as the SF model's bias head: the coil node (and the fast lag, if z has none)
    on filters of their own after the SF model's (`with_rows`); T (and the fast lag) from
    z's own features."""
    fast, tau_c = fit.taus_s
    assert fit.w is not None  # a lead fit has its weight
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
