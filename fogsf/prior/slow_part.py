"""The slow-part features of `fleet check`: what a unit's recorded step series
(`unit_summary`'s "series") says of how slowly its SF follows temperature, when its logs can
show it. All one-sided (`fleet.check`): only a slower response, a larger misfit or
chi-square flags.

- `slow.log_tau_s`: the one-node physics law's (`unit_fit.design_matrix`, k = 1) time
  constant, the mean of log tau over a grid weighted by exp(-(SSE(tau) - SSE_min) / (2
  TEMPER sigma^2)); a slower part lengthens it whatever the parts' coefficients. A weighted
  mean, not the best tau: a normal unit's SSE often has two near-equal minima.
- `slow.shape_log_misfit`: the log of the unit's SF curve's squared misfit to the line's
  other units (`shape_misfit`), when all ran the same program: a slower part bends the curve
  in a way the others' leading directions of variation do not take.
- `slow.prior_log_chi2`: log(10 + the check chi-square) of the unit's step series against the
  design's prior learned from the line's other units (`prior_chi2`): a slower part is a
  response the others' spread of parameters does not give, whatever parameter moves.
- Only when every unit's training logs hold a soak of SOAK_MIN_S or more after a ramp: a 2 h
  loop's 20 min soaks cannot show a part 2.5 x slower (the probe `fleet_slow_part`), and
  only when the units ran one program (ramp rate and soak within SAME_PROGRAM).
Figures: docs/fleet.md (check), benchmarks/probes/README.md (`fleet_slow_part`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from fogsf.errors import UserError
from fogsf.models.structures.node_fit import ridge_fit
from fogsf.models.structures.physics_nodes import NODE_LAMBDA, TAU_MAX_S, TAU_MIN_S
from fogsf.prior.design_prior import SHRINK, DesignPrior, learn, spread
from fogsf.prior.map_estimate import NOISE_SCALE, check_problem
from fogsf.prior.unit_fit import (
    Play,
    StepSeries,
    UnitFit,
    correlation_factor,
    design_matrix,
    fit_at,
    fit_unit,
    jacobian,
    n_coef,
)

# a soak shorter than this after a ramp cannot show a slower part: a 2 h loop's 20 min soaks
# read 4-15 min, a 1 h chamber soak 37-57 min (the board lags the chamber by design)
SOAK_MIN_S = 30 * 60.0
FLAT_C_PER_MIN = 0.1  # board temperature moving slower than this (5 min mean): a soak
RAMP_C_PER_MIN = 0.3  # and faster than this: a ramp
SMOOTH_S = 300.0  # the board temperature's rate is read on means this long
SAME_PROGRAM = 0.15  # units whose ramp rate or soak is further from the line's: another program
SLOW = "slow."  # the slow-part features' names start so (`fleet.check`: one-sided)
PREFIX = SLOW + "log_tau_s"
TAU_GRID_S = np.geomspace(60.0, TAU_MAX_S, 61)
# the SSE's scale in the weights, x the residual variance: wide enough that a normal unit's
# two near-equal minima share the weight (tuned on development designs, the probe's README)
TEMPER = 150.0
SHAPE = SLOW + "shape_log_misfit"
SHAPE_BLOCK_S = 300.0  # the curves compared are 5 min means (the SF noise averaged down)
SHAPE_RANK = 6  # the others' leading directions a normal unit's curve may take (at most
# n - 3 of a line of n; tuned on development designs)
ALIGN_C = 1.0  # board temperatures (less their mean) further apart (median, C): other
# programs
PRIOR = SLOW + "prior_log_chi2"
# the chi-square's offset in the log: below about 10 (the parameters' count) a chi-square's
# differences are noise, not a defect (tuned on development designs, the probe's README)
PRIOR_OFFSET = 10.0
# the kept units the chi-square needs: the others of a kept unit (one less) give a mean and
# a spread of at least 2 degrees of freedom
MIN_KEPT = 4
# each feature's standard error, the least difference that is a defect (5 % in the time
# constant, x1.35 in the misfit, x1.1 in 10 + the chi-square): else a line whose others
# agree closely flags a normal unit
SE_FLOOR = {PREFIX: 0.05, SHAPE: 0.3, PRIOR: 0.1}
SLOW_VERSION = 2  # a summary's "slow" of another version is computed again from its series


def _rate_c_per_min(t: np.ndarray, step_s: float) -> np.ndarray:
    k = max(1, int(round(SMOOTH_S / step_s)))
    # padded with the end values: zeros would make a log's start a ramp from 20 C
    padded = np.pad(t, (k // 2, k - 1 - k // 2), mode="edge")
    smooth = np.convolve(padded, np.ones(k) / k, mode="valid")
    return np.asarray(np.gradient(smooth) * 60.0 / step_s, dtype=np.float64)


def program_of(series: StepSeries) -> tuple[float, float]:
    """(ramp rate C/min, longest soak after a ramp s) of the unit's logs: the median rate of
    the ramps' steps and the longest stretch of flat board temperature that follows one
    (SMOOTH_S / 2 added back: what the smoothing takes off a soak's two ends)."""
    rates: list[np.ndarray] = []
    longest = 0
    for t in series.t_rel:
        if t.size < 3:
            continue
        r = _rate_c_per_min(t, series.step_s)
        ramp = np.abs(r) > RAMP_C_PER_MIN
        rates.append(np.abs(r[ramp]))
        if not ramp.any():
            continue
        flat = (np.abs(r) < FLAT_C_PER_MIN)[int(np.argmax(ramp)):].astype(np.int8)
        edges = np.flatnonzero(np.diff(np.r_[0, flat, 0]))  # flat runs' starts and ends
        if edges.size:
            longest = max(longest, int(np.max(edges[1::2] - edges[::2])))
    both = np.concatenate(rates) if rates else np.zeros(0)
    soak = longest * series.step_s + SMOOTH_S / 2 if longest else 0.0
    return (float(np.median(both)) if both.size else 0.0), soak


def feature_name(rate: float, soak_s: float) -> str:
    """The feature's name, saying the program it was read on (the line's median)."""
    return f"{PREFIX} ({rate:.2g} C/min, {soak_s / 60.0:.0f} min soaks)"


def effective_log_tau(series: StepSeries) -> float:
    """The SSE-weighted mean of log tau of the one-node law over TAU_GRID_S (module doc)."""
    sse = np.empty(TAU_GRID_S.size)
    for i, tau in enumerate(TAU_GRID_S):
        sse[i] = ridge_fit(design_matrix(series, np.array([tau]))[:, 1:], series.y,
                           NODE_LAMBDA).sse
    x = design_matrix(series, TAU_GRID_S[[int(np.argmin(sse))]])[:, 1:]
    fit = ridge_fit(x, series.y, NODE_LAMBDA)
    resid = series.y - fit.predict(x)
    s2 = float(resid @ resid) / max(1, resid.size) * correlation_factor(resid, series.step_s)
    w = np.exp(-(sse - sse.min()) / (2.0 * TEMPER * max(s2, 1e-12)))
    return float(w @ np.log(TAU_GRID_S) / w.sum())


def unit_slow(series: StepSeries) -> dict:
    """What the slow-part features need of one unit, JSON-able and small (kept in the unit's
    summary, "slow"): its program, its time constant (when a soak is long enough), its SF
    curve and board temperature in SHAPE_BLOCK_S means, per log."""
    rate, soak = program_of(series)
    full = np.full(sum(t.size for t in series.t_rel), np.nan)
    full[series.rows] = series.y
    b = max(1, int(round(SHAPE_BLOCK_S / series.step_s)))
    curves, temps, start = [], [], 0
    for t in series.t_rel:
        m = t.size // b * b
        with np.errstate(all="ignore"):
            c = np.nanmean(full[start:start + m].reshape(-1, b), axis=1)
        ok = np.isfinite(c)  # a block without a measured step: its log's mean (JSON: no NaN)
        c = np.where(ok, c, float(np.mean(c[ok])) if ok.any() else 0.0)
        curves.append([round(float(v), 3) for v in c])
        temps.append([round(float(v), 3) for v in t[:m].reshape(-1, b).mean(axis=1)])
        start += t.size
    return {"version": SLOW_VERSION, "rate_c_per_min": rate, "soak_s": soak,
            "log_tau_s": effective_log_tau(series) if soak >= SOAK_MIN_S else None,
            "curve_ppm": curves, "temp_c": temps}


def _unit_slow(summary: dict) -> dict | None:
    """The summary's "slow", else computed from its step series (a unit recorded before
    fogsf kept it); None when it has neither (or a series that does not read)."""
    got = summary.get("slow")
    # one kept under a longer soak gate lacks the time constant its soak gives now: computed
    if isinstance(got, dict) and got.get("version") == SLOW_VERSION and (
            got.get("log_tau_s") is not None or got.get("soak_s", 0.0) < SOAK_MIN_S):
        return got
    try:
        return unit_slow(StepSeries.from_dict(summary["series"]))
    except (KeyError, TypeError, ValueError):
        return None


def line_features(summaries: list[dict]) -> tuple[list[dict[str, float]], list[dict[str, float]],
                                                  str]:
    """Each unit's slow-part features and their standard errors (SE_FLOOR), {} where not
    read, and a note saying why they are not read when not."""
    empty: list[dict[str, float]] = [{} for _ in summaries]
    units = [_unit_slow(s) for s in summaries]
    old = sum(u is None for u in units)
    if old:
        return empty, list(empty), (f"slower thermal part not checked: {old} unit(s) recorded "
                                    "without a step series (recorded before fogsf kept one)")
    slow = [u for u in units if u is not None]
    short = sum(u["log_tau_s"] is None for u in slow)
    if short:
        return empty, list(empty), (
            f"slower thermal part not checked: {short} unit(s) trained on logs without a "
            f"soak of {SOAK_MIN_S / 60:.0f} min after a ramp (a 2 h loop's 20 min soaks "
            "cannot show a part 2.5 x slower; hour-long soaks can)")
    rate = float(np.median([u["rate_c_per_min"] for u in slow]))
    soak = float(np.median([u["soak_s"] for u in slow]))
    if any(abs(u["rate_c_per_min"] / rate - 1.0) > SAME_PROGRAM
           or abs(u["soak_s"] / soak - 1.0) > SAME_PROGRAM for u in slow):
        return empty, list(empty), ("slower thermal part not checked: the units' programs "
                                    "differ (ramp rate or soak length; units of one program "
                                    "compare)")
    name = feature_name(rate, soak)
    feats = [{name: float(u["log_tau_s"])} for u in slow]
    chi2 = prior_chi2(summaries)
    note = "" if chi2 is not None else (
        "slower thermal part: the prior's chi-square not read (the line's prior could not "
        f"be learned with {MIN_KEPT} units kept, or a unit's fit failed)")
    if chi2 is not None:
        for f, v in zip(feats, chi2.tolist(), strict=True):
            f[name.replace(PREFIX, PRIOR)] = math.log(PRIOR_OFFSET + max(v, 0.0))
    shape = shape_misfit(slow)
    if shape is not None:
        name = name.replace(PREFIX, SHAPE)
        for f, v in zip(feats, shape.tolist(), strict=True):
            f[name] = v
    return feats, [{k: SE_FLOOR[k.split(" ")[0]] for k in f} for f in feats], note


def shape_misfit(units: list[dict]) -> np.ndarray | None:
    """log of each unit's SF curve's squared misfit to the line's other units (`unit_slow`'s
    curves, less their mean: a unit's SF offset is not its response): its deviation from
    their mean less its part in their SHAPE_RANK leading directions (an SVD of theirs). None
    when the units' programs do not line up (log count, length or board temperature):
    curves of other programs are not comparable."""
    n = len(units)
    logs = {len(u["curve_ppm"]) for u in units}
    if n < 4 or len(logs) > 1:
        return None
    lengths = [[len(c) for c in u["curve_ppm"]] for u in units]
    steps = [min(x[j] for x in lengths) for j in range(logs.pop())]
    if any(x[j] > 1.02 * steps[j] + 1 for x in lengths for j in range(len(steps))):
        return None

    def cut(u: dict, key: str) -> np.ndarray:
        x = np.concatenate([np.asarray(c[:m], dtype=np.float64)
                            for c, m in zip(u[key], steps, strict=True)])
        return np.asarray(x - x.mean(), dtype=np.float64)  # self-heating offsets the board

    temps = np.array([cut(u, "temp_c") for u in units])
    if np.max(np.median(np.abs(temps - np.median(temps, axis=0)), axis=1)) > ALIGN_C:
        return None
    curves = np.array([cut(u, "curve_ppm") for u in units])
    rank = min(SHAPE_RANK, n - 3)
    out = np.empty(n)
    for i in range(n):
        others = np.delete(curves, i, axis=0)
        mean = others.mean(axis=0)
        vt = np.linalg.svd(others - mean, full_matrices=False)[2][:rank]
        e = curves[i] - mean
        e = e - vt.T @ (vt @ e)
        out[i] = math.log(max(float(e @ e), 1e-12))
    return out


def prior_chi2(summaries: list[dict]) -> np.ndarray | None:
    """Each unit's check chi-square against the design's prior learned from the line's
    other units (`short_search_chi2`: `map_estimate.check_chi2`'s, its search over the
    time constants made short). The structure (node count, play, the units left out) and
    the kept units' fits are learned once from the whole line (`design_prior.learn`); the
    spread without the unit from the kept units' sums less its own. None when the prior
    cannot be learned (too few units, a series that does not read), a fit fails or a
    chi-square is not finite (one such value would void the whole line's z)."""
    try:
        return _prior_chi2(summaries)
    except (KeyError, TypeError, ValueError, UserError, np.linalg.LinAlgError):
        return None


def line_sums(thetas: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                              np.ndarray, int]:
    """The sums `leave_one_out` reads: of the rows of `thetas`, of their outer products and
    of `covs`, and the count (once a line)."""
    return thetas.sum(axis=0), thetas.T @ thetas, covs.sum(axis=0), thetas.shape[0]


def leave_one_out(sums: tuple[np.ndarray, np.ndarray, np.ndarray, int],
                  own: tuple[np.ndarray, np.ndarray] | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(mean, covariance (ddof 1), mean estimation covariance, count) of the units of
    `line_sums` other than `own` (its theta and covariance; None: all of them), from the
    sums less its own: O(p^2) a unit, where a pass over the others is O(N p^2)."""
    t1, t2, tc, m = sums
    if own is not None:
        t, c = own
        t1, t2, tc, m = t1 - t, t2 - np.outer(t, t), tc - c, m - 1
    mu = t1 / m
    return mu, (t2 - m * np.outer(mu, mu)) / (m - 1), tc / m, m


def short_search_chi2(series: StepSeries, prior: DesignPrior, s2: float, alone: UnitFit,
                      play: Play | None) -> float:
    """`map_estimate.check_chi2` (min_theta J_check(theta) - |y - f(theta_a)|^2 / s2, theta_a
    the unit's own fit) with the search over the time constants made short: the objective
    with the law's coefficients at their optimum (closed form) read at three time constants,
    the least kept: the fit's, the prior's mean, and one Gauss-Newton step from the fit (the
    model linearised there, f(theta_a + d) = f(theta_a) + J d: its minimum over d is at
    A d = g, A = J^T J / s2 + P, g = J^T r / s2 - P (theta_a - mu), P = Sigma_check^-1, r the
    fit's residual). The first two are `check_chi2`'s starts, which its search descends
    from; the step reaches its minimum where the model is near linear over the prior's
    spread. The linearised value itself is not read: where a normal unit's time constants lie
    far from the others' it overstates the chi-square by what a move of them takes away."""
    k, th = prior.k, alone.theta
    lo, hi = math.log(TAU_MIN_S), math.log(TAU_MAX_S)  # the check's search range
    pb = check_problem(series, prior, s2)
    prec = pb.lmat.T @ pb.lmat  # L^T L = P
    jac = jacobian(series, th, k, play=play)
    r = series.y - jac[:, k:] @ th[k:]  # the Jacobian's last columns: the design matrix
    g = jac.T @ r / s2 - prec @ (th - prior.mu)
    step = np.linalg.solve(jac.T @ jac / s2 + prec, g)
    starts = (th[:k], prior.mu[:k], th[:k] + step[:k])
    best = min(float(r @ r) for r in (pb.coef(np.sort(np.clip(t, lo, hi)))[1] for t in starts))
    return best - alone.sse / s2


def _prior_chi2(summaries: list[dict]) -> np.ndarray | None:
    series = [StepSeries.from_dict(s["series"]) for s in summaries]
    first: dict[int, dict[str, UnitFit]] = {}
    for i, summary in enumerate(summaries):
        for k, f in summary.get("fits", {}).items():
            first.setdefault(int(k), {})[str(i)] = UnitFit.from_dict(f)
    prior = learn({str(i): x for i, x in enumerate(series)}, first=first)
    k, play = prior.k, prior.play
    kept = [int(u) for u in prior.units]
    if prior.unit_thetas is None or len(kept) < MIN_KEPT:
        return None
    # the kept units' fits at the time constants `learn` found for them (its unit_thetas
    # keep them; the better of its two starts, the play fitted in): no search again
    fits = [fit_at(series[i], k, np.exp(t[:k]), play)
            for i, t in zip(kept, prior.unit_thetas, strict=True)]
    sums = line_sums(np.stack([f.theta for f in fits]), np.stack([f.cov for f in fits]))
    where = {i: j for j, i in enumerate(kept)}
    out = np.empty(len(series))
    for i, s in enumerate(series):
        j = where.get(i)
        mu, between, noise, m = leave_one_out(
            sums, None if j is None else (fits[j].theta, fits[j].cov))
        loo = replace(prior, mu=mu, sigma=spread(between, noise, m, SHRINK),
                      sigma_check=spread(between, noise, m, None))
        # the unit's own fit: a kept unit's `learn` made; one left out fitted from the
        # others' time constants, as `map_fit` starts the check
        alone = fits[j] if j is not None else fit_unit(s, k, np.exp(mu[:k]), play)
        # the grid start's fit where the summary keeps it (without a play, of this layout);
        # else a kept unit keeps `learn`'s (the better of its starts), one left out is fitted
        grid = first.get(k, {}).get(str(i)) if play is None else None
        if grid is None or grid.theta.size != k + n_coef(k):
            grid = fit_unit(s, k, play=play) if j is None else None
        if grid is not None and grid.sse < alone.sse:
            alone = grid
        out[i] = short_search_chi2(s, loo, alone.sigma2 * NOISE_SCALE, alone, play)
    return out if np.all(np.isfinite(out)) else None
