"""Profiled parameters of a scored candidate: refinement, intervals, reported values.

A candidate with a nonlinear grid parameter (a time constant, a lag) is first fitted on its
coarse grid; `refine` refits on a finer grid around every local minimum of the profile.
The parameter's interval (`profile_interval`, and `interval_with_extra_node` on a base with
a third node; the reported one is their union) is where the profiled SSE stays within
chi2(1, 95%) = 3.84 units of `sse_scale` (reduced chi-square times the residual's long-run
variance ratio) of its minimum. `candidate_params` turns the fits into the reported
parameters: the coefficient's interval carries the parameter's uncertainty
(coefficient range over the profile), and a candidate marked `average` (temp_rate) reports
profile-likelihood averages with the best fit alongside.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from fogsf.diagnose import profile_ls
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects import catalogue
from fogsf.diagnose.effects.catalogue import Candidate, GridValue, first
from fogsf.diagnose.fits import ModelFit, fit_model

Z95 = 1.959964
BATCH_WINDOWS = 10  # batch means for the residual's long-run variance (sse_scale)


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


def profile_interval(coarse: ModelFit, fine: ModelFit, scale: float
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


def interval_with_extra_node(ctxs: list[RunContext], cand: Candidate, y: np.ndarray,
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


def refine(ctxs: list[RunContext], cand: Candidate, model: ModelFit, y: np.ndarray,
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


def candidate_params(cand: Candidate, model: ModelFit, fine: ModelFit | None,
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
        if cand.name in ("temp_rate", "bias_shupe"):
            out["coil_outer_tau_s_best_fit"] = catalogue.coil_taus(g)[1]
            out.update(_housing_coupling(model, fine, y, w, interval, accepted, cand.name))
        if cand.name == "hysteresis":  # the loop's full height, what the logs pin best
            out["height_ppm"] = coef * gv
            out["coil_tau_s_best_fit"] = float(g[1]) if isinstance(g, tuple) else None
        return out
    return {cand.coef_name: coef, f"{cand.coef_name}_ci95": ci}


def _housing_coupling(coarse: ModelFit, fine: ModelFit, y: np.ndarray, w: np.ndarray,
                      interval: tuple[float, float], accepted: list[GridValue],
                      effect: str = "temp_rate") -> dict[str, object]:
    """temp_rate's coupling to the housing (catalogue.housing_coupling), at the best fit and
    its 95 % range over the coil time constants the profile accepts: what the logs pin of
    a dT/dt term (the strength in ppm/(C/min) also needs the coil's time constants)."""
    name = catalogue.CATALOGUE[effect].coef_name
    best = catalogue.housing_coupling(fine.coef(name), fine.combo[1])
    lo, hi = _coef_range_over_profile(coarse, name, y, w, interval, accepted,
                                      lambda v: catalogue.housing_coupling(1.0, v))
    key = "housing_ppm_per_c" if effect == "temp_rate" else "housing_dph_per_c"  # bias_shupe
    return {key: best, f"{key}_ci95": [min(lo, best), max(hi, best)]}
