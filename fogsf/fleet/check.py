"""Units unlike the line (`fogsf fleet check`): which units' structure or parameters lie
outside the design's spread, and why, at a stated false-alarm rate.

Reads only the units' records (their `summary`: "structure" and "params", optionally
"params_se", each parameter's standard error from the unit's own fit):

- structure: the line's structure is the one most units have (at least half of them); a unit
  with another (node count, law terms) is flagged;
- parameters: for each numeric parameter every unit of the line's structure has, each unit
  is compared with the others (leave-one-out): centre their median, spread 1.4826 x their
  median absolute deviation, the unit's own estimation noise added in quadrature (and the
  others' typical noise taken out of the spread), z = (x - centre) / sqrt(spread^2 + se^2).
  The threshold on |z| is the (1 - alpha / P) quantile of the largest |z| over N units of
  a line of normal units (Gaussian parameters; P parameters, N units; Monte Carlo, a fixed
  seed): a line of normal units gives a flag with chance at most alpha (Bonferroni over the
  parameters, exact over the units; correlated parameters make it conservative).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from fogsf.fleet.records import UnitRecord

DEFAULT_FALSE_ALARM = 0.01
MIN_UNITS = 5  # fewer: the spread cannot be told from the units, nothing is checked
MAD_SCALE = 1.4826  # MAD -> standard deviation of a Gaussian
NULL_DRAWS = 40_000  # Monte Carlo draws of the threshold (per line size and level)


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
    z: dict[str, dict[str, float]] = field(default_factory=dict)  # unit -> parameter -> z
    note: str = ""

    @property
    def flagged(self) -> set[str]:
        return {o.unit for o in self.outliers}

    def as_dict(self) -> dict:
        return {"outliers": [{"unit": o.unit, "why": o.why} for o in self.outliers],
                "units": self.units, "structure": self.structure,
                "parameters": self.parameters, "false_alarm": self.false_alarm,
                "threshold_z": self.threshold_z, "z": self.z, "note": self.note}

    def message(self) -> str:
        head = (f"{self.units} units; the line's structure {self.structure or '-'}; "
                f"{len(self.parameters)} parameters compared; false-alarm rate "
                f"{self.false_alarm:g} for the whole line (|z| > {self.threshold_z:.2f})")
        lines = [head]
        if self.note:
            lines.append(self.note)
        if not self.outliers:
            lines.append("no unit unlike the line")
        for o in self.outliers:
            lines.append(f"  {o.unit}: {o.why}")
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


def unit_parameters(rec: UnitRecord) -> tuple[dict[str, float], dict[str, float]]:
    """A unit's parameters and their standard errors (0 where not given), flattened to
    dotted names."""
    params: dict[str, float] = {}
    se: dict[str, float] = {}
    _flatten("", rec.summary.get("params", {}), params)
    _flatten("", rec.summary.get("params_se", {}), se)
    return params, {k: abs(se.get(k, 0.0)) for k in params}


def structure_label(rec: UnitRecord) -> str:
    s = rec.summary.get("structure", "?")
    return s if isinstance(s, str) else str(s)


@lru_cache(maxsize=64)
def null_threshold(n_units: int, n_params: int, alpha: float) -> float:
    """|z| threshold: the (1 - alpha / n_params) quantile of max over `n_units` of the
    leave-one-out robust |z| of a Gaussian line (Monte Carlo, seed 0)."""
    rng = np.random.default_rng(0)
    q = 1.0 - alpha / max(1, n_params)
    maxima = []
    for _ in range(max(1, NULL_DRAWS // 10_000)):
        x = rng.standard_normal((10_000, n_units))
        maxima.append(np.max(np.abs(_loo_z(x, np.zeros_like(x), 1e-12)), axis=1))
    return float(np.quantile(np.concatenate(maxima), q))


def _loo_z(x: np.ndarray, se: np.ndarray, floor: float | np.ndarray) -> np.ndarray:
    """Leave-one-out robust z of each entry of the rows of x [R, N] (N units; se: their
    standard errors, [R, N]; floor: a least scale, so that a parameter that barely varies
    divides by no zero)."""
    n = x.shape[-1]
    idx = np.array([[j for j in range(n) if j != i] for i in range(n)])  # [N, N-1]
    others = x[..., idx]  # [R, N, N-1]
    centre = np.median(others, axis=-1)
    mad = MAD_SCALE * np.median(np.abs(others - centre[..., None]), axis=-1)
    noise = np.median(se[..., idx] ** 2, axis=-1)  # the others' typical estimation noise
    design2 = np.maximum(mad ** 2 - noise, 0.0)
    scale = np.sqrt(design2 + se ** 2 + np.square(floor))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (x - centre) / scale
    return np.where(scale > 0, z, np.where(x == centre, 0.0, np.inf))


def check_fleet(units: list[UnitRecord], false_alarm: float = DEFAULT_FALSE_ALARM
                ) -> CheckResult:
    """The units unlike the line (see the module's docstring)."""
    from fogsf.errors import UserError

    if not 0.0 < false_alarm < 1.0:
        raise UserError(f"--false-alarm must lie in (0, 1), got {false_alarm:g}")
    n = len(units)
    counts = Counter(structure_label(u) for u in units)
    if n < MIN_UNITS:
        return CheckResult(n, counts.most_common(1)[0][0] if counts else None, [],
                           false_alarm, math.inf,
                           note=f"nothing checked: {n} unit(s), the line's spread needs at "
                                f"least {MIN_UNITS}")
    line, n_line = counts.most_common(1)[0]
    outliers: list[Outlier] = []
    if 2 * n_line < n:
        return CheckResult(n, None, [], false_alarm, math.inf,
                           note="nothing checked: no structure is shared by half the units "
                                f"({', '.join(f'{s} x{c}' for s, c in counts.most_common())})")
    for u in units:
        s = structure_label(u)
        if s != line:
            outliers.append(Outlier(u.unit, f"structure {s}, the line's is {line} ({n_line} "
                                             f"of {n} units)", "structure"))
    same = [u for u in units if structure_label(u) == line]
    pars = [unit_parameters(u) for u in same]
    names = sorted(set.intersection(*(set(p) for p, _ in pars))) if pars else []
    if len(same) < MIN_UNITS or not names:
        return CheckResult(n, line, names, false_alarm, math.inf, outliers,
                           note=f"parameters not checked: {len(same)} unit(s) of the line's "
                                f"structure with {len(names)} common parameter(s)")
    x = np.array([[p[k] for k in names] for p, _ in pars]).T  # [P, N]
    se = np.array([[s[k] for k in names] for _, s in pars]).T
    varied = np.ptp(x, axis=1) > 0  # a parameter the structure fixes (a grid) says nothing
    names = [k for k, v in zip(names, varied, strict=True) if v]
    x, se = x[varied], se[varied]
    if not names:
        return CheckResult(n, line, [], false_alarm, math.inf, outliers,
                           note="parameters not checked: none varies between units")
    floor = 1e-9 * np.maximum(np.abs(np.median(x, axis=1)), 1e-12)[:, None]
    z = _loo_z(x, se, floor)
    thr = null_threshold(len(same), len(names), false_alarm)
    zmap = {u.unit: {k: float(z[i, j]) for i, k in enumerate(names)}
            for j, u in enumerate(same)}
    for j, u in enumerate(same):
        far = [i for i in np.argsort(-np.abs(z[:, j])) if abs(z[i, j]) > thr]
        if not far:
            continue
        parts = []
        for i in far[:3]:
            others = np.delete(x[i], j)
            centre = float(np.median(others))
            spread = MAD_SCALE * float(np.median(np.abs(others - centre)))
            parts.append(f"{names[i]} = {x[i, j]:.4g} (the others {centre:.4g} +/- "
                         f"{spread:.2g}, z = {z[i, j]:+.1f})")
        more = f" and {len(far) - 3} more" if len(far) > 3 else ""
        outliers.append(Outlier(u.unit, "parameters outside the line's spread: "
                                + "; ".join(parts) + more, "parameters",
                                float(np.max(np.abs(z[:, j])))))
    return CheckResult(n, line, names, false_alarm, thr, outliers, zmap)

