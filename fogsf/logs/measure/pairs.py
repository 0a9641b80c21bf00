"""+/- pairs and rate steps (IEEE Std 952): the SF and the bias from adjacent plateaus of
opposite sign and equal |rate|, fitted with their neighbours, and a staircase's SF per rate
step with its nonlinearity and asymmetry."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.measure.plateaus import (
    BLOCK_SAMPLES,
    DPS_TO_DPH,
    MIN_PLATEAU_S,
    SETTLE_S,
    T_REF_C,
    settled_plateaus,
)
from fogsf.logs.read import columns
from fogsf.logs.read.columns import (
    Column,
    all_equal,
    derived,
    exact_sum,
    is_lazy,
    span_means,
    stand_in,
)

PAIR_RATE_TOL = 0.01  # |r1| and |r2| within 1 % (and 1e-6 deg/s) make a +/- pair
MIN_RATE_LEVELS = 2  # |rates| (each in both directions) that nonlinearity and asymmetry need


@dataclass
class PlateauPairs:
    """SF and bias separated by adjacent +/- rate plateaus (one entry per pair)."""

    t_s: np.ndarray
    temp_c: np.ndarray
    sf_ratio: np.ndarray
    bias_dps: np.ndarray
    rate_dps: np.ndarray  # |rate| of the pair
    # each pair's bias as weights on the plateau means it is made of: (plateau indices,
    # weights), and every plateau's sample count (what its mean's noise goes as 1/n of)
    bias_weights: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    plateau_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # the [start, stop) spans each plateau's mean averages ([k, 3]: start, stop, plateau;
    # a plateau cut by a stall has two) and every plateau's commanded rate (deg/s)
    plateau_spans: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    plateau_rate: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def minus_sf(self, sf_ppm: Column) -> PlateauPairs:
        """The pairs with an SF series (ppm per sample, e.g. the SF model's prediction) taken
        off every plateau's mean before the fit: the bias the pair's fit gives then, which
        is free of the SF moving between its plateaus as far as the series follows it.
        The fit is linear in the plateau means and blind to an SF constant over a group (its
        bias weights sum to zero against the rates), so this is bias - sum_j g_j r_j s_j.
        A staircase pair has no neighbour at its own rate to cancel that drift: 1 ppm
        between 16 s plateaus at 100 deg/s is 0.18 deg/h of bias."""
        if not len(self):
            return self
        sp = self.plateau_spans
        n = (sp[:, 1] - sp[:, 0]).astype(np.float64)
        sums = span_means(sf_ppm, sp[:, 0], sp[:, 1]) * n  # over the samples each mean has
        k = self.plateau_rate.shape[0]
        s = (np.bincount(sp[:, 2], sums, k) / np.bincount(sp[:, 2], n, k)) * 1e-6
        rs = self.plateau_rate * s
        shift = np.array([float(np.dot(g, rs[idx])) for idx, g in self.bias_weights])
        return replace(self, bias_dps=self.bias_dps - shift)

    def bias_drift_dph_per_c(self) -> float | None:
        """Slope of the pairs' bias over their board temperature (deg/h per C); None when
        the temperature spans less than 1 C or there are fewer than 3 pairs."""
        if len(self) < 3 or np.ptp(self.temp_c) < 1.0:
            return None
        return float(np.polyfit(self.temp_c, self.bias_dps * DPS_TO_DPH, 1)[0])


@dataclass
class _Plateau:
    start: int
    stop: int
    rate: float  # mean commanded rate
    mean: float  # mean of gyro - earth
    t_s: float
    temp_c: float
    n: int  # samples averaged (a plateau cut by a stall: both pieces)
    pieces: tuple[tuple[int, int], ...] = ()  # the [start, stop) spans averaged


def _plateau_means(log: ChamberLog, latitude_deg: float | None, settle_s: float
                   ) -> list[_Plateau]:
    """The settled plateaus' means; the pieces of one commanded plateau that rows measuring
    nothing (a stall, a disabled row) cut apart are one plateau again: a pair's fit needs
    its +/- neighbours at the usual distance, and two pieces close in time would read the SF
    drift from noise. gyro - earth is taken plateau by plateau (no log-long temporary)."""
    earth = log.earth(latitude_deg)
    out: list[_Plateau] = []
    for a, b in settled_plateaus(log, settle_s):
        if is_lazy(log.gyro_dps) and b - a > columns.READ_SAMPLES:  # a long plateau on disk
            out.append(_long_plateau(log, earth, a, b, out[-1] if out else None))
            if len(out) > 1 and out[-1].start == out[-2].start:
                del out[-2]  # merged into the one before
            continue
        rate = log.table_rate_dps[a:b]
        signal = log.gyro_dps[a:b] - earth[a:b]
        if out and all_equal(log.table_rate_dps, out[-1].stop - 1, a + 1, rate[0]):
            prev, n = out[-1], b - a  # same command all through the gap: merge
            tot = prev.n + n
            out[-1] = _Plateau(
                prev.start, b, prev.rate,
                (prev.mean * prev.n + float(signal.sum())) / tot,
                (prev.t_s * prev.n + float(log.time_s[a:b].sum())) / tot,
                (prev.temp_c * prev.n + float(log.temp_c[a:b].sum())) / tot, tot,
                (*prev.pieces, (a, b)))
            continue
        out.append(_Plateau(a, b, float(rate.mean()), float(signal.mean()),
                            float(log.time_s[a:b].mean()), float(log.temp_c[a:b].mean()),
                            b - a, ((a, b),)))
    return out


def _long_plateau(log: ChamberLog, earth: np.ndarray, a: int, b: int,
                  prev: _Plateau | None) -> _Plateau:
    """`_plateau_means`' entry for a plateau [a, b) too long to read at once (a log on
    disk): the same sums, read in pieces (numpy's pairwise order); merged with `prev` when
    the command holds through the gap (the merged plateau has prev's start)."""
    def total(col) -> float:  # noqa: ANN001
        return exact_sum(lambda x, y: np.asarray(col[x:y]), a, b)

    signal = exact_sum(lambda x, y: log.gyro_dps[x:y] - earth[x:y], a, b)
    first = float(log.table_rate_dps[a])
    if prev is not None and all_equal(log.table_rate_dps, prev.stop - 1, a + 1, first):
        tot = prev.n + b - a
        return _Plateau(prev.start, b, prev.rate, (prev.mean * prev.n + signal) / tot,
                        (prev.t_s * prev.n + total(log.time_s)) / tot,
                        (prev.temp_c * prev.n + total(log.temp_c)) / tot, tot,
                        (*prev.pieces, (a, b)))
    n = b - a
    return _Plateau(a, b, total(log.table_rate_dps) / n, signal / n, total(log.time_s) / n,
                    total(log.temp_c) / n, n, ((a, b),))


def _is_pair(p: _Plateau, q: _Plateau) -> bool:
    if np.sign(p.rate) == np.sign(q.rate) or p.rate == 0 or q.rate == 0:
        return False
    big = max(abs(p.rate), abs(q.rate))
    return abs(abs(p.rate) - abs(q.rate)) <= PAIR_RATE_TOL * big + 1e-6


def _pair_fit(group: list[_Plateau], tc: float) -> tuple[float, float, np.ndarray]:
    """(SF ratio, bias) at time `tc` from a pair and its +/- neighbours: a least-squares fit
    of m = r (s0 + s1 tau) + b0 + b1 tau (tau = t - tc; with three plateaus no b1, with two
    neither s1 nor b1), each plateau weighted by its length (a stall shortens one). With
    both neighbours at +/-r and equal lengths this is the bias (m0 + 3 m1 + 3 m2 + m3) / 8
    (signs alternating), which cancels an SF that drifts linearly, even
    quadratically, in time (the SF moving between the two plateaus of a pair on a ramp
    would otherwise read as bias: 5 ppm at 100 deg/s is 0.9 deg/h) and a linear bias drift.
    The third value: the bias as weights on the group's plateau means."""
    r = np.array([p.rate for p in group])
    m = np.array([p.mean for p in group])
    tau = np.array([p.t_s for p in group]) - tc
    cols = [r, np.ones_like(r)]
    if len(group) >= 3:
        cols.append(r * tau)
    if len(group) >= 4:
        cols.append(tau)
    w = np.sqrt([p.n for p in group])  # a plateau's noise goes as 1/sqrt(n)
    a = np.column_stack(cols) * w[:, None]
    coef, *_ = np.linalg.lstsq(a, m * w, rcond=None)
    return float(coef[0]), float(coef[1]), np.linalg.pinv(a)[1] * w


def find_pairs(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> PlateauPairs | None:
    """The log's +/- pairs: adjacent settled plateaus of opposite sign and equal |rate|
    (PAIR_RATE_TOL), no plateau in two pairs; None without any. Each pair's SF and bias are
    at its centre time, from the pair and the +/- plateaus next to it (`_pair_fit`)."""
    pl = _plateau_means(log, latitude_deg, settle_s)
    out: list[tuple[float, float, float, float, float]] = []
    weights: list[tuple[np.ndarray, np.ndarray]] = []
    i = 0
    while i + 1 < len(pl):
        p, q = pl[i], pl[i + 1]
        if not _is_pair(p, q):
            i += 1
            continue
        idx = [i, i + 1]
        if i > 0 and _is_pair(pl[i - 1], p):
            idx.insert(0, i - 1)
        if i + 2 < len(pl) and _is_pair(q, pl[i + 2]):
            idx.append(i + 2)
        i += 2
        tc = 0.5 * (p.t_s + q.t_s)
        sf, bias, g = _pair_fit([pl[j] for j in idx], tc)
        weights.append((np.asarray(idx), g))
        out.append((tc, 0.5 * (p.temp_c + q.temp_c), sf, bias,
                    0.5 * (abs(p.rate) + abs(q.rate))))
    if not out:
        return None
    a = np.asarray(out)
    return PlateauPairs(t_s=a[:, 0], temp_c=a[:, 1], sf_ratio=a[:, 2], bias_dps=a[:, 3],
                        rate_dps=a[:, 4], bias_weights=weights,
                        plateau_n=np.array([p.n for p in pl], dtype=np.float64),
                        plateau_spans=np.array([[a, b, j] for j, p in enumerate(pl)
                                                for a, b in p.pieces], np.int64),
                        plateau_rate=np.array([p.rate for p in pl], dtype=np.float64))


def plateau_pairs(log: ChamberLog, latitude_deg: float | None = None,
                  settle_s: float = SETTLE_S) -> PlateauPairs:
    """`find_pairs`, refused when the log has none."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        raise UserError(f"{log.path}: no adjacent +/- table-rate plateaus of equal |rate| "
                        f"to pair (each at least {MIN_PLATEAU_S:g} s after the {settle_s:g} s "
                        "settle margin, --settle-s)")
    return pp


def bias_track(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> np.ndarray | None:
    """Per sample, the bias (deg/s) of the pairs at the sample's |table rate|, interpolated
    in time between their centres (held before the first and after the last); 0 at a |rate|
    without pairs (a pair's bias holds asymmetry x rate / 2: it is not moved to another
    rate). None for a log without pairs."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        return None
    levels = [(r, np.abs(pp.rate_dps - r) <= PAIR_RATE_TOL * r + 1e-6)
              for r in np.unique(pp.rate_dps)]

    def track(s: slice) -> np.ndarray:
        tab, t = np.asarray(log.table_rate_dps[s]), np.asarray(log.time_s[s])
        out = np.zeros(tab.shape[0])
        for r, at in levels:
            here = np.abs(np.abs(tab) - r) <= PAIR_RATE_TOL * r + 1e-6
            out[here] = np.interp(t[here], pp.t_s[at], pp.bias_dps[at])
        return out

    if is_lazy(log.time_s):  # a log on disk: computed where it is read
        return stand_in(derived(len(log), np.dtype(np.float64), track))
    out = np.zeros(len(log))
    for a in range(0, len(log), BLOCK_SAMPLES):  # no log-long temporaries
        s = slice(a, a + BLOCK_SAMPLES)
        out[s] = track(s)
    return out


@dataclass
class RateSteps:
    """SF per rate step of a staircase and IEEE Std 952's nonlinearity and asymmetry.

    A least-squares fit over every settled plateau's mean output m = (SF + a(T)) r + b + c(T)
    gives the line: a(T) and c(T), the SF's and the bias's thermal change, are polynomials
    in the plateau's board temperature T about `temp_c` (20 C when the plateaus span it,
    else their mean) of a degree the span allows (none under 1 C, a line under 5 C, a
    quadratic under 20 C, a cubic beyond: a staircase at several heater set points). SF+
    and SF- come from the same fit with a slope for each sign; the SF per step is at
    `temp_c`."""

    rates_dps: np.ndarray  # |rate| levels
    sf_pos_ppm: np.ndarray  # SF at +rate vs nominal, ppm (NaN: no plateau there)
    sf_neg_ppm: np.ndarray
    sf_ppm: float  # the line's slope vs nominal, ppm (at the log's mean temperature)
    bias_dps: float  # the separate-slope fit's intercept (the line's holds asymmetry too)
    nonlinearity_ppm: float  # max |level mean - line| / full-scale output, ppm
    asymmetry_ppm: float  # (SF+ - SF-) / mean SF, ppm (the separate-slope fit)
    temp_c: float = T_REF_C  # the board temperature the SF per step is at

    def as_dict(self) -> dict:
        return {"rates_dps": self.rates_dps.tolist(),
                "sf_pos_ppm": _nan_none(self.sf_pos_ppm), "sf_neg_ppm": _nan_none(self.sf_neg_ppm),
                "sf_ppm": self.sf_ppm, "bias_dph": self.bias_dps * DPS_TO_DPH,
                "sf_nonlinearity_ppm_fs": self.nonlinearity_ppm,
                "sf_asymmetry_ppm": self.asymmetry_ppm, "temp_c": self.temp_c}


def _nan_none(a: np.ndarray) -> list[float | None]:
    return [None if not np.isfinite(x) else float(x) for x in a]


def _rate_levels(rates: np.ndarray) -> np.ndarray:
    """Per plateau, the index of its |rate| level (levels within PAIR_RATE_TOL merged)."""
    mag = np.abs(rates)
    order = np.argsort(mag)
    level = np.empty(mag.size, dtype=int)
    k, base = -1, -np.inf
    for i in order:
        if mag[i] > base * (1 + PAIR_RATE_TOL) + 1e-6:
            k, base = k + 1, mag[i]
        level[i] = k
    return level


def rate_steps(log: ChamberLog, latitude_deg: float | None = None,
               settle_s: float = SETTLE_S) -> RateSteps | None:
    """The staircase figures (`RateSteps`) of a sample log's settled plateaus; None for a log
    with fewer than MIN_RATE_LEVELS |rates| or without both signs."""
    pl = _plateau_means(log, latitude_deg, settle_s)
    if not pl:
        return None
    return steps_of_means(np.array([p.rate for p in pl]), np.array([p.mean for p in pl]),
                          np.array([p.temp_c for p in pl]))


def steps_of_means(r: np.ndarray, m: np.ndarray, temp: np.ndarray,
                   max_degree: int | None = None) -> RateSteps | None:
    """`RateSteps` from plateau means: commanded rate `r`, mean output less the earth rate
    `m`, mean board temperature `temp` (a sample log's settled plateaus, or a plateau
    table's rows: both paths measure with this one fit). A zero-rate plateau (a table's bias
    plateau) enters both fits, where it pins the bias, but is no rate level. `max_degree`
    caps the thermal polynomials' (a table at k set points tells k - 1 powers of temperature
    apart, whatever its span). None with fewer than MIN_RATE_LEVELS |rates| or without both
    signs."""
    moving = r != 0.0
    rm = r[moving]
    if rm.size == 0:
        return None
    level = _rate_levels(rm)
    if level.max() + 1 < MIN_RATE_LEVELS or not ((rm > 0).any() and (rm < 0).any()):
        return None
    t0, thermal = _thermal_columns(r, temp, max_degree)
    one = np.ones_like(r)
    line_x = np.column_stack([r, one, *thermal])
    line, *_ = np.linalg.lstsq(line_x, m, rcond=None)
    split_x = np.column_stack([np.where(r > 0, r, 0.0), np.where(r < 0, r, 0.0), one, *thermal])
    split, *_ = np.linalg.lstsq(split_x, m, rcond=None)
    resid = (m - line_x @ line)[moving]
    sign = np.sign(rm)
    groups = [(level == k) & (sign == s) for k in range(level.max() + 1) for s in (-1, 1)]
    dev = max(abs(float(resid[g].mean())) for g in groups if g.any())
    # per plateau: SF with the split fit's bias and thermal terms taken off (the split fit's
    # intercept is the bias whatever the asymmetry; the line's holds asymmetry x rate / 2)
    bias = float(split[2])
    per = m - bias - (np.column_stack(thermal) @ split[3:] if thermal else 0.0)
    per_sf = (per[moving] / rm - 1.0) * 1e6
    levels = range(level.max() + 1)
    rates = np.array([np.abs(rm[level == k]).mean() for k in levels])

    def side(k: int, positive: bool) -> float:
        sel = (level == k) & ((rm > 0) if positive else (rm < 0))
        return float(per_sf[sel].mean()) if sel.any() else float("nan")

    pos = np.array([side(k, True) for k in levels])
    neg = np.array([side(k, False) for k in levels])
    sf = float(line[0])
    full_scale = abs(sf) * float(np.abs(rm).max())
    asym = float((split[0] - split[1]) / (0.5 * (split[0] + split[1]))) * 1e6
    return RateSteps(rates, pos, neg, (sf - 1.0) * 1e6, bias, dev / full_scale * 1e6, asym, t0)


def _thermal_columns(r: np.ndarray, temp: np.ndarray, max_degree: int | None = None
                     ) -> tuple[float, list[np.ndarray]]:
    """(T0, the SF's and the bias's change with board temperature in `rate_steps`): the
    columns of `thermal_columns` on the basis the plateaus' temperatures give."""
    basis = thermal_basis(temp, max_degree)
    return basis[0], thermal_columns(r, temp, basis)


def thermal_basis(temp: np.ndarray, max_degree: int | None = None
                  ) -> tuple[float, float, int]:
    """(T0, scale, degree) of the thermal polynomials: T0 is 20 C when the plateaus span it,
    else their mean; u = (T - T0) / scale spans +/-1; the degree goes by the span (0 under
    1 C, 1 under 5 C, 2 under 20 C, else 3): what the span can tell apart."""
    span = float(np.ptp(temp))
    t0 = T_REF_C if temp.min() <= T_REF_C <= temp.max() else float(temp.mean())
    degree = 0 if span < 1.0 else 1 if span < 5.0 else 2 if span < 20.0 else 3
    if max_degree is not None:  # what the plateaus' distinct temperatures tell apart
        degree = min(degree, max_degree)
    return t0, max(float(np.max(np.abs(temp - t0))), 1e-9), degree


def thermal_columns(r: np.ndarray, temp: np.ndarray, basis: tuple[float, float, int]
                    ) -> list[np.ndarray]:
    """Columns r u^k and u^k, k = 1..degree, at temperatures `temp` on `basis`."""
    t0, scale, degree = basis
    if degree == 0:
        return []
    u = (temp - t0) / scale
    powers = [u**k for k in range(1, degree + 1)]
    return [r * p for p in powers] + powers
