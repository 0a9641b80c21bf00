"""IEEE Std 952 figures of a plateau table (logs/plateau_table.py) against temperature: the
rows grouped by board temperature, each group's SF, nonlinearity, asymmetry and bias from
the fit of `pairs.steps_of_means` (the one a sample log's staircase gets), and the whole
table's from the same fit with the SF and bias as polynomials of temperature."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fogsf.logs.measure.pairs import RateSteps, steps_of_means, thermal_basis, thermal_columns
from fogsf.logs.measure.plateaus import DPS_TO_DPH

# a temperature group: the rows within this of its coolest row. A rig's plateau means at one
# chamber set point scatter by tenths of a degree; set points lie degrees apart.
TEMP_GROUP_C = 1.0


def temperature_groups(temp: np.ndarray) -> np.ndarray:
    """Per row, its group's index (groups from the coolest up): a group holds the rows less
    than TEMP_GROUP_C above its coolest row."""
    order = np.argsort(temp, kind="stable")
    label = np.empty(temp.size, dtype=int)
    k, base = -1, -np.inf
    for i in order:
        if temp[i] >= base + TEMP_GROUP_C:
            k, base = k + 1, float(temp[i])
        label[i] = k
    return label


@dataclass
class GroupFigures:
    """One temperature group's figures; NaN where its rates cannot give one (nonlinearity
    and asymmetry need two |rates| in both directions, the SF a rate other than 0)."""

    temp_c: float  # the group's mean board temperature
    temp_range_c: tuple[float, float]
    plateaus: int  # rows, bias plateaus included
    sf_ppm: float  # the SF vs nominal
    bias_dps: float
    nonlinearity_ppm: float = float("nan")  # ppm of full scale
    asymmetry_ppm: float = float("nan")

    def as_dict(self) -> dict:
        return {"temp_c": self.temp_c, "temp_range_c": list(self.temp_range_c),
                "plateaus": self.plateaus, "sf_ppm": _num(self.sf_ppm),
                "bias_dph": _num(self.bias_dps * DPS_TO_DPH),
                "sf_nonlinearity_ppm_fs": _num(self.nonlinearity_ppm),
                "sf_asymmetry_ppm": _num(self.asymmetry_ppm)}


@dataclass
class TableFigures:
    """A plateau table's figures: per temperature group, and the whole table's fit."""

    groups: list[GroupFigures]
    overall: RateSteps | None  # None: the table's rates give no staircase
    sf_drift_ppm_per_c: float | None  # a line through the groups' SF; None under 2 groups
    bias_drift_dph_per_c: float | None
    rates_dps: list[float] = field(default_factory=list)  # the table's rates

    def as_dict(self) -> dict:
        return {"groups": [g.as_dict() for g in self.groups],
                "overall": None if self.overall is None else self.overall.as_dict(),
                "sf_drift_ppm_per_c": self.sf_drift_ppm_per_c,
                "bias_drift_dph_per_c": self.bias_drift_dph_per_c,
                "rates_dps": self.rates_dps}


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def group_figures(r: np.ndarray, m: np.ndarray, temp: np.ndarray) -> GroupFigures:
    """One group's figures from its rows (rate, mean output less earth rate, temperature)."""
    steps = steps_of_means(r, m, temp)
    head = (float(temp.mean()), (float(temp.min()), float(temp.max())), int(r.size))
    if steps is not None:
        return GroupFigures(*head, steps.sf_ppm, steps.bias_dps, steps.nonlinearity_ppm,
                            steps.asymmetry_ppm)
    if not (r != 0.0).any():  # bias plateaus only
        return GroupFigures(*head, float("nan"), float(m.mean()))
    # one |rate| or one direction: a line gives the SF and the bias, nothing more
    (sf, bias), *_ = np.linalg.lstsq(np.column_stack([r, np.ones_like(r)]), m, rcond=None)
    if not (r == 0.0).any() and np.unique(r).size < 2:  # one rate, no bias plateau
        sf, bias = float(np.mean(m / r)), float("nan")
    return GroupFigures(*head, (float(sf) - 1.0) * 1e6, float(bias))


def table_figures(r: np.ndarray, m: np.ndarray, temp: np.ndarray) -> TableFigures:
    """The figures of a table's measuring rows: commanded rate `r`, mean output less the
    earth rate `m`, mean board temperature `temp`."""
    label = temperature_groups(temp)
    # k temperature groups with the table turning tell the SF's k - 1 powers of temperature
    # apart, whatever their span (more would be fitted to nothing)
    degree = max(0, np.unique(label[r != 0.0]).size - 1)
    at = referred(r, m, temp, label, degree)
    groups = [group_figures(r[label == k], at[label == k], temp[label == k])
              for k in range(int(label.max()) + 1)]
    return TableFigures(groups, steps_of_means(r, m, temp, degree),
                        _drift([g.temp_c for g in groups], [g.sf_ppm for g in groups]),
                        _drift([g.temp_c for g in groups],
                               [g.bias_dps * DPS_TO_DPH for g in groups]),
                        sorted({float(x) for x in r}))


def referred(r: np.ndarray, m: np.ndarray, temp: np.ndarray, label: np.ndarray,
             max_degree: int) -> np.ndarray:
    """Every row's output moved to its group's mean temperature by the whole table's thermal
    terms (the fit of `steps_of_means`, one slope per sign): the scatter of temperature
    inside a group would otherwise read as bias (0.2 C at 2 ppm/C and 150 deg/s: 0.2 deg/h)."""
    basis = thermal_basis(temp, max_degree)
    cols = thermal_columns(r, temp, basis)
    if not cols:
        return m
    x = np.column_stack([np.where(r > 0, r, 0.0), np.where(r < 0, r, 0.0), np.ones_like(r),
                         *cols])
    coef, *_ = np.linalg.lstsq(x, m, rcond=None)
    mean_t = np.array([temp[label == k].mean() for k in range(int(label.max()) + 1)])
    there = np.column_stack(thermal_columns(r, mean_t[label], basis))
    return m - (np.column_stack(cols) - there) @ coef[3:]


def _drift(temp: list[float], y: list[float]) -> float | None:
    """The slope of a line through the groups' (T, y) that have a y; None under two."""
    t, v = np.asarray(temp), np.asarray(y)
    ok = np.isfinite(v)
    if ok.sum() < 2:
        return None
    return float(np.polyfit(t[ok], v[ok], 1)[0])
