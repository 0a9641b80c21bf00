"""Fit the base model, score every catalogue effect on held-out data, name the cause.

`diagnose` is the entry point: it loads the runs, refuses logs of more than one gyro,
fits the base model, scores every candidate and applies the rules below, then decides
whether structure remains. The scoring and choosing rules live in `selection` (with their
thresholds: ALPHA, MIN_VISIBLE, AMBIGUOUS_P, ...), the profiled parameters in `intervals`,
the fitted models and the records in `fits`; the structure rules are this module's.

Decision rules (all on held-out residuals, per block of windows, never per window):

- A candidate is *significant* when it predicts held-out windows better than the base on
  enough blocks that a paired sign-flip test gives p < ALPHA, and its held-out RMS gain is
  at least MIN_GAIN_PCT.
- It is *not identifiable* on these logs when the part of its column that the base model
  cannot absorb is below MIN_VISIBLE of the column (e.g. asymmetry at one |rate|, aging or
  a dT/dt term on steady ramps alone): it is then not scored, and says so.
- A node-like candidate (a dT/dt term, an extra lag) must also beat the base with a third
  node of the base's own kind on held-out blocks (p < ALPHA): the base's two nodes stand
  for the FOG's several, and on long logs any added node lowers the residual a little.
- The three candidates that can each take a slow misfit of the base's node count (a dT/dt
  term, an extra lag, aging: catalogue.THIRD_NODE_CHECK) must reach p < ALPHA / k, k the
  identifiable ones among them (Bonferroni within that family,
  selection.slow_misfit_family).
- A warmup (start-up transient) is scored only when a run starts at power-on.
- Profiled parameters: the interval is where the profiled SSE stays within 3.84 units
  (reduced chi-square times the residual's long-run variance ratio) of its minimum, on the
  base and on a base with a third node (the union). A candidate marked `average` (temp_rate,
  whose coil time constant is often unpinned) reports its coefficient and parameter as
  profile-likelihood averages, with the best fit alongside.
- Nested candidates (an extra slow lag contains a dT/dt term's signature once the slow
  node is slow enough): the simpler is preferred unless the larger beats it on held-out
  blocks (p < AMBIGUOUS_P) and the logs hold a long soak after a ramp
  (selection.nested_choice).
- The best significant candidate is *ambiguous* with another significant one when, pairwise,
  it is not better than it on held-out blocks (p >= AMBIGUOUS_P): no cause is named.
- *Structure remains* when the chosen model's held-out residual (the best candidate's, else
  the base's) has a (trimmed) variance above STRUCTURE_EXCESS times the noise floor's, or is
  grossly non-white (Ljung-Box p < STRUCTURE_P; held-out residuals of one block share one
  fold's fit, so they are mildly correlated by construction and a plain 1e-3 cut would
  flag correct models of strong effects): `unexplained` is then true, and no cause is named
  with confidence (a partial fit is reported in the candidate's evidence).
"""
from __future__ import annotations

import numpy as np

from fogsf.diagnose import crossval, design, driver, profile_ls, runs, selection, stats
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects import catalogue
from fogsf.diagnose.fits import (
    CandidateResult,
    Diagnosis,
    block_sums,
    fit_model,
    weighted_rms,
)
from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog

STRUCTURE_P = 1e-8
STRUCTURE_EXCESS = 2.5  # held-out trimmed mean (e/sigma)^2 above which structure remains
TRIM = 0.95
MODEL_FLOOR_FRAC = 0.02  # see model_floor (benchmarks/probes/README.md, "Diagnose thresholds")
WHITE_EXCESS = 1.5  # non-whiteness counts as structure only above this excess variance
# ... for naming causes. Reported as unexplained structure, whatever its variance, is a
# held-out residual that is not white: Ljung-Box p below WHITE_P with a structured share
# (stats.structured_share) of at least WHITE_SHARE; calibrated on development gyros so that
# a correct model's residual does not trip it (docs/diagnose.md, "Unexplained structure")
WHITE_P = 1e-6
WHITE_SHARE = 0.1
# ... and that structure at least this mean square in noise variances (the noise including
# the base's resolution, model_floor): structure finer than the base resolves is not
# reported (benchmarks/probes/README.md, "Diagnose whiteness threshold")
WHITE_MIN_VARIANCE = 0.1
DOMINANT_SHARE = 0.8  # a cause is named with structure remaining if it explains this much
# effects tied to no logged quantity or event (aging: elapsed time only; warmup is tied to
# the power-on the board shows): named as the dominant cause only when what remains after
# them is not gross (held-out variance at most STRUCTURE_EXCESS times the noise)
UNPINNED = ("aging",)
MIXED_GYRO_RATIO = 3.0  # joint-fit RMS over the worst single-log fit's, in noise units
MIXED_GYRO_MIN_CHI2 = 10.0


def _one_gyro(ctxs: list[RunContext], y: np.ndarray, sigma_win: np.ndarray,
              names: list[str]) -> None:
    """Refuse logs that one gyro's base model cannot share: the base fitted to all logs at
    once leaves a weighted RMS (noise units) above MIXED_GYRO_RATIO times the worst fit of
    any log on its own, and above sqrt(MIXED_GYRO_MIN_CHI2), and so does the base with any
    one of the catalogue's effects (`names`). Two gyros differ by tens to hundreds of ppm in
    their SF law; one gyro's logs agree to a few ppm, unless an effect that each log's own
    base absorbs shows only across them (a bias on a slow coil over an up and a down log)."""
    if len(ctxs) < 2:
        return
    w = 1.0 / sigma_win**2

    def rms(sub: list[RunContext], yy: np.ndarray, ww: np.ndarray,
            cand: catalogue.Candidate | None = None) -> float:
        st = profile_ls.build(sub, cand)
        fit = profile_ls.solve(st, yy, ww, np.arange(yy.shape[0]))
        return float(np.sqrt(np.mean((yy - profile_ls.predict(st, fit)) ** 2 * ww)))

    def mixed(joint: float) -> bool:
        return joint > MIXED_GYRO_RATIO * single and joint**2 > MIXED_GYRO_MIN_CHI2

    joint = rms(ctxs, y, w)
    edges = np.cumsum([0] + [len(c.run) for c in ctxs])
    single = max(rms([c], y[a:b], w[a:b])
                 for c, a, b in zip(ctxs, edges[:-1], edges[1:], strict=True))
    for name in names if mixed(joint) else []:
        try:
            if not mixed(rms(ctxs, y, w, catalogue.CATALOGUE[name])):
                return  # one effect of the catalogue makes the logs one gyro's
        except UserError:
            continue
    if mixed(joint):
        raise UserError(f"the logs do not look like one gyro: one base model fitted to all "
                        f"leaves {joint:.1f}x the noise, each log alone at most {single:.1f}x; "
                        "diagnose one gyro's logs at a time (give only that gyro's LOG.CSV "
                        "files)")


def model_floor(ctxs: list[RunContext], y: np.ndarray, sigma_win: np.ndarray) -> float:
    """The base model's resolution (ppm): MODEL_FLOOR_FRAC of the RMS of its fitted thermal
    SF. The base (two nodes, quadratic laws) approximates a gyro with several nodes and
    cubic laws to a fraction of its thermal swing; at a high |table rate| the window noise
    (about 1/|rate|) falls below that, and the approximation would read as structure. It is
    added in quadrature to every window's noise."""
    st = profile_ls.build(ctxs, None)
    fit = profile_ls.solve(st, y, 1.0 / sigma_win**2, np.arange(y.shape[0]))
    pred = profile_ls.predict(st, fit)
    return MODEL_FLOOR_FRAC * float(np.std(pred))


def _structure_remains(st: dict[str, float]) -> bool:
    """Structure large enough to weigh on the causes (their dominance, below)."""
    return bool(st["excess_variance"] > STRUCTURE_EXCESS
                or (st["whiteness_p"] < STRUCTURE_P and st["excess_variance"] > WHITE_EXCESS))


def _not_white(st: dict[str, float]) -> bool:
    """Structure reported whatever its variance: the held-out residual is not white."""
    return bool(st["whiteness_p"] < WHITE_P and st["structured_share"] >= WHITE_SHARE
                and st["structure_variance"] >= WHITE_MIN_VARIANCE)


def _remaining_share(base_st: dict[str, float], st: dict[str, float]) -> float:
    """Share of the base's excess held-out variance (above the noise) left after a model."""
    e0 = base_st["excess_variance"] - 1.0
    if e0 <= 0.0:
        return 0.0
    return float(np.clip((st["excess_variance"] - 1.0) / e0, 0.0, 1.0))


def correlations(d_ctxs: list[RunContext], e: np.ndarray) -> dict[str, dict[str, float]]:
    """Correlation of a residual with the quantities an effect would follow: Pearson r (zero
    by construction for the base's own regressors) and the correlation ratio eta^2 over
    quantile bins (any smooth dependence), each with a p-value on the effective size."""
    feats: dict[str, list[np.ndarray]] = {k: [] for k in (
        "temperature_c", "dtemp_dt_c_per_min", "time_since_power_on_s", "elapsed_s",
        "table_rate_dps", "abs_rate_dps", "sign_rate")}
    for ctx in d_ctxs:
        r = ctx.run
        feats["temperature_c"].append(design.board(ctx) + design.T_REF_C)
        feats["dtemp_dt_c_per_min"].append(design.board_rate_c_per_min(ctx))
        feats["time_since_power_on_s"].append(r.t_s)
        feats["elapsed_s"].append(r.t_s - float(r.log.time_s[0]))
        feats["table_rate_dps"].append(r.rate)
        feats["abs_rate_dps"].append(np.abs(r.rate))
        feats["sign_rate"].append(np.sign(r.rate))
    arrays = {k: np.concatenate(v) for k, v in feats.items()}
    if np.unique(arrays["sign_rate"]).shape[0] > 1:  # what a bias following T looks like
        arrays["temperature_x_sign_rate"] = arrays["temperature_c"] * arrays["sign_rate"]
    out = {}
    for k, x in arrays.items():
        rr, p = stats.correlation(e, x)
        eta2, p_eta = stats.correlation_ratio(e, x)
        out[k] = {"r": rr, "p": p, "eta2": eta2, "eta_p": p_eta}
    return out


def _structure(d_e: np.ndarray, sigma: np.ndarray, run_ids: np.ndarray) -> dict[str, float]:
    """Whiteness and excess variance of a held-out residual, and how large its structure
    is: the variance is a 95 %-trimmed mean of (e/sigma)^2 over its expectation for pure
    noise, so one badly extrapolated block is not taken for structure; the structured share
    is the share of its (standardised) mean square that is slow structure, the structure
    variance that structure's mean square in noise variances, and the smoothed RMS its size
    in ppm (stats.structure_ms)."""
    z2 = np.sort((d_e / sigma) ** 2)
    keep = z2[: max(1, int(np.ceil(TRIM * z2.shape[0])))]
    ids = np.unique(run_ids)
    segs = [d_e[run_ids == i] / sigma[run_ids == i] for i in ids]
    return {"whiteness_p": stats.ljung_box_p(segs),
            "excess_variance": float(np.mean(keep)) / stats.trimmed_chi2_1_mean(TRIM),
            "structured_share": stats.structured_share(segs),
            "structure_variance": stats.structure_ms(segs)[0],
            "smoothed_rms_ppm": stats.smoothed_rms([d_e[run_ids == i] for i in ids])}


def diagnose(logs: list[ChamberLog], window_s: float = 60.0, latitude_deg: float | None = None,
             cv: str = "blocks", start: str = "auto", effects: list[str] | None = None,
             progress: bool = False) -> Diagnosis:
    if not logs:
        raise UserError("give at least one chamber log")
    rs = [runs.load_run(log, window_s, latitude_deg) for log in logs]
    rates = np.unique(np.round(np.concatenate([r.rate for r in rs]), 6))
    bias_on = rates.shape[0] > 1
    ctxs = []
    for r in rs:
        drv = driver.identify(r.log.time_s, r.log.temp_c, r.log.extra.get("chamber_c"), start)
        ctxs.append(RunContext(r, drv, drv.power_on, bias_on))
    y = np.concatenate([r.y_ppm for r in rs])
    sigma_win = np.concatenate([r.sigma_ppm for r in rs])
    names = list(catalogue.CATALOGUE) if effects is None else effects
    unknown = [n for n in names if n not in catalogue.CATALOGUE]
    if unknown:
        raise UserError(f"unknown effect(s) {', '.join(unknown)}; known: "
                        f"{', '.join(catalogue.CATALOGUE)}")
    _one_gyro(ctxs, y, sigma_win, names)
    floor = model_floor(ctxs, y, sigma_win)
    sigma = np.sqrt(sigma_win**2 + floor**2)
    w = 1.0 / sigma**2
    run_ids = np.concatenate([np.full(len(r), i) for i, r in enumerate(rs)])
    blocks = crossval.block_ids([len(r) for r in rs])
    folds = crossval.fold_ids(blocks, run_ids, cv)

    base = fit_model(ctxs, None, y, w, folds)
    e_in = y - base.pred
    segs_in = [e_in[run_ids == i] for i in range(len(rs))]
    base_rms = weighted_rms(e_in)
    before = weighted_rms(base.heldout)
    results: list[CandidateResult] = []
    it = names
    if progress:
        from tqdm import tqdm
        it = tqdm(names, desc="candidates", unit="effect", leave=False)
    skipped: list[dict[str, str]] = []
    for name in it:
        try:
            results.append(selection.score(catalogue.CATALOGUE[name], ctxs, y, w, folds,
                                           blocks, run_ids, base, before))
        except UserError as e:  # a form that cannot apply to these logs: skipped, named
            skipped.append({"effect": name, "stage": "scoring", "reason": str(e)})
            results.append(CandidateResult(name, False, 0.0, heldout_before=before,
                                           heldout_after=before,
                                           evidence=f"skipped: {e}"))

    selection.slow_misfit_family(results)
    selection.against_extra_node(results, ctxs, y, w, folds, blocks)
    sig = sorted([c for c in results if c.significant], key=lambda c: c.heldout_after)
    soak_s = max(selection.longest_soak_after_ramp(c) for c in ctxs)
    sig, ambiguous = selection.nested_choice(sig, w, blocks, soak_s)
    chosen = base
    causes: list[CandidateResult] = []
    if ambiguous:
        chosen = sig[0].model or base
        for c in (c for c in results if c.name in ambiguous):
            c.confounded_with = [o for o in ambiguous if o != c.name]
            c.separating_run = selection.SEPARATES.get(frozenset(ambiguous[:2]),
                                                       selection.SEPARATES_DEFAULT)
            c.evidence += f"; the run that would separate them: {c.separating_run}"
    elif sig:
        best = sig[0]
        assert best.model is not None
        chosen = best.model
        for other in sig[1:]:
            assert other.model is not None
            d = block_sums((other.model.heldout**2 - best.model.heldout**2) * w, blocks)
            p = stats.sign_flip_p(d)
            if p >= selection.AMBIGUOUS_P and not selection.adds_to(ctxs, best, other, y, w,
                                                                    folds, blocks):
                ambiguous.append(other.name)
                other.evidence += (f"; not separable from {best.name} on held-out blocks "
                                   f"(p={p:.2g})")
        if ambiguous:
            ambiguous.insert(0, best.name)
            runs_needed = "; ".join(dict.fromkeys(
                selection.SEPARATES.get(frozenset((best.name, o)), selection.SEPARATES_DEFAULT)
                for o in ambiguous[1:]))
            best.evidence += ("; confounded with " + ", ".join(ambiguous[1:]) +
                              ": these logs cannot tell them apart; the run that would "
                              f"separate them: {runs_needed}")
            for o in (c for c in results if c.name in ambiguous[1:]):
                o.confounded_with = [best.name]
                o.separating_run = selection.SEPARATES.get(frozenset((best.name, o.name)),
                                                           selection.SEPARATES_DEFAULT)
            best.confounded_with = ambiguous[1:]
            best.separating_run = runs_needed
        else:
            pool = [c for c in results if c is not best and c.identifiable and c.model
                    is not None and (c.significant or c.name not in catalogue.NODE_LIKE)
                    and c.name not in ambiguous
                    and c.name not in selection.nested_partners(best.name)]
            causes, chosen = selection.forward_select(best, pool, ctxs, y, w, folds, blocks)
    structure = _structure(chosen.heldout, sigma, run_ids)
    base_structure = _structure(base.heldout, sigma, run_ids)
    unexplained = _structure_remains(structure)
    not_white = _not_white(structure)
    remains = _remaining_share(base_structure, structure)
    structure["remaining_pct"] = 100.0 * remains
    flagged_by = (["variance"] if unexplained else []) + (["whiteness"] if not_white else [])
    if unexplained and causes:
        best = causes[0]
        if best.name in UNPINNED and structure["excess_variance"] > STRUCTURE_EXCESS:
            best.evidence += (f"; {100 * remains:.0f}% of the structure remains after "
                              f"{' + '.join(c.name for c in causes)}, with a held-out "
                              f"variance {structure['excess_variance']:.2f}x the noise: an "
                              "unlogged slow process is present, and a drift tied to no "
                              "logged quantity cannot be told from its slow part: not named")
            causes = []
            chosen = base
        elif remains <= 1.0 - DOMINANT_SHARE:
            best.evidence += (f"; {100 * remains:.0f}% of the structure remains after "
                              f"{' + '.join(c.name for c in causes)} (held-out whiteness "
                              f"p={structure['whiteness_p']:.2g}, variance "
                              f"{structure['excess_variance']:.2f}x the noise): unexplained "
                              "beyond it")
        else:
            best.evidence += ("; but most of the structure remains after it "
                              f"({100 * remains:.0f}% of the base's excess variance; "
                              f"whiteness p={structure['whiteness_p']:.2g}, variance "
                              f"{structure['excess_variance']:.2f}x the noise): not dominant, "
                              "not named")
            causes = []
            chosen = base
    elif not_white and causes:
        causes[0].evidence += (
            f"; the held-out residual after {' + '.join(c.name for c in causes)} is not "
            f"white (p={structure['whiteness_p']:.2g}; structure "
            f"{100 * structure['structured_share']:.0f}% of its variance, "
            f"{structure['smoothed_rms_ppm']:.2f} ppm RMS): unexplained structure beside it")
    cause = causes[0].name if causes else None
    extended = chosen if cause is not None else base
    return Diagnosis(causes=[c.name for c in causes], model_floor_ppm=floor,
        window_noise_ppm=float(np.sqrt(np.mean(sigma_win**2))),
        runs=rs, ctxs=ctxs, y=y, sigma=sigma, run_ids=run_ids, blocks=blocks, folds=folds,
        base=base, base_rms=base_rms, base_whiteness_p=stats.ljung_box_p(segs_in),
        correlations=correlations(ctxs, e_in), candidates=results, cause=cause,
        ambiguous=ambiguous, unexplained=bool(flagged_by),
        structure={**structure, "flagged_by": flagged_by},
        extended=extended,
        cv_mode=cv, window_s=window_s, skipped=skipped)
