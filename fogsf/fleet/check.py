"""Units unlike the line (`fogsf fleet check`): which units' structure or parameters lie
outside the design's spread, and why, at a stated false-alarm rate. Reads only the records.

- Structure: the line's is the one most units have (at least half of them); a unit with
  another (node count, law terms, a hysteresis term) is flagged.
- Parameters, through what they predict: each unit's model read on the design's reference
  program (`records.response`: SF error at soaks and ramp points, less their mean). Two
  slow parts that move together trade their fitted coefficients from unit to unit (their
  time constants jump between fits of normal units); the prediction they make does not.
  And the log of the unit's training residual over its noise floor (`fit.log_residual`,
  one-sided: only a larger one flags): a defect the design's structure cannot express (a
  mode hop, a step of SF) is left in the residual.
  Raw parameters of the summary enter too when the summary gives their standard errors
  ("params_se"): then a unit's own estimation noise is known.
- A slower thermal part, from the recorded step series (`prior.slow_part`): each unit's
  effective one-node time constant, its SF curve's misfit to the others' and its
  chi-square against the design's prior learned from the others (one-sided); only when
  every unit's logs hold a soak of 30 min or more after a ramp (a 2 h loop's 20 min soaks
  cannot show it: the note says so).
- Each unit against the others of the line (leave one out): z = (x - mean) / sqrt(s^2 -
  the others' mean se^2 + se^2 + s^2 / k) (k others, s their standard deviation, se the
  standard errors, 0 where not given): a t statistic for a line of normal units. The
  threshold on |z| is the (1 - alpha' / P) quantile of the largest |z| of N normal units
  (Monte Carlo of Gaussian lines, a fixed seed, the quantile taken 10 % further out for
  its error), alpha' = alpha / 2 for the one-sided features (the residual, the slow part's)
  and for the other P features (alpha when only one kind is there): a line of normal units
  gives any flag with chance at most alpha (exact over the units, Bonferroni over the
  features; correlated features make it conservative).
- The farthest unit beyond the threshold is flagged and leaves the reference; the others
  are compared again, at the threshold of a line of that many (one defect does not hide a
  second, and the units left keep the stated rate).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache

import numpy as np

from fogsf import __version__
from fogsf.errors import UserError
from fogsf.fleet.names import shown
from fogsf.fleet.plateau_unit import is_plateau_unit
from fogsf.fleet.records import UnitRecord, structure_of
from fogsf.fleet.schema import cached, state_of
from fogsf.fleet.store import keep_quietly, open_store
from fogsf.prior.slow_part import SLOW, line_features

DEFAULT_FALSE_ALARM = 0.01
MIN_UNITS = 5  # fewer: the spread cannot be told from the units, nothing is checked
RESIDUAL = "fit.log_residual"  # one-sided: a unit fitting better than the line is no defect
NULL_DRAWS = 100_000  # Monte Carlo draws of the threshold (per line size and level)
# the threshold's quantile taken at 1 - MC_MARGIN alpha / P: the Monte Carlo's error in the
# tail (about +/-4 % of alpha at NULL_DRAWS) must not put the rate above alpha
MC_MARGIN = 0.9


@dataclass
class Outlier:
    unit: str
    why: str
    kind: str  # "structure" or "parameters"
    z: float = math.nan


@dataclass
class CheckResult:
    units: int
    structure: str | None
    parameters: list[str]
    false_alarm: float
    threshold_z: float
    outliers: list[Outlier] = field(default_factory=list)
    z: dict[str, dict[str, float]] = field(default_factory=dict)  # unit -> feature -> z
    note: str = ""
    threshold_residual_z: float = math.nan  # the residual's (one-sided), when compared
    compared: int | None = None  # the units compared, when some are left out (plateau units)

    @property
    def flagged(self) -> set[str]:
        return {o.unit for o in self.outliers}

    def as_dict(self) -> dict:
        return {"outliers": [{"unit": o.unit, "why": o.why} for o in self.outliers],
                "units": self.units, "structure": self.structure,
                "parameters": self.parameters, "false_alarm": self.false_alarm,
                "threshold_z": self.threshold_z,
                "threshold_residual_z": self.threshold_residual_z, "z": self.z,
                "note": self.note, "compared": self.units if self.compared is None
                else self.compared}

    def to_cache(self) -> dict:
        """Everything, for the fleet's cache (`checked`); `from_cache` reads it back."""
        d = self.as_dict()
        d["outliers"] = [vars(o) for o in self.outliers]
        return d

    @classmethod
    def from_cache(cls, d: dict) -> CheckResult:
        known = {f.name for f in fields(cls)}  # a later fogsf's keys are not this one's
        d = {k: v for k, v in d.items() if k in known}
        d["outliers"] = [Outlier(**o) for o in d["outliers"]]
        return cls(**d)

    def message(self) -> str:
        compared = math.isfinite(self.threshold_z)
        head = f"{self.units} unit{'s' if self.units != 1 else ''}" + (
            f", {self.compared} compared" if self.compared not in (None, self.units) else "")
        lines = [f"{head}; the line's structure "
                 f"{self.structure or '-'}; " + (
                     f"{len(self.parameters)} features compared; false-alarm rate "
                     f"{self.false_alarm:g} for the whole line (|z| > {self.threshold_z:.2f}"
                     + (f", the residual's z > {self.threshold_residual_z:.2f}"
                        if math.isfinite(self.threshold_residual_z) else "") + ")"
                     if compared else "no features compared")]
        if self.note:
            lines.append(self.note)
        if not self.outliers:  # a line too small to compare is not said to pass
            lines.append("no unit unlike the line" if compared else "no unit checked")
        lines += [f"  {o.unit}: {o.why}" for o in self.outliers]
        return "\n".join(lines)


def _flatten(prefix: str, x: object, out: dict[str, float]) -> None:
    if isinstance(x, bool):
        return
    if isinstance(x, (int, float)):
        if math.isfinite(float(x)):
            out[prefix] = float(x)
    elif isinstance(x, dict):
        for k, v in x.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            _flatten(f"{prefix}[{i}]", v, out)


def unit_features(rec: UnitRecord) -> tuple[dict[str, float], dict[str, float]]:
    """A unit's features (dotted names) and their standard errors (0 where not known): the
    response on the reference program, and the summary's parameters that have standard
    errors."""
    feats: dict[str, float] = {}
    _flatten("response", rec.figures.get("response_ppm", {}), feats)
    ratio = rec.figures.get("train_rms_over_floor")
    if isinstance(ratio, (int, float)) and ratio > 0 and math.isfinite(ratio):
        feats[RESIDUAL] = math.log(ratio)
    se: dict[str, float] = {}
    if rec.summary.get("params_se"):
        params: dict[str, float] = {}
        _flatten("params", rec.summary.get("params", {}), params)
        _flatten("params", rec.summary["params_se"], se)
        feats.update({k: v for k, v in params.items() if k in se})
    return feats, {k: abs(se.get(k, 0.0)) for k in feats}


structure_label = structure_of


def _loo_z(x: np.ndarray, se: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """z of every unit (last axis) against the reference units other than itself.
    x, se: [..., N]; ref: [N] bool. O(N) along the last axis: the others' sums are the
    reference's sums less the unit's own (taken about the reference's mean, so that the
    variance's difference of sums loses no digits)."""
    r = ref.astype(np.float64)
    n_ref = float(r.sum())
    k = n_ref - r  # each unit's others: the reference less itself
    center = (x * r).sum(axis=-1, keepdims=True) / n_ref
    xc = x - center
    s1 = (xc * r).sum(axis=-1, keepdims=True) - r * xc
    s2 = (xc * xc * r).sum(axis=-1, keepdims=True) - r * xc * xc
    e2 = (se * se * r).sum(axis=-1, keepdims=True) - r * se * se
    mean = s1 / k
    var = np.maximum(s2 - k * mean * mean, 0.0) / (k - 1.0)
    design = np.maximum(var - e2 / k, 0.0)
    scale = np.sqrt(design + se * se + var / k)
    tiny = 1e-12 * np.maximum(np.abs(mean + center), 1.0)
    return (xc - mean) / np.maximum(scale, tiny)


# Rows of Gaussian lines drawn at once: memory stays flat in the line's size (about
# NULL_CHUNK_VALUES doubles an array), the draws the same whatever the chunk (one stream).
NULL_CHUNK_VALUES = 1_000_000


@lru_cache(maxsize=4)
def null_maxima(n_units: int) -> tuple[np.ndarray, np.ndarray]:
    """The null distribution of a line of `n_units` normal units: the largest leave-one-out
    |z| and the largest z of NULL_DRAWS Gaussian lines (Monte Carlo, seed 0), each sorted.

    In a line without standard errors a unit's z is an increasing odd function of its
    deviation d from the line's mean (n units, S the sum of squared deviations):
    x - mean_others = n d / (n - 1), (n - 2) s_others^2 = S - n d^2 / (n - 1), so
    z = (n d / (n - 1)) / sqrt(s_others^2 n / (n - 1)): the largest z is that of the largest
    d, the largest |z| that of the largest |d| (what `_loo_z` gives, read off in O(N))."""
    rng = np.random.default_rng(0)
    n = float(n_units)
    rows = max(1, NULL_CHUNK_VALUES // max(1, n_units))
    two, one = np.empty(NULL_DRAWS), np.empty(NULL_DRAWS)

    def z_of(d: np.ndarray, ss: np.ndarray) -> np.ndarray:
        var = np.maximum(ss - n * d * d / (n - 1.0), 0.0) / (n - 2.0)
        scale = np.sqrt(var * n / (n - 1.0))
        return (n * d / (n - 1.0)) / np.maximum(scale, 1e-300)

    for start in range(0, NULL_DRAWS, rows):
        m = min(rows, NULL_DRAWS - start)
        x = rng.standard_normal((m, n_units))
        mean = x.mean(axis=-1)
        ss = x.var(axis=-1) * n
        hi, lo = x.max(axis=-1) - mean, mean - x.min(axis=-1)
        one[start:start + m] = z_of(hi, ss)
        two[start:start + m] = z_of(np.maximum(hi, lo), ss)
    two.sort()
    one.sort()
    return two, one


# The thresholds this process knows, by line size, feature count, level and side: they do
# not depend on the units, so `checked` keeps them in the fleet's cache for any state (an
# add then costs one Monte Carlo, of the new line size, not one a flagged unit).
NULL_KNOWN: dict[str, float] = {}


def null_threshold(n_units: int, n_features: int, alpha: float, one_sided: bool = False
                   ) -> float:
    """z threshold: the (1 - alpha / n_features) quantile of the largest leave-one-out |z|
    (z with `one_sided`) over `n_units` units of a Gaussian line (`null_maxima`)."""
    key = f"{n_units} {n_features} {float(alpha)!r} {int(one_sided)}"
    if key not in NULL_KNOWN:
        two, one = null_maxima(n_units)
        NULL_KNOWN[key] = float(np.quantile(one if one_sided else two,
                                            1.0 - MC_MARGIN * alpha / max(1, n_features)))
    return NULL_KNOWN[key]


def one_sided(name: str) -> bool:
    """Only a larger value flags: the residual, and the slow-part features (a slower
    response, a curve farther from the line's: what a slower part does)."""
    return name == RESIDUAL or name.startswith(SLOW)


def thresholds(n_units: int, names: list[str], alpha: float) -> np.ndarray:
    """Each feature's threshold for a line of `n_units`: alpha shared by Bonferroni, half of
    it to the one-sided features (the residual, the slow part's) when they are there
    beside others, half to the rest."""
    ones = [k for k in names if one_sided(k)]
    if not ones or len(ones) == len(names):
        return np.full(len(names), null_threshold(n_units, len(names), alpha, bool(ones)))
    rest = null_threshold(n_units, len(names) - len(ones), alpha / 2)
    res = null_threshold(n_units, len(ones), alpha / 2, True)
    return np.array([res if one_sided(k) else rest for k in names])


def check_fleet(units: list[UnitRecord], false_alarm: float = DEFAULT_FALSE_ALARM
                ) -> CheckResult:
    """The units unlike the line (see the module's docstring); plateau units left out and
    named in the note: the check compares SF responses over time, which a table does not
    give."""

    if not 0.0 < false_alarm < 1.0:
        raise UserError(f"--false-alarm must lie in (0, 1), got {false_alarm:g}")
    plateau = sorted(u.unit for u in units if is_plateau_unit(u))
    if not plateau:
        return _with_prior_note(_check_line(units, false_alarm), units)
    result = _with_prior_note(
        _check_line([u for u in units if not is_plateau_unit(u)], false_alarm), units)
    names = ", ".join(shown(sn) for sn in plateau[:5]) + (" ..." if len(plateau) > 5 else "")
    left = (f"{len(plateau)} plateau unit(s) left out ({names}): the check compares units by "
            "their SF response over time, which plateau tables do not give")
    return replace(result, units=len(units), compared=result.units,
                   note="; ".join(x for x in (left, result.note) if x))


def under_prior(u: UnitRecord) -> bool:
    """A unit `train --prior` fitted under the design's prior: its structure is the
    prior's, not one its logs chose, so it neither sets the line's nor is flagged for it."""
    prior = (u.fitted_with.get("options") or {}).get("prior")
    return isinstance(prior, dict) and bool(prior.get("used"))


def _with_prior_note(result: CheckResult, units: list[UnitRecord]) -> CheckResult:
    other = [u.unit for u in units if under_prior(u) and structure_label(u) != result.structure]
    if not other or result.structure is None:
        return result
    said = (f"{len(other)} unit(s) fitted under the design's prior with its structure "
            f"({', '.join(shown(sn) for sn in other[:5])}{' ...' if len(other) > 5 else ''}): "
            "not compared")
    return replace(result, note="; ".join(x for x in (result.note, said) if x))


def _check_line(units: list[UnitRecord], false_alarm: float) -> CheckResult:
    n = len(units)
    own = [u for u in units if not under_prior(u)] or units  # the structures logs chose
    counts = Counter(structure_label(u) for u in own)
    if n < MIN_UNITS:
        return CheckResult(n, counts.most_common(1)[0][0] if counts else None, [],
                           false_alarm, math.inf,
                           note=f"nothing checked: {n} unit(s), the line's spread needs at "
                                f"least {MIN_UNITS}")
    line, n_line = counts.most_common(1)[0]
    if 2 * n_line < len(own):
        return CheckResult(n, None, [], false_alarm, math.inf,
                           note="nothing checked: no structure is shared by half the units "
                                f"({', '.join(f'{s} x{c}' for s, c in counts.most_common())})")
    outliers = [Outlier(u.unit, f"structure {structure_label(u)}, the line's is {line} "
                                f"({n_line} of {len(own)} units)", "structure")
                for u in own if structure_label(u) != line]
    same = [u for u in units if structure_label(u) == line]
    feats = [unit_features(u) for u in same]
    slow, slow_se, slow_note = line_features([u.summary for u in same])
    feats = [({**f, **g}, {**e, **h}) for (f, e), g, h in zip(feats, slow, slow_se, strict=True)]
    names = sorted(set.intersection(*(set(f) for f, _ in feats)))
    if len(same) < MIN_UNITS or not names:
        return CheckResult(n, line, names, false_alarm, math.inf, outliers,
                           note="; ".join(x for x in (
                               f"features not checked: {len(same)} unit(s) of the line's "
                               f"structure with {len(names)} common feature(s)", slow_note) if x))
    x = np.array([[f[k] for k in names] for f, _ in feats]).T  # [P, N]
    se = np.array([[s[k] for k in names] for _, s in feats]).T
    thr = thresholds(len(same), names, false_alarm)
    ref = np.ones(len(same), dtype=bool)
    side = np.array([one_sided(k) for k in names])
    limit = np.tile(thr[:, None], (1, len(same)))  # the thresholds each unit was flagged at
    while ref.sum() > MIN_UNITS:  # flag the farthest unit, then compare the rest again
        z = _loo_z(x, se, ref)
        z[side] = np.maximum(z[side], 0.0)
        t = thresholds(int(ref.sum()), names, false_alarm)  # for a line of that many
        worst = np.where(ref, np.max(np.abs(z) / t[:, None], axis=0), 0.0)
        if worst.max() <= 1.0:
            break
        j = int(np.argmax(worst))
        ref[j], limit[:, j] = False, t
    z = _loo_z(x, se, ref)
    z[side] = np.maximum(z[side], 0.0)
    for j in np.flatnonzero(~ref).tolist():
        ratio = np.abs(z[:, j]) / limit[:, j]
        far = [i for i in np.argsort(-ratio) if ratio[i] > 1.0]
        parts = []
        for i in far[:3]:
            others = x[i, ref]
            parts.append(f"{names[i]} {x[i, j]:.4g} (the line's {others.mean():.4g} +/- "
                         f"{others.std(ddof=1):.2g}, z {z[i, j]:+.1f} > {limit[i, j]:.1f})")
        more = f" and {len(far) - 3} more" if len(far) > 3 else ""
        outliers.append(Outlier(same[j].unit, "outside the line's spread: "
                                + "; ".join(parts) + more, "parameters",
                                float(np.max(np.abs(z[:, j])))))
    zmap = {u.unit: {k: round(float(z[i, j]), 3) for i, k in enumerate(names)}
            for j, u in enumerate(same)}
    if slow_note == "" and not any(k.startswith(SLOW) for k in names):
        slow_note = "slower thermal part not checked: the units' programs differ"
    return CheckResult(n, line, names, false_alarm, float(np.max(thr)), outliers, zmap,
                       note=slow_note,
                       threshold_residual_z=float(thr[names.index(RESIDUAL)])
                       if RESIDUAL in names
                       else math.nan)


# what a cached check was computed by: a result another fogsf, or another method, computed
# is not read (bump it when the check's method changes)
CHECK_METHOD = 8


def checked(fleet: str, false_alarm: float = DEFAULT_FALSE_ALARM, with_units: bool = False
            ) -> tuple[CheckResult, list[UnitRecord] | None, str]:
    """`check_fleet` of the fleet at `fleet` (a path or URL): read from the fleet's cache
    when it holds the result for the fleet's state and this level, else computed from its
    units and kept there (`fleet.schema`). Returns the result, the units (read only when
    `with_units` or not cached) and the fleet's location as shown."""
    key = f"fogsf {__version__}; method {CHECK_METHOD}; false alarm {float(false_alarm)!r}"
    null_key = f"fogsf {__version__}; method {CHECK_METHOD}; draws {NULL_DRAWS}"
    with open_store(fleet, "read") as store, store.snapshot():
        state = state_of(store)
        hit = cached(store, "check", key, state)
        units = store.units() if with_units or hit is None else None
        known = cached(store, "null", null_key, None) if hit is None else None
        where = store.location
    if hit is not None:
        return CheckResult.from_cache(json.loads(hit)), units, where
    assert units is not None
    NULL_KNOWN.update(json.loads(known or "{}"))
    had = len(NULL_KNOWN)
    result = check_fleet(units, false_alarm)
    keep_quietly(fleet, "check", key, state, json.dumps(result.to_cache()))
    if len(NULL_KNOWN) > had:
        keep_quietly(fleet, "null", null_key, state, json.dumps(NULL_KNOWN))
    return result, units, where
