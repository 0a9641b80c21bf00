"""Fit the base model, score every catalogue effect on held-out data, name the cause.

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
  identifiable ones among them (Bonferroni within that family, _slow_misfit_family).
- A warmup (start-up transient) is scored only when a run starts at power-on.
- Profiled parameters: the interval is where the profiled SSE stays within 3.84 units
  (reduced chi-square times the residual's long-run variance ratio) of its minimum, on the
  base and on a base with a third node (the union). A candidate marked `average` (temp_rate,
  whose coil time constant is often unpinned) reports its coefficient and parameter as
  profile-likelihood averages, with the best fit alongside.
- Nested candidates (an extra slow lag contains a dT/dt term's signature once the slow
  node is slow enough): the simpler is preferred unless the larger beats it on held-out
  blocks (p < AMBIGUOUS_P) and the logs hold a long soak after a ramp (_nested_choice).
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

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from fogsf.trainer.diagnose import catalogue, crossval, design, driver, profile_ls, runs, stats
from fogsf.trainer.diagnose.catalogue import Candidate, GridValue, first
from fogsf.trainer.diagnose.design import RunContext
from fogsf.trainer.diagnose.profile_ls import Stack
from fogsf.trainer.errors import UserError
from fogsf.trainer.logs.logio import ChamberLog

ALPHA = 0.01
MIN_GAIN_PCT = 5.0
MIN_VISIBLE = 1e-3  # below: the column is (numerically) inside the base model
AMBIGUOUS_P = 0.05
STRUCTURE_P = 1e-8
STRUCTURE_EXCESS = 2.5  # held-out trimmed mean (e/sigma)^2 above which structure remains
# extra_lag with a very slow node tends to "housing term + slow drift", which contains
# temp_rate's signature ("housing term", the coil node being in the base already)
NESTED = {"extra_lag": "temp_rate"}
NESTED_MIN_GAIN_PCT = 2.0
MIN_SOAK_FOR_LAG_S = 2700.0  # 45 min of soak, as found (the 5 min after a ramp stops excluded)
SOAK_RATE_C_PER_MIN = 0.02  # slower than this (driver, 5-min average) is a soak
RAMP_MIN_C = 5.0  # a soak counts when the driver moved at least this much before it
Z95 = 1.959964
TRIM = 0.95
MODEL_FLOOR_FRAC = 0.02  # see model_floor (dev gyros 0-39, mixed-rate nulls)
MIN_DZ2 = 0.05  # held-out gain rule: mean drop of (e/sigma)^2 per window, in noise variances
WHITE_EXCESS = 1.5  # non-whiteness counts as structure only above this excess variance
DOMINANT_SHARE = 0.8  # a cause is named with structure remaining if it explains this much
MAX_CAUSES = 3
# effects tied to no logged quantity or event (aging: elapsed time only; warmup is tied to
# the power-on the board shows): named as the dominant cause only when what remains after
# them is not gross (held-out variance at most STRUCTURE_EXCESS times the noise)
UNPINNED = ("aging",)
# the run that would separate a candidate from the base model when it is not identifiable
SEPARATING_RUN = {
    "rate_nonlinearity": "a second |table rate| (three or more to tell linear from quadratic)",
    "asymmetry": "a second |table rate|, each with both signs",
    "bias_drift": "a second |table rate| or both signs of the rate",
    "aging": "a soak of at least 3 h at constant temperature, or the first temperature "
             "repeated at the log's end",
    "temp_rate": "a temperature step followed by a soak of at least 45 min",
    "extra_lag": "a soak of at least 45 min after a ramp of 5 C or more",
    "warmup": "a log that starts at power-on (or --start power-on if it does)",
}
# ... and from another candidate
SEPARATES = {
    frozenset(("temp_rate", "extra_lag")): "a soak of at least 45 min after a ramp of 5 C "
                                           "or more",
    frozenset(("warmup", "aging")): "a soak of at least 3 h at constant temperature",
    frozenset(("asymmetry", "bias_drift")): "a second |table rate|, each with both signs",
    frozenset(("rate_nonlinearity", "bias_drift")): "a third |table rate|",
    frozenset(("aging", "extra_lag")): "a soak of at least 3 h at constant temperature",
}
SEPARATES_DEFAULT = ("a longer log with soaks at two temperatures, a power-on start and a "
                     "second |table rate|")
BATCH_WINDOWS = 10  # batch means for the residual's long-run variance (sse_scale)


@dataclass
class ModelFit:
    """One model (base, or base + a candidate) fitted on all windows."""

    stack: Stack
    fit: profile_ls.Fit
    pred: np.ndarray  # in-sample prediction per window
    heldout: np.ndarray  # held-out residual per window
    chi2_red: float  # in-sample weighted SSE / dof

    @property
    def combo(self) -> profile_ls.Combo:
        return self.stack.combos[self.fit.index]

    def coef(self, name: str) -> float:
        return float(self.fit.beta[self.stack.names.index(name)])

    def coef_se(self, name: str) -> float:
        i = self.stack.names.index(name)
        return float(math.sqrt(max(self.fit.cov[i, i], 0.0) * max(1.0, self.chi2_red)))


@dataclass
class CandidateResult:
    name: str
    identifiable: bool
    visible: float  # fraction of the candidate's column the base cannot absorb
    params: dict[str, object] = field(default_factory=dict)
    heldout_before: float = float("nan")
    heldout_after: float = float("nan")
    gain_pct: float = 0.0
    p_value: float = 1.0
    blocks_better: int = 0
    blocks: int = 0
    significant: bool = False
    evidence: str = ""
    model: ModelFit | None = None
    effect: dict | None = None  # simulator effect entry
    confounded_with: list[str] = field(default_factory=list)  # "base" or candidate names
    separating_run: str = ""  # the run that would separate it from them
    added_gain_pct: float = 0.0  # forward selection: held-out gain over the causes before it


@dataclass
class Diagnosis:
    runs: list[runs.Run]
    ctxs: list[RunContext]
    y: np.ndarray
    sigma: np.ndarray
    run_ids: np.ndarray
    blocks: np.ndarray
    folds: np.ndarray
    base: ModelFit
    base_rms: float
    base_whiteness_p: float
    correlations: dict[str, dict[str, float]]
    candidates: list[CandidateResult]
    cause: str | None
    ambiguous: list[str]
    unexplained: bool
    structure: dict[str, float]
    extended: ModelFit  # base + cause (the base when there is no cause)
    cv_mode: str
    window_s: float
    causes: list[str] = field(default_factory=list)  # forward selection, `cause` first
    model_floor_ppm: float = 0.0

    @property
    def noise_floor_ppm(self) -> float:
        return float(np.sqrt(np.mean(self.sigma**2)))


MIXED_GYRO_RATIO = 3.0  # joint-fit RMS over the worst single-log fit's, in noise units
MIXED_GYRO_MIN_CHI2 = 10.0


def _one_gyro(ctxs: list[RunContext], y: np.ndarray, sigma_win: np.ndarray) -> None:
    """Refuse logs that one gyro's base model cannot share: the base fitted to all logs at
    once leaves a weighted RMS (noise units) above MIXED_GYRO_RATIO times the worst fit of
    any log on its own, and above sqrt(MIXED_GYRO_MIN_CHI2). Two gyros differ by tens to
    hundreds of ppm in their SF law; one gyro's logs agree to a few ppm."""
    if len(ctxs) < 2:
        return
    w = 1.0 / sigma_win**2

    def rms(sub: list[RunContext], yy: np.ndarray, ww: np.ndarray) -> float:
        st = profile_ls.build(sub, None)
        fit = profile_ls.solve(st, yy, ww, np.arange(yy.shape[0]))
        return float(np.sqrt(np.mean((yy - profile_ls.predict(st, fit)) ** 2 * ww)))

    joint = rms(ctxs, y, w)
    edges = np.cumsum([0] + [len(c.run) for c in ctxs])
    single = max(rms([c], y[a:b], w[a:b])
                 for c, a, b in zip(ctxs, edges[:-1], edges[1:], strict=True))
    if joint > MIXED_GYRO_RATIO * single and joint**2 > MIXED_GYRO_MIN_CHI2:
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


def _significant(p: float, d: np.ndarray, n: int) -> bool:
    """The held-out gain rule: better on held-out blocks (paired sign-flip p < ALPHA) and the
    held-out weighted SSE lower by at least MIN_DZ2 noise variances per window on average.
    It scales with the noise: a gain of a few % of RMS counts when the residual is near the
    noise, and a big residual needs a gain that is big in noise units."""
    return p < ALPHA and float(np.sum(d)) / max(n, 1) >= MIN_DZ2


def _structure_remains(st: dict[str, float]) -> bool:
    return bool(st["excess_variance"] > STRUCTURE_EXCESS
                or (st["whiteness_p"] < STRUCTURE_P and st["excess_variance"] > WHITE_EXCESS))


def _remaining_share(base_st: dict[str, float], st: dict[str, float]) -> float:
    """Share of the base's excess held-out variance (above the noise) left after a model."""
    e0 = base_st["excess_variance"] - 1.0
    if e0 <= 0.0:
        return 0.0
    return float(np.clip((st["excess_variance"] - 1.0) / e0, 0.0, 1.0))


def _adds_to(ctxs: list[RunContext], best: CandidateResult, other: CandidateResult,
             y: np.ndarray, w: np.ndarray, folds: np.ndarray, blocks: np.ndarray) -> bool:
    """Does `other` on top of `best` beat `best` alone on held-out blocks? (then the two are
    two effects, not one effect two ways)."""
    assert best.model is not None
    try:
        comb = catalogue.combine([(catalogue.CATALOGUE[best.name], best.model.combo[1])],
                                 catalogue.CATALOGUE[other.name])
    except ValueError:
        return False
    m = fit_model(ctxs, comb, y, w, folds)
    d = _block_sums((best.model.heldout**2 - m.heldout**2) * w, blocks)
    return _significant(stats.sign_flip_p(d), d, y.shape[0])


def _beats_third_node(ctxs: list[RunContext], chosen: list[tuple[Candidate, GridValue]],
                      m: ModelFit, y: np.ndarray, w: np.ndarray, folds: np.ndarray,
                      blocks: np.ndarray) -> bool:
    """Does `m` beat the causes so far plus a third base node, on held-out blocks?"""
    ref = fit_model(ctxs, catalogue.combine(chosen, catalogue.EXTRA_NODE), y, w, folds)
    d = _block_sums((ref.heldout**2 - m.heldout**2) * w, blocks)
    return stats.sign_flip_p(d) < ALPHA


def _forward_select(first_c: CandidateResult, pool: list[CandidateResult],
                    ctxs: list[RunContext], y: np.ndarray, w: np.ndarray, folds: np.ndarray,
                    blocks: np.ndarray) -> tuple[list[CandidateResult], ModelFit]:
    """The causes in the order found: the best significant candidate, then each further one
    of `pool` (identifiable candidates; a second effect can be hidden behind the first when
    each is scored on the base alone) only when, added to the model with the ones before it
    (held at their chosen forms and time constants, its own profiled), it wins on held-out
    blocks by the gain rule
    (_significant). The combined model's coefficients replace the single fits'."""
    assert first_c.model is not None
    causes = [first_c]
    model = first_c.model
    chosen = [(catalogue.CATALOGUE[first_c.name], first_c.model.combo[1])]
    rest = list(pool)
    while rest and len(causes) < MAX_CAUSES:
        best: tuple[CandidateResult, ModelFit, float] | None = None
        for r in rest:
            comb = catalogue.combine(chosen, catalogue.CATALOGUE[r.name])
            m = fit_model(ctxs, comb, y, w, folds)
            d = _block_sums((model.heldout**2 - m.heldout**2) * w, blocks)
            p = stats.sign_flip_p(d)
            if _significant(p, d, y.shape[0]) and (
                    best is None or _weighted_rms(m.heldout) < _weighted_rms(best[1].heldout)
            ) and (r.name not in catalogue.THIRD_NODE_CHECK
                   or _beats_third_node(ctxs, chosen, m, y, w, folds, blocks)):
                best = (r, m, p)
        if best is None:
            break
        r, m, p = best
        before, after = _weighted_rms(model.heldout), _weighted_rms(m.heldout)
        r.added_gain_pct = 100.0 * (1.0 - after / before) if before > 0 else 0.0
        if r.evidence.startswith("not significant:"):
            r.evidence = "on the base alone not significant:" + r.evidence[16:]
        r.evidence += (f"; added after {' + '.join(c.name for c in causes)}: held-out RMS "
                       f"{before:.2f} -> {after:.2f} ppm (p={p:.2g}): a cause")
        r.significant = True
        causes.append(r)
        chosen.append((catalogue.CATALOGUE[r.name], m.combo[1]))
        rest.remove(r)
        model = m
    if len(causes) > 1:
        assert model.stack.candidate is not None
        for c, name in zip(causes, model.stack.candidate.names(), strict=True):
            cand = catalogue.CATALOGUE[c.name]
            coef, se = model.coef(name), model.coef_se(name)
            c.params[cand.coef_name] = coef
            c.params[f"{cand.coef_name}_ci95"] = [coef - Z95 * se, coef + Z95 * se]
            c.evidence += (f"; with the other causes: {cand.coef_name} = {coef:.4g}")
    return causes, model


def _weighted_rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e * e)))


def fit_model(ctxs: list[RunContext], cand: Candidate | None, y: np.ndarray, w: np.ndarray,
              folds: np.ndarray, combos: list[profile_ls.Combo] | None = None) -> ModelFit:
    stack = profile_ls.build(ctxs, cand, combos)
    rows = np.arange(y.shape[0])
    fit = profile_ls.solve(stack, y, w, rows)
    pred = profile_ls.predict(stack, fit)
    dof = max(1, y.shape[0] - stack.x.shape[2])
    chi2 = float(np.sum((y - pred) ** 2 * w)) / dof
    held = crossval.heldout_residuals(stack, y, w, folds)
    return ModelFit(stack, fit, pred, held, chi2)


def visible_fraction(model: ModelFit, w: np.ndarray) -> float:
    """Share (RMS) of the candidate column not reproducible by the base columns."""
    x = model.stack.x[model.fit.index]
    col = x[:, -1]
    base = x[:, :-1]
    sw = np.sqrt(w)
    c = col * sw
    if not np.any(col != col[0]):
        return 0.0
    coef, *_ = np.linalg.lstsq(base * sw[:, None], c, rcond=None)
    r = c - (base * sw[:, None]) @ coef
    cm = c - sw * np.sum(col * w) / np.sum(w)
    return float(np.linalg.norm(r) / max(np.linalg.norm(cm), 1e-300))


def _keys(model: ModelFit) -> list[GridValue]:
    return [c[1] for c in model.stack.combos]


def _profile(model: ModelFit) -> dict[GridValue, float]:
    """Profiled weighted SSE per value of the candidate's grid parameter (each at its best
    base time constants)."""
    out: dict[GridValue, float] = {}
    for k, e in zip(_keys(model), model.fit.sse, strict=True):
        out[k] = min(float(e), out.get(k, np.inf))
    return out


def _line(g: GridValue) -> tuple:
    """The further profiled parameters of a grid value (a line of the grid along the first)."""
    return tuple(g[1:]) if isinstance(g, tuple) else ()


def _with_first(g: GridValue, v: float) -> GridValue:
    return (v, *g[1:]) if isinstance(g, tuple) else v


def sse_scale(model: ModelFit, y: np.ndarray, w: np.ndarray, run_ids: np.ndarray) -> float:
    """What one unit of chi-square is worth in the weighted SSE: the reduced chi-square
    times the residual's long-run variance ratio (batch means over BATCH_WINDOWS windows,
    per run). 60 s windows of a fitted residual are correlated, so a change of the SSE of
    3.84 is not yet 95 % evidence against a time constant: the interval would be too short."""
    z = (y - model.pred) * np.sqrt(w)
    num = den = 0.0
    for i in np.unique(run_ids):
        zi = z[run_ids == i]
        k = zi.shape[0] // BATCH_WINDOWS
        if k < 2:
            continue
        b = zi[: k * BATCH_WINDOWS].reshape(k, BATCH_WINDOWS).sum(axis=1)
        num += float(np.sum(b * b)) / BATCH_WINDOWS
        den += float(np.sum(zi[: k * BATCH_WINDOWS] ** 2))
    ratio = num / den if den > 0 else 1.0
    return max(1.0, model.chi2_red) * max(1.0, ratio)


def _profile_interval(coarse: ModelFit, fine: ModelFit, scale: float
                      ) -> tuple[tuple[float, float], list[GridValue]]:
    """Interval of the candidate's (first) grid parameter where the profiled weighted SSE
    stays within chi2(1, 95%) = 3.84 units (`scale`, see sse_scale) of its minimum, and the
    accepted grid values. Values of the coarse grid and of its refinements are accepted
    alike; the bounds are the coarse grid values next beyond the accepted ones (grid
    resolution: the refinements hold the base time constants fixed, so their SSE only bounds
    the profile from above and cannot reject a value)."""
    prof = _profile(coarse)
    for v, e in _profile(fine).items():
        prof[v] = min(e, prof.get(v, np.inf))
    best = min(prof.values())
    acc = [v for v, e in prof.items() if e <= best + 3.84 * scale]
    fa = [first(v) for v in acc]
    grid = np.array(sorted({first(v) for v in _profile(coarse)}))
    below = grid[grid < min(fa)]
    above = grid[grid > max(fa)]
    lo = float(below[-1]) if below.shape[0] else float(min(grid[0], min(fa)))
    hi = float(above[0]) if above.shape[0] else float(max(grid[-1], max(fa)))
    return (lo, hi), acc


def _interval_with_extra_node(ctxs: list[RunContext], cand: Candidate, y: np.ndarray,
                              w: np.ndarray, scale: float) -> tuple[float, float]:
    """The profile interval of the candidate's (first) grid parameter on a base with a third
    node (catalogue.with_extra_node; coarse grid, all windows, same chi-square rule). The
    base's two nodes stand for the FOG's several, and a slow parameter such as an extra
    lag's time constant can take up what a missing node leaves: its profile on two nodes
    alone is sharp around a shifted minimum. The reported interval is the union of the two,
    so it holds whichever base the logs need."""
    st = profile_ls.build(ctxs, catalogue.with_extra_node(cand))
    fit = profile_ls.solve(st, y, w, np.arange(y.shape[0]))
    prof: dict[float, float] = {}
    for (_, gg), e in zip(st.combos, fit.sse, strict=True):
        prof[first(gg)] = min(float(e), prof.get(first(gg), np.inf))
    best = min(prof.values())
    grid = np.array(sorted(prof))
    acc = grid[np.array([prof[v] <= best + 3.84 * scale for v in grid])]
    below = grid[grid < acc.min()]
    above = grid[grid > acc.max()]
    return (float(below[-1]) if below.shape[0] else float(acc.min()),
            float(above[0]) if above.shape[0] else float(acc.max()))


def _refine(ctxs: list[RunContext], cand: Candidate, model: ModelFit, y: np.ndarray,
            w: np.ndarray, folds: np.ndarray) -> ModelFit:
    """Refit on a finer grid of the candidate's (first) parameter around every local minimum
    of the coarse profile along it, each with the base time constants (and any further
    profiled parameter) held at that minimum's best. The profile can have more than one
    minimum (e.g. an extra slow node that settles in the logs, and a much slower one that
    the base's nodes turn into a drift); refining only the coarse best could miss a deeper
    minimum between two coarse grid values, and the interval would then leave it out."""
    st = model.stack
    keys = _keys(model)
    prof = _profile(model)
    grid = np.array(sorted({first(g) for g in cand.grid}))
    combos: list[profile_ls.Combo] = []
    for line in dict.fromkeys(_line(v) for v in prof):
        vals = sorted((v for v in prof if _line(v) == line), key=first)
        sse = np.array([prof[v] for v in vals])
        for i, v in enumerate(vals):
            if (i > 0 and sse[i - 1] < sse[i]) or (i + 1 < len(vals) and sse[i + 1] < sse[i]):
                continue  # not a local minimum
            k = [j for j, key in enumerate(keys) if key == v]
            bt = st.combos[k[int(np.argmin(model.fit.sse[k]))]][0]
            j = int(np.argmin(np.abs(grid - first(v))))
            lo = grid[max(j - 1, 0)]
            hi = grid[min(j + 1, grid.shape[0] - 1)]
            fine = np.unique(np.round(np.geomspace(lo, hi, 9), 1))
            combos += [(bt, _with_first(v, float(f))) for f in fine
                       if cand.admissible(bt, _with_first(v, float(f)))]
    combos = list(dict.fromkeys(combos))
    if not combos:
        return model
    return fit_model(ctxs, cand, y, w, folds, combos)


def _block_sums(v: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    return np.bincount(blocks, weights=v)


def _fits_per_value(model: ModelFit, y: np.ndarray, w: np.ndarray
                    ) -> dict[GridValue, profile_ls.Fit]:
    """The best fit (over the base time constants) at each value of the grid parameter."""
    st = model.stack
    keys = _keys(model)
    rows = np.arange(y.shape[0])
    out = {}
    for v in dict.fromkeys(keys):
        sel = np.array([k == v for k in keys])
        sub = profile_ls.Stack([c for c, k in zip(st.combos, sel, strict=True) if k],
                               st.x[sel], st.names, st.candidate)
        out[v] = profile_ls.solve(sub, y, w, rows)
    return out


def _coef_range_over_profile(model: ModelFit, name: str, y: np.ndarray, w: np.ndarray,
                             interval: tuple[float, float], accepted: list[GridValue],
                             factor: Callable[[GridValue], float] = lambda v: 1.0
                             ) -> tuple[float, float]:
    """The linear coefficient's 95 % range over every grid value of the nonlinear parameter
    inside its profile interval (each at its best base time constants; further profiled
    parameters at accepted values): the coefficient's interval then carries the time
    constant's uncertainty too. `factor(v)` scales the coefficient at grid value v (a
    quantity derived from it, e.g. temp_rate's housing coupling)."""
    lines = {_line(v) for v in accepted}
    lo, hi = np.inf, -np.inf
    i = model.stack.names.index(name)
    for v, fit in _fits_per_value(model, y, w).items():
        if not (interval[0] <= first(v) <= interval[1] and _line(v) in lines):
            continue
        se = math.sqrt(max(fit.cov[i, i], 0.0) * max(1.0, model.chi2_red))
        a, b = ((float(fit.beta[i]) + z * se) * factor(v) for z in (-Z95, Z95))
        lo, hi = min(lo, a, b), max(hi, a, b)
    return lo, hi


def _profile_average(cand: Candidate, coarse: ModelFit, fine: ModelFit, y: np.ndarray,
                     w: np.ndarray, scale: float) -> tuple[float, float]:
    """The coefficient and the (first) grid parameter averaged over the profile likelihood
    exp(-(SSE - min) / (2 scale)), with a log-uniform prior on the parameter (trapezoid
    weights in log along each line of the grid). Where the profile is flat (a weak dT/dt
    term: only strength / coil time constant is pinned, by the housing running ahead of
    the board), the best grid value lands anywhere on the flat part, often at an end of
    the grid; the average does not. Where the profile is sharp, it is the best fit."""
    fits = _fits_per_value(coarse, y, w)
    for v, f in _fits_per_value(fine, y, w).items():
        if v not in fits or f.sse[f.index] < fits[v].sse[fits[v].index]:
            fits[v] = f
    i = coarse.stack.names.index(cand.coef_name)
    best = min(float(f.sse[f.index]) for f in fits.values())
    num_c = num_t = den = 0.0
    for line in dict.fromkeys(_line(v) for v in fits):
        vals = sorted((v for v in fits if _line(v) == line), key=first)
        lt = np.log([first(v) for v in vals])
        if lt.shape[0] > 1:
            dw = np.gradient(lt) * np.where((np.arange(lt.shape[0]) == 0)
                                            | (np.arange(lt.shape[0]) == lt.shape[0] - 1),
                                            0.5, 1.0)
        else:
            dw = np.ones(1)
        for v, lv, d in zip(vals, lt, dw, strict=True):
            f = fits[v]
            pw = d * math.exp(-(float(f.sse[f.index]) - best) / (2.0 * scale))
            num_c += pw * float(f.beta[i])
            num_t += pw * float(lv)
            den += pw
    return num_c / den, math.exp(num_t / den)


def _params(cand: Candidate, model: ModelFit, fine: ModelFit | None,
            prof: tuple[tuple[float, float], list[GridValue]] | None, y: np.ndarray,
            w: np.ndarray, scale: float) -> dict[str, object]:
    m = fine or model
    coef = m.coef(cand.coef_name)
    se = m.coef_se(cand.coef_name)
    ci = [coef - Z95 * se, coef + Z95 * se]
    g = m.combo[1]
    out: dict[str, object] = {}
    if cand.forms and cand.grid_name is not None:
        return {cand.coef_name: coef, f"{cand.coef_name}_ci95": ci,
                cand.grid_name: first(g)}
    if cand.grid_name is not None and g is not None and prof is not None and fine is not None:
        interval, accepted = prof
        lo, hi = _coef_range_over_profile(model, cand.coef_name, y, w, interval, accepted)
        ci = [min(ci[0], lo), max(ci[1], hi)]
        gv = first(g)
        if cand.average:
            out[f"{cand.coef_name}_best_fit"] = coef
            out[f"{cand.grid_name}_best_fit"] = gv
            coef, gv = _profile_average(cand, model, fine, y, w, scale)
            ci = [min(ci[0], coef), max(ci[1], coef)]
        out.update({cand.coef_name: coef, f"{cand.coef_name}_ci95": ci, cand.grid_name: gv,
                    f"{cand.grid_name}_ci95": [min(interval[0], gv), max(interval[1], gv)]})
        if cand.name == "temp_rate":
            out["coil_outer_tau_s_best_fit"] = catalogue.coil_taus(g)[1]
            out.update(_housing_coupling(model, fine, y, w, interval, accepted))
        return out
    return {cand.coef_name: coef, f"{cand.coef_name}_ci95": ci}


def _housing_coupling(coarse: ModelFit, fine: ModelFit, y: np.ndarray, w: np.ndarray,
                      interval: tuple[float, float], accepted: list[GridValue]
                      ) -> dict[str, object]:
    """temp_rate's coupling to the housing (catalogue.housing_coupling), at the best fit and
    its 95 % range over the coil time constants the profile accepts: what the logs pin of
    a dT/dt term (the strength in ppm/(C/min) also needs the coil's time constants)."""
    name = catalogue.CATALOGUE["temp_rate"].coef_name
    best = catalogue.housing_coupling(fine.coef(name), fine.combo[1])
    lo, hi = _coef_range_over_profile(coarse, name, y, w, interval, accepted,
                                      lambda v: catalogue.housing_coupling(1.0, v))
    return {"housing_ppm_per_c": best,
            "housing_ppm_per_c_ci95": [min(lo, best), max(hi, best)]}


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


def _structure(d_e: np.ndarray, sigma: np.ndarray, segs: list[np.ndarray]) -> dict[str, float]:
    """Whiteness and excess variance of a held-out residual; the variance is a 95 %-trimmed
    mean of (e/sigma)^2 over its expectation for pure noise, so one badly extrapolated
    block is not taken for structure."""
    z2 = np.sort((d_e / sigma) ** 2)
    keep = z2[: max(1, int(np.ceil(TRIM * z2.shape[0])))]
    return {"whiteness_p": stats.ljung_box_p(segs),
            "excess_variance": float(np.mean(keep)) / stats.trimmed_chi2_1_mean(TRIM)}


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
    _one_gyro(ctxs, y, sigma_win)
    floor = model_floor(ctxs, y, sigma_win)
    sigma = np.sqrt(sigma_win**2 + floor**2)
    w = 1.0 / sigma**2
    run_ids = np.concatenate([np.full(len(r), i) for i, r in enumerate(rs)])
    blocks = crossval.block_ids([len(r) for r in rs])
    folds = crossval.fold_ids(blocks, run_ids, cv)

    base = fit_model(ctxs, None, y, w, folds)
    e_in = y - base.pred
    segs_in = [e_in[run_ids == i] for i in range(len(rs))]
    base_rms = _weighted_rms(e_in)
    before = _weighted_rms(base.heldout)
    names = list(catalogue.CATALOGUE) if effects is None else effects
    unknown = [n for n in names if n not in catalogue.CATALOGUE]
    if unknown:
        raise UserError(f"unknown effect(s) {', '.join(unknown)}; known: "
                        f"{', '.join(catalogue.CATALOGUE)}")
    results: list[CandidateResult] = []
    it = names
    if progress:
        from tqdm import tqdm
        it = tqdm(names, desc="candidates", unit="effect", leave=False)
    for name in it:
        results.append(_score(catalogue.CATALOGUE[name], ctxs, y, w, folds, blocks, run_ids,
                              base, before))

    _slow_misfit_family(results)
    _against_extra_node(results, ctxs, y, w, folds, blocks)
    sig = sorted([c for c in results if c.significant], key=lambda c: c.heldout_after)
    soak_s = max(_longest_soak_after_ramp(c) for c in ctxs)
    sig, ambiguous = _nested_choice(sig, w, blocks, soak_s)
    chosen = base
    causes: list[CandidateResult] = []
    if ambiguous:
        chosen = sig[0].model or base
        for c in (c for c in results if c.name in ambiguous):
            c.confounded_with = [o for o in ambiguous if o != c.name]
            c.separating_run = SEPARATES.get(frozenset(ambiguous[:2]), SEPARATES_DEFAULT)
            c.evidence += f"; the run that would separate them: {c.separating_run}"
    elif sig:
        best = sig[0]
        assert best.model is not None
        chosen = best.model
        for other in sig[1:]:
            assert other.model is not None
            d = _block_sums((other.model.heldout**2 - best.model.heldout**2) * w, blocks)
            p = stats.sign_flip_p(d)
            if p >= AMBIGUOUS_P and not _adds_to(ctxs, best, other, y, w, folds, blocks):
                ambiguous.append(other.name)
                other.evidence += (f"; not separable from {best.name} on held-out blocks "
                                   f"(p={p:.2g})")
        if ambiguous:
            ambiguous.insert(0, best.name)
            runs_needed = "; ".join(dict.fromkeys(
                SEPARATES.get(frozenset((best.name, o)), SEPARATES_DEFAULT)
                for o in ambiguous[1:]))
            best.evidence += ("; confounded with " + ", ".join(ambiguous[1:]) +
                              ": these logs cannot tell them apart; the run that would "
                              f"separate them: {runs_needed}")
            for o in (c for c in results if c.name in ambiguous[1:]):
                o.confounded_with = [best.name]
                o.separating_run = SEPARATES.get(frozenset((best.name, o.name)),
                                                 SEPARATES_DEFAULT)
            best.confounded_with = ambiguous[1:]
            best.separating_run = runs_needed
        else:
            pool = [c for c in results if c is not best and c.identifiable and c.model
                    is not None and (c.significant or c.name not in catalogue.NODE_LIKE)
                    and c.name not in ambiguous and c.name not in _nested_partners(best.name)]
            causes, chosen = _forward_select(best, pool, ctxs, y, w, folds, blocks)
    structure = _structure(chosen.heldout, sigma,
                           [chosen.heldout[run_ids == i] / sigma[run_ids == i]
                            for i in range(len(rs))])
    base_structure = _structure(base.heldout, sigma,
                                [base.heldout[run_ids == i] / sigma[run_ids == i]
                                 for i in range(len(rs))])
    unexplained = _structure_remains(structure)
    remains = _remaining_share(base_structure, structure)
    structure["remaining_pct"] = 100.0 * remains
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
    cause = causes[0].name if causes else None
    extended = chosen if cause is not None else base
    return Diagnosis(causes=[c.name for c in causes], model_floor_ppm=floor,
        runs=rs, ctxs=ctxs, y=y, sigma=sigma, run_ids=run_ids, blocks=blocks, folds=folds,
        base=base, base_rms=base_rms, base_whiteness_p=stats.ljung_box_p(segs_in),
        correlations=correlations(ctxs, e_in), candidates=results, cause=cause,
        ambiguous=ambiguous, unexplained=unexplained, structure=structure, extended=extended,
        cv_mode=cv, window_s=window_s)


def _slow_misfit_family(results: list[CandidateResult]) -> None:
    """The candidates of catalogue.THIRD_NODE_CHECK (a dT/dt term, an extra lag, aging) are
    three explanations of one residual feature, a slow misfit of the base's node count, and
    each is tested against the base at ALPHA on the same logs: on a null the best of k of
    them passes by chance up to k times as often. Within that family each must reach
    ALPHA / k (Bonferroni, k the identifiable ones). The other candidates follow logged
    quantities of their own (|rate|, its sign, the board, a power-on) onto which a thermal
    misfit does not project. Forward selection, which tests one candidate on top of causes
    already found, keeps ALPHA."""
    family = [c for c in results if c.name in catalogue.THIRD_NODE_CHECK and c.identifiable
              and c.model is not None]
    level = ALPHA / max(len(family), 1)
    for c in family:
        if c.significant and c.p_value >= level:
            c.significant = False
            c.evidence = c.evidence.replace("significant:", "not significant:", 1) + (
                f"; p={c.p_value:.2g} is not below {level:.2g}: ALPHA over the "
                f"{len(family)} candidates ({', '.join(x.name for x in family)}) that "
                "could each take a slow misfit of the base")


def _against_extra_node(results: list[CandidateResult], ctxs: list[RunContext], y: np.ndarray,
                        w: np.ndarray, folds: np.ndarray, blocks: np.ndarray) -> None:
    """A significant node-like candidate (catalogue.THIRD_NODE_CHECK: a dT/dt term, an extra
    lag, and aging, a drift being what a missing slow node looks like over a log) must also
    beat the base with a third node of its own kind on held-out blocks (p <
    ALPHA): otherwise what it explains is the base's node count, not the effect, and it is
    no longer significant. Both add one column, so the comparison is fair; a real dT/dt
    term or extra lag carries the housing running ahead of the board, which no node of the
    base's kind reproduces."""
    todo = [c for c in results if c.significant and c.name in catalogue.THIRD_NODE_CHECK]
    if not todo:
        return
    ref = fit_model(ctxs, catalogue.EXTRA_NODE, y, w, folds)
    for c in todo:
        assert c.model is not None
        d = _block_sums((ref.heldout**2 - c.model.heldout**2) * w, blocks)
        p = stats.sign_flip_p(d)
        if p >= ALPHA:
            c.significant = False
            c.evidence = c.evidence.replace("significant:", "not significant:", 1) + (
                f"; no better on held-out blocks (p={p:.2g}) than the base with a third node "
                f"of its own kind ({ref.combo[1]:.0f} s): what it explains is the base's "
                "node count")


def _longest_soak_after_ramp(ctx: RunContext) -> float:
    """Longest stretch (s) over which the driving temperature holds still, after it has
    moved by RAMP_MIN_C or more since the run's start or the previous soak."""
    t = ctx.run.log.time_s
    d = ctx.driver.temp_c
    k = max(1, int(round(300.0 / float(np.median(np.diff(t))))))
    dm = d[: d.shape[0] // k * k].reshape(-1, k).mean(axis=1)  # 5-min means
    tm = t[: d.shape[0] // k * k].reshape(-1, k).mean(axis=1)
    still = np.abs(np.gradient(dm, tm)) * 60.0 < SOAK_RATE_C_PER_MIN if dm.shape[0] > 1 \
        else np.zeros(dm.shape, bool)
    best = 0.0
    ref = float(dm[0])
    i = 0
    while i < still.shape[0]:
        if not still[i]:
            i += 1
            continue
        j = i
        while j + 1 < still.shape[0] and still[j + 1]:
            j += 1
        if abs(float(dm[i]) - ref) >= RAMP_MIN_C:
            best = max(best, float(tm[j] - tm[i]) + 300.0)
        ref = float(dm[j])
        i = j + 1
    return best


def _nested_partners(name: str) -> set[str]:
    """The candidates nested with `name` (NESTED, either way). Forward selection does not
    add one on top of the other: both are the housing running ahead of lagged nodes, so
    together they are one housing coupling split two ways, and _nested_choice has already
    chosen between them."""
    return {b for a, b in NESTED.items() if a == name} | {a for a, b in NESTED.items()
                                                         if b == name}


def _nested_choice(sig: list[CandidateResult], w: np.ndarray, blocks: np.ndarray,
                   soak_s: float) -> tuple[list[CandidateResult], list[str]]:
    """Between a candidate and the simpler one it contains (NESTED), both significant and
    one of them the best:

    - the larger wins when it beats the simpler on held-out blocks (p < AMBIGUOUS_P) by at
      least NESTED_MIN_GAIN_PCT of held-out RMS and the logs hold a soak after a ramp of at
      least MIN_SOAK_FOR_LAG_S: only there does an extra slow node show as it keeps
      settling (on shorter soaks a 2 % edge at p < 0.05 is within what the base's own
      approximations give either one);
    - else, when it is no better at all (held-out RMS not below the simpler's) and the logs
      hold a soak after a ramp of at least MIN_SOAK_FOR_LAG_S (`soak_s`, the longest), the
      simpler wins: an extra slow node would have shown as it kept settling there (the
      claim: no extra node up to about that time constant; a much slower one is, over these
      logs, a constant plus a drift);
    - else the two are ambiguous: what the logs show of either is the housing running ahead
      of the board thermometer, and they do not resolve an extra slow node.
    Returns the significant candidates without the loser, and the ambiguous names, if any."""
    names = {c.name: c for c in sig}
    for big, small in NESTED.items():
        if big not in names or small not in names or sig[0].name not in (big, small):
            continue  # the pair matters only when it holds the best candidate
        b, s = names[big], names[small]
        assert b.model is not None and s.model is not None
        d = _block_sums((s.model.heldout**2 - b.model.heldout**2) * w, blocks)
        p = stats.sign_flip_p(d)
        gain = 100.0 * (1.0 - b.heldout_after / s.heldout_after)
        if p < AMBIGUOUS_P and gain >= NESTED_MIN_GAIN_PCT and soak_s >= MIN_SOAK_FOR_LAG_S:
            b.evidence += (f"; beats the simpler {small} on held-out blocks (p={p:.2g}, "
                           f"{gain:.1f}% lower RMS): the logs need the extra slow node")
            winner, loser = b, s
        elif soak_s >= MIN_SOAK_FOR_LAG_S and gain <= 0.0:
            s.evidence += (f"; the logs hold a {soak_s / 60:.0f} min soak after a ramp and "
                           f"{big} is no better on held-out blocks (p={p:.2g}): no extra slow "
                           f"node settles there")
            b.evidence += (f"; no better than the simpler {small} (p={p:.2g}) although a "
                           f"{soak_s / 60:.0f} min soak after a ramp would show its settling")
            winner, loser = s, b
        else:
            why = (f"the logs' longest soak after a ramp ({soak_s / 60:.0f} min) is too short "
                   "to watch it settle" if soak_s < MIN_SOAK_FOR_LAG_S else
                   f"it fits the held-out data {gain:.1f}% better, too little to tell")
            note = (f"{big} vs {small}: the extra slow node ({b.params.get('tau_s', 0):.0f} s) "
                    f"is not separable on held-out blocks (p={p:.2g}): {why}")
            b.evidence += "; " + note
            s.evidence += "; " + note
            return sig, [s.name, b.name]
        sig = sorted([c for c in sig if c is not loser], key=lambda c: c.heldout_after)
        assert winner in sig
    return sig, []


def _score(cand: Candidate, ctxs: list[RunContext], y: np.ndarray, w: np.ndarray,
           folds: np.ndarray, blocks: np.ndarray, run_ids: np.ndarray, base: ModelFit,
           before: float
           ) -> CandidateResult:
    if cand.needs_power_on and not any(c.power_on for c in ctxs):
        return CandidateResult(
            cand.name, False, 0.0, heldout_before=before, heldout_after=before,
            confounded_with=["base"], separating_run=SEPARATING_RUN["warmup"],
            evidence="not identifiable from these logs: every run starts warm (no "
                     "self-heating rise of the board after a power-on), so there is no start-up "
                     "transient to see (pass --start power-on if the logs do begin at "
                     "power-on)")
    if cand.name in catalogue.NODE_LIKE and all(c.driver.source == "board" for c in ctxs):
        sep = "the chamber air logged (chamber_c), with " + SEPARATING_RUN[cand.name]
        return CandidateResult(
            cand.name, False, 0.0, heldout_before=before, heldout_after=before,
            confounded_with=["base"], separating_run=sep,
            evidence="not identifiable from these logs: no chamber air (chamber_c), so the "
                     "housing running ahead of the board thermometer, which is all that "
                     "tells this term from the base's nodes, cannot be seen; confounded "
                     f"with the base model: the run that would separate them: {sep}")
    model = fit_model(ctxs, cand, y, w, folds)
    vis = visible_fraction(model, w)
    res = CandidateResult(cand.name, vis >= MIN_VISIBLE, vis, heldout_before=before)
    if not res.identifiable:
        res.heldout_after = before
        res.confounded_with = ["base"]
        res.separating_run = SEPARATING_RUN.get(cand.name, SEPARATES_DEFAULT)
        res.evidence = (f"not identifiable from these logs: {100 * (1 - vis):.1f}% of its "
                        "signature is absorbed by the base model (" + _why_hidden(cand.name)
                        + "); confounded with the base model: the run that would separate them: "
                        + res.separating_run)
        return res
    fine = None
    prof = None
    scale = 1.0
    if cand.grid_name is not None and not cand.forms:
        fine = _refine(ctxs, cand, model, y, w, folds)
        scale = sse_scale(fine, y, w, run_ids)
        (lo, hi), accepted = _profile_interval(model, fine, scale)
        lo3, hi3 = _interval_with_extra_node(ctxs, cand, y, w, scale)
        prof = (min(lo, lo3), max(hi, hi3)), accepted
    after = _weighted_rms(model.heldout)
    d = _block_sums((base.heldout**2 - model.heldout**2) * w, blocks)
    res.heldout_after = after
    res.gain_pct = 100.0 * (1.0 - after / before) if before > 0 else 0.0
    res.p_value = stats.sign_flip_p(d)
    res.blocks = int(d.shape[0])
    res.blocks_better = int(np.sum(d > 0))
    res.significant = _significant(res.p_value, d, y.shape[0])
    res.model = fine or model
    res.params = _params(cand, model, fine, prof, y, w, scale)
    g = res.model.combo[1]
    res.effect = cand.to_effect(res.model.coef(cand.coef_name), g)
    verdict = "significant" if res.significant else "not significant"
    res.evidence = (f"{verdict}: held-out RMS {before:.2f} -> {after:.2f} ppm "
                    f"(gain {res.gain_pct:.1f}%), better on {res.blocks_better} of {res.blocks} "
                    f"blocks (sign-flip p={res.p_value:.2g}); {100 * vis:.0f}% of its "
                    "signature is beyond the base model")
    return res


def _why_hidden(name: str) -> str:
    return {
        "rate_nonlinearity": "one |table rate| only: an SF that depends on |rate| is then a "
                             "constant",
        "asymmetry": "one |table rate|: +/- asymmetry cannot be told from a constant bias, "
                     "which also flips with the rate's sign",
        "bias_drift": "one table rate: a bias following temperature is then an SF term in "
                      "temperature",
        "aging": "time and temperature move together, or a slow thermal node stands in for a "
                 "drift over a run this short",
        "temp_rate": "steady ramps only: a dT/dt term is then a constant offset per ramp rate",
        "extra_lag": "steady ramps only: a lag is then a constant offset per ramp rate",
        "warmup": "no power-on transient in the logs",
    }.get(name, "collinear with the base on these logs")
