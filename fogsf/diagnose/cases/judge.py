"""Whether a diagnosis got a planted case right (`diagnose.cases.planted`): the rules the tests and
`benchmarks.diagnose_rate` apply, with the tolerance held on each effect's parameter."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fogsf.diagnose.cases import kinds as case_kinds
from fogsf.diagnose.cases.planted import MULTIPLE_RANGE, Case

# the profiled parameter and the tolerance a diagnosis must meet on each effect
PARAM_CHECK: dict[str, tuple[str, str, float]] = {
    # effect: (param key in the diagnosis, truth key, relative tolerance)
    "warmup": ("tau_s", "tau_s", 0.5),
    "extra_lag": ("sens_ppm_per_c", "sens_ppm_per_c", 0.3),  # and tau_s inside its interval
    # the dT/dt term: its coupling to the housing, what the logs pin (see housing_coupling)
    "temp_rate": ("housing_ppm_per_c", "housing_ppm_per_c", 0.5),
    "rate_nonlinearity": ("strength_ppm_at_100dps", "strength", 0.3),
    "asymmetry": ("strength_ppm", "strength", 0.3),
    "bias_drift": ("strength_dph_per_c", "strength", 0.3),
    "aging": ("strength_ppm_per_h", "strength", 0.3),
    # the loop's height (strength x width): the play of one lagged node stands for the
    # coil's layers, which trades the width against the strength
    "hysteresis": ("height_ppm", "height_ppm", 0.5),
    # as temp_rate: the coupling to the housing (deg/h per C), what the logs pin
    "bias_shupe": ("housing_dph_per_c", "housing_dph_per_c", 0.5),
}


@dataclass
class Outcome:
    ok: bool
    reason: str
    cause: str | None
    unexplained: bool


def judge(case: Case, truth: dict[str, Any], cause: str | None, unexplained: bool,
          candidates: list[dict[str, Any]], ambiguous: list[str] | None = None,
          causes: list[str] | None = None) -> Outcome:
    """Did the diagnosis get this case right? (the rules the tests and benchmark apply)

    Beyond `draw`'s kinds: asymmetry at one |rate| is right when no cause is named and the
    asymmetry is reported confounded with the base (its separating run named); a slow
    warm-up is right when named (tau within 50 %) or explained by the base's own unseen
    self-heating (no cause, no structure left); a settling aging's initial slope is held to
    50 %; two planted effects are right when `causes` holds both and nothing else. A dT/dt
    term is judged on its housing coupling (housing_coupling, 50 %): the logs pin that, and
    the strength only with the unseen coil's time constants; one whose coil nodes all sit
    behind other internal nodes (coupling 0) is part of the gyro's own thermal SF law, and
    is right when no cause is named (docs/diagnose.md, "The dT/dt term's strength")."""
    ambiguous = ambiguous or []
    causes = causes if causes is not None else ([cause] if cause else [])

    def out(ok: bool, why: str) -> Outcome:
        return Outcome(ok, why, cause, unexplained)

    if case.kind == "two":
        want = set(truth["effects"])
        ok = set(causes) == want
        return out(ok, f"causes {causes}, planted {sorted(want)}"
                   + ("" if ok or not unexplained else " (unexplained)"))
    if case.kind == "effect" and case.variant == "one":
        c = next(x for x in candidates if x["effect"] == case.name)
        ok = cause is None and "base" in c.get("confounded_with", []) and bool(
            c.get("separating_run"))
        return out(ok, f"cause {cause!r}; confounded with {c.get('confounded_with')}, "
                       f"separating run: {c.get('separating_run')!r}")
    coupling = {"temp_rate": "housing_ppm_per_c", "bias_shupe": "housing_dph_per_c"}
    if case.kind == "effect" and case.name in coupling and truth[coupling[case.name]] == 0:
        # every coil node sits behind another internal node: an SF term is a combination of
        # internal nodes' temperatures, i.e. part of the gyro's own thermal SF law; a bias
        # term is still a bias (its sign follows the table's), named or not, never another
        ok = cause is None or (case.name == "bias_shupe" and cause == case.name)
        return out(ok, "no coil node behind the housing: confounded with the "
                   f"gyro's own nodes, {'not named' if cause is None else f'named {cause}'}")
    if case.kind == "effect" and case.name == "hysteresis" and cause is None \
            and case.multiple_reached < MULTIPLE_RANGE[0]:
        return out(True, f"visible part {case.multiple_reached:.1f} x the floor (under "
                         f"{MULTIPLE_RANGE[0]:g}): not named, not misnamed")
    if case.kind == "effect" and case.variant == "slow" and cause is None:
        return out(not unexplained, "explained by the base's self-heating" if not unexplained
                   else "unexplained, not named")
    if case.kind == "effect":
        if cause is None and case.name in ambiguous:
            return out(False, f"ambiguous between {', '.join(ambiguous)} (planted {case.name}):"
                              " not wrong, not named")
        if cause != case.name:
            return out(False, f"cause {cause!r}, planted {case.name}")
        if case.variant == "coil_pair" and causes != [cause]:
            return out(False, f"causes {causes}, planted {case.name} alone")
        c = next(x for x in candidates if x["effect"] == cause)
        if case.name == "bias_shupe" and not truth.get("coils_behind_housing", 1.0):
            # a coil behind another internal node: the catalogue's coil (layers right
            # behind the housing) holds the term only in effect; named is what is checked
            return out(bool(c["significant"]), "named (a coil behind another node: its "
                       "coupling is not the model's parameter)")
        key, tkey, tol = PARAM_CHECK[case.name]
        if case.variant in ("settling", "slow"):
            tol = 0.5
        est, true = float(c["params"][key]), float(truth[tkey])
        if abs(est - true) > tol * abs(true):
            return out(False, f"{key} {est:.4g} vs planted {true:.4g} (tolerance {tol:.0%})")
        if case.name == "extra_lag":  # a slow node's time constant is often only bounded
            lo, hi = c["params"]["tau_s_ci95"]
            if not lo <= truth["tau_s"] <= hi:
                return out(False, f"tau_s interval [{lo:.4g}, {hi:.4g}] misses the planted "
                                  f"{truth['tau_s']:.4g}")
        if not c["significant"]:
            return out(False, f"not significant (held-out gain {c['gain_pct']:.1f}%)")
        return out(True, f"{key} {est:.4g} vs {true:.4g}, gain {c['gain_pct']:.1f}%")
    if case.kind == "null":
        return out(cause is None, "named nothing" if cause is None else f"false cause {cause}")
    if case.kind == "ooc":
        if case.name == "mode_hop" and cause is None and not unexplained \
                and case.multiple_reached < case_kinds.MODE_HOP_MIN_VISIBLE:
            return out(True, f"visible part {case.multiple_reached:.2f} x the floor (under "
                             f"{case_kinds.MODE_HOP_MIN_VISIBLE:g}): not held to the report")
        if cause is not None:
            return out(False, f"named catalogue effect {cause} for out-of-catalogue "
                              f"{case.name}")
        return out(unexplained, "unexplained" if unexplained else "structure not flagged")
    if case.kind == "ramp_only":
        return out(cause is None, "did not guess" if cause is None else f"guessed {cause}")
    if case.kind == "short_soak":
        if cause is None and case.name in ambiguous:
            return out(True, "ambiguous, as short soaks leave it")
        if case.name == "temp_rate" and truth["housing_ppm_per_c"] == 0 and cause is None:
            return out(True, "no coil node behind the housing: confounded with the gyro's "
                             "own nodes, not named")
        return out(cause == case.name, f"cause {cause!r}, planted {case.name}")
    raise ValueError(case.kind)


def judge_report(case: Case, truth: dict[str, Any], j: dict[str, Any]) -> Outcome:
    """`judge` on a diagnosis as `report.to_json` writes it."""
    return judge(case, truth, j["cause"], j["unexplained"], j["candidates"], j["ambiguous"],
                 j["causes"])
