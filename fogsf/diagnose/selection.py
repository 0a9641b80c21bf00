"""Scoring the catalogue's candidates against the base and choosing among them.

`score` fits one candidate on all windows and scores it on held-out blocks against the
base (or says why it is not identifiable on these logs); the held-out gain rule is
`_significant`. The further rules then prune the significant ones: a node-like candidate
must beat a third base node (`against_extra_node`), the slow-misfit family is held to a
Bonferroni level (`slow_misfit_family`), a nested pair is resolved by the longest soak
after a ramp (`nested_choice`), and a candidate that is no better than the best and adds
nothing on top of it is ambiguous with it (`adds_to`). `forward_select` adds further
causes on top of the best one. The constants are the rules' thresholds and the runs that
would separate a candidate from the base or from another candidate.
"""

from __future__ import annotations

import numpy as np

from fogsf.diagnose import intervals, stats
from fogsf.diagnose.design import RunContext
from fogsf.diagnose.effects import catalogue, hysteresis_form
from fogsf.diagnose.effects.catalogue import Candidate, GridValue
from fogsf.diagnose.fits import (
    CandidateResult,
    ModelFit,
    block_sums,
    fit_model,
    visible_fraction,
    weighted_rms,
)
from fogsf.logs.read.columns import block_means

ALPHA = 0.01
MIN_GAIN_PCT = 5.0
MIN_VISIBLE = 1e-3  # below: the column is (numerically) inside the base model
AMBIGUOUS_P = 0.05
# extra_lag with a very slow node tends to "housing term + slow drift", which contains
# temp_rate's signature ("housing term", the coil node being in the base already)
NESTED = {"extra_lag": "temp_rate"}
NESTED_MIN_GAIN_PCT = 2.0
# pairs that forward selection does not put together unless a log has the chamber air: a
# bias on a coil the board thermometer lags or leads, which bias_drift's one-node forms only
# approximate, leaves a residual in the board's rate, the Shupe bias's signature; without
# the housing (chamber_c) a Shupe bias is not told from that (benchmarks/probes/README.md,
# "Diagnose thresholds")
NEEDS_CHAMBER_TOGETHER = (frozenset(("bias_drift", "bias_shupe")),)
SEPARATES_WITH_CHAMBER = ("the chamber air logged (chamber_c), with a ramp of 5 C or more "
                          "and a soak after it")
MIN_SOAK_FOR_LAG_S = 2700.0  # 45 min of soak, as found (the 5 min after a ramp stops excluded)
SOAK_RATE_C_PER_MIN = 0.02  # slower than this (driver, 5-min average) is a soak
RAMP_MIN_C = 5.0  # a soak counts when the driver moved at least this much before it
MIN_DZ2 = 0.05  # held-out gain rule: mean drop of (e/sigma)^2 per window, in noise variances
MAX_CAUSES = 3
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
    "hysteresis": hysteresis_form.SEPARATING_RUN,
    "bias_shupe": "ramps with both signs of the table rate, or a second |table rate| (at one "
                  "rate a bias is an SF term)",
}
# ... and from another candidate
SEPARATES = {
    frozenset(("temp_rate", "extra_lag")): "a soak of at least 45 min after a ramp of 5 C "
                                           "or more",
    frozenset(("warmup", "aging")): "a soak of at least 3 h at constant temperature",
    frozenset(("asymmetry", "bias_drift")): "a second |table rate|, each with both signs",
    frozenset(("rate_nonlinearity", "bias_drift")): "a third |table rate|",
    frozenset(("aging", "extra_lag")): "a soak of at least 3 h at constant temperature",
    frozenset(("temp_rate", "bias_shupe")): "both signs of the table rate, or a second "
                                            "|table rate|",
}
SEPARATES_DEFAULT = ("a longer log with soaks at two temperatures, a power-on start and a "
                     "second |table rate|")


def _significant(p: float, d: np.ndarray, n: int) -> bool:
    """The held-out gain rule: better on held-out blocks (paired sign-flip p < ALPHA) and the
    held-out weighted SSE lower by at least MIN_DZ2 noise variances per window on average.
    It scales with the noise: a gain of a few % of RMS counts when the residual is near the
    noise, and a big residual needs a gain that is big in noise units."""
    return p < ALPHA and float(np.sum(d)) / max(n, 1) >= MIN_DZ2


def adds_to(ctxs: list[RunContext], best: CandidateResult, other: CandidateResult,
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
    d = block_sums((best.model.heldout**2 - m.heldout**2) * w, blocks)
    return _significant(stats.sign_flip_p(d), d, y.shape[0])


def _beats_third_node(ctxs: list[RunContext], chosen: list[tuple[Candidate, GridValue]],
                      m: ModelFit, y: np.ndarray, w: np.ndarray, folds: np.ndarray,
                      blocks: np.ndarray) -> bool:
    """Does `m` beat the causes so far plus a third base node, on held-out blocks?"""
    ref = fit_model(ctxs, catalogue.combine(chosen, catalogue.EXTRA_NODE), y, w, folds)
    d = block_sums((ref.heldout**2 - m.heldout**2) * w, blocks)
    return stats.sign_flip_p(d) < ALPHA


def forward_select(first_c: CandidateResult, pool: list[CandidateResult],
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
    if not any(c.driver.source == "chamber" for c in ctxs):
        for r in list(rest):
            if frozenset((first_c.name, r.name)) in NEEDS_CHAMBER_TOGETHER:
                rest.remove(r)
                r.confounded_with = [first_c.name]
                r.separating_run = SEPARATES_WITH_CHAMBER
                r.evidence += (f"; not added after {first_c.name}: without the chamber air it "
                               f"is not told from {first_c.name} on a node the board "
                               "thermometer only approximates; the run that would separate "
                               f"them: {SEPARATES_WITH_CHAMBER}")
    while rest and len(causes) < MAX_CAUSES:
        best: tuple[CandidateResult, ModelFit, float] | None = None
        for r in rest:
            comb = catalogue.combine(chosen, catalogue.CATALOGUE[r.name])
            m = fit_model(ctxs, comb, y, w, folds)
            d = block_sums((model.heldout**2 - m.heldout**2) * w, blocks)
            p = stats.sign_flip_p(d)
            if _significant(p, d, y.shape[0]) and (
                    best is None or weighted_rms(m.heldout) < weighted_rms(best[1].heldout)
            ) and (r.name not in catalogue.THIRD_NODE_CHECK
                   or _beats_third_node(ctxs, chosen, m, y, w, folds, blocks)):
                best = (r, m, p)
        if best is None:
            break
        r, m, p = best
        before, after = weighted_rms(model.heldout), weighted_rms(m.heldout)
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
            c.params[f"{cand.coef_name}_ci95"] = [coef - intervals.Z95 * se,
                                                  coef + intervals.Z95 * se]
            c.evidence += (f"; with the other causes: {cand.coef_name} = {coef:.4g}")
    return causes, model


def slow_misfit_family(results: list[CandidateResult]) -> None:
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


def against_extra_node(results: list[CandidateResult], ctxs: list[RunContext], y: np.ndarray,
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
        d = block_sums((ref.heldout**2 - c.model.heldout**2) * w, blocks)
        p = stats.sign_flip_p(d)
        if p >= ALPHA:
            c.significant = False
            c.evidence = c.evidence.replace("significant:", "not significant:", 1) + (
                f"; no better on held-out blocks (p={p:.2g}) than the base with a third node "
                f"of its own kind ({ref.combo[1]:.0f} s): what it explains is the base's "
                "node count")


def longest_soak_after_ramp(ctx: RunContext) -> float:
    """Longest stretch (s) over which the driving temperature holds still, after it has
    moved by RAMP_MIN_C or more since the run's start or the previous soak."""
    k = max(1, int(round(300.0 / ctx.run.dt_s)))
    dm = block_means(ctx.driver.temp_c, k)  # 5-min means
    tm = block_means(ctx.run.log.time_s, k)
    still: np.ndarray = np.abs(np.gradient(dm, tm)) * 60.0 < SOAK_RATE_C_PER_MIN \
        if dm.shape[0] > 1 else np.zeros(dm.shape, bool)
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


def nested_partners(name: str) -> set[str]:
    """The candidates nested with `name` (NESTED, either way). Forward selection does not
    add one on top of the other: both are the housing running ahead of lagged nodes, so
    together they are one housing coupling split two ways, and nested_choice has already
    chosen between them."""
    return {b for a, b in NESTED.items() if a == name} | {a for a, b in NESTED.items()
                                                         if b == name}


def nested_choice(sig: list[CandidateResult], w: np.ndarray, blocks: np.ndarray,
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
        d = block_sums((s.model.heldout**2 - b.model.heldout**2) * w, blocks)
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


def score(cand: Candidate, ctxs: list[RunContext], y: np.ndarray, w: np.ndarray,
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
    if cand.name == "hysteresis" and not any(hysteresis_form.has_minor_loop(c) for c in ctxs):
        sep = hysteresis_form.SEPARATING_RUN
        return CandidateResult(
            cand.name, False, 0.0, heldout_before=before, heldout_after=before,
            confounded_with=["base"], separating_run=sep,
            evidence="not identifiable from these logs: no run turns back inside its "
                     "temperature range, so a play is a direction-dependent offset that the "
                     "base's misfit takes as well; the run that would separate them: " + sep)
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
        fine = intervals.refine(ctxs, cand, model, y, w, folds)
        scale = intervals.sse_scale(fine, y, w, run_ids)
        (lo, hi), accepted = intervals.profile_interval(model, fine, scale)
        lo3, hi3 = intervals.interval_with_extra_node(ctxs, cand, y, w, scale)
        prof = (min(lo, lo3), max(hi, hi3)), accepted
    after = weighted_rms(model.heldout)
    d = block_sums((base.heldout**2 - model.heldout**2) * w, blocks)
    res.heldout_after = after
    res.gain_pct = 100.0 * (1.0 - after / before) if before > 0 else 0.0
    res.p_value = stats.sign_flip_p(d)
    res.blocks = int(d.shape[0])
    res.blocks_better = int(np.sum(d > 0))
    res.significant = _significant(res.p_value, d, y.shape[0])
    res.model = fine or model
    res.params = intervals.candidate_params(cand, model, fine, prof, y, w, scale)
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
