"""The design's prior: an empirical-Bayes model of a design's units.

From the step series of the fleet's units (`unit_fit.StepSeries`, kept in the fleet
database by `unit_summary`):
1. the structure: the node count K (1-3) is the one with the least misfit over the units
   (`choose_k`: each unit's fit at K on its own program, in sample, the median over units;
   the smallest K within STRUCTURE_TOLERANCE of the best);
2. every unit fitted at K, twice: once from the grid start, then from the fleet's median
   time constants, so every unit's node j is the design's node j;
3. units unlike the line left out: a unit whose fit lies outside the others' spread
   (robust Mahalanobis distance on a robust scale, `robust_keep`);
4. the population: mean mu of theta and its spread Sigma = Cov(theta_i) - mean(C_i) (each
   unit's estimation covariance C_i taken out, the method of moments), its eigenvalues
   kept at least a FLOOR share of the between-unit variance (in the units' correlation
   scale); for the check of a new unit against the design also shrunk toward its
   diagonal by the share p / (p + N) (a few units cannot pin p(p+1)/2 covariances).
5. the design's hysteresis: the play (of T or of one node, `unit_fit.Play`) whose column
   lowers the kept units' pooled squared error most on the law without the nodes' cubes, at
   that law's time constants, kept when it lowers the whole law's by more than PLAY_GAIN
   (`choose_play`): a physics node fitted to one program mimics a play at that program's
   rates and mispredicts the others. With one, every unit is fitted again with it, and
   theta, mu and Sigma hold its coefficient after the nodes' (`unit_fit`).
How much the structure leaves on the units' own programs (`structure_misfit`, 1: noise
only) says how far the prior's figures can be trusted. The kept units' fits (`unit_thetas`)
and a full program they ran (`reference`) carry the prior in the space of responses
(response_prior.py), what a new unit is fitted with; `map_fit` (map_estimate.py) fits the
parameters themselves: the check against the design.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError
from fogsf.models.features import PHYSICAL_SCALE_C
from fogsf.models.structures.hysteresis import MAX_SOURCE_TAU_S, plays_batch
from fogsf.prior.unit_fit import (
    Play,
    StepSeries,
    UnitFit,
    all_steps,
    correlation_factor,
    design_matrix,
    fit_taus,
    fit_unit,
    n_coef,
    plain_refit,
    predict,
    window_means,
)

K_CHOICES = (1, 2, 3)
# one more node is taken when it lowers the units' misfit by more than this share; a lower
# share holds some designs' fast loops and loses others' plans and checks
# (benchmarks/probes/README.md, "fleet_structure_choice")
STRUCTURE_TOLERANCE = 0.05
# a unit is left out when a parameter lies this many robust scales from the units' median
# (`robust_keep`)
OUTLIER_Z = 4.0
FLOOR = 1e-3
# the spread's shrinkage toward its diagonal for the MAP (None: p / (p + N)): none, the
# units' own directions of variation kept; shrinking them costs the new units' accuracy
# (benchmarks/probes/README.md, "Fleet prior: where it stops")
SHRINK: float | None = 0.0
MIN_UNITS = 3
# the play's widths (C) and the units it is chosen on; it is kept when it lowers their
# pooled squared error by more than PLAY_GAIN, above what a design without hysteresis gains
# (benchmarks/probes/README.md, "Fleet prior: where it stops", "The design's play")
PLAY_WIDTHS_C = tuple(float(w) for w in range(2, 13))
PLAY_UNITS = 8
PLAY_GAIN = 0.001


@dataclass
class DesignPrior:
    k: int
    mu: np.ndarray  # [log taus, coefficients]
    sigma: np.ndarray  # the units' spread around the design (estimation noise out)
    units: list[str]  # the units it was learned from
    left_out: list[dict]  # {"unit", "why"}
    k_scores: dict[int, float]  # total misfit per node count (ppm^2 per step)
    between: np.ndarray  # the raw covariance of the units' fits
    noise: np.ndarray  # the mean estimation covariance taken out
    # the spread shrunk toward its diagonal by p / (p + N): what the check of a new unit
    # against the design reads (a few units span few of the p directions: a unit may
    # differ from the design where no unit of the fleet happened to)
    sigma_check: np.ndarray
    step_noise_ppm2: float  # the units' median residual variance per model step
    # the kept units' fits at k from the design's time constants, their coefficients by
    # least squares (`unit_fit.plain_refit`; one row a unit): their responses are the prior
    # in the space of responses (`response_prior`)
    unit_thetas: np.ndarray | None = None
    # a full program the units ran (every step): where a new unit's law is fitted
    reference: StepSeries | None = None
    play: Play | None = None  # the design's hysteresis term (`choose_play`), if any
    # how much the design's structure leaves on the kept units' own programs: the median
    # over them of sqrt(`unit_fit.correlation_factor`) of their residuals (1: noise only)
    structure_misfit: float = 1.0

    def as_dict(self) -> dict:
        taus = np.exp(self.mu[:self.k])
        return {"k": self.k, "mu": self.mu.tolist(), "sigma": self.sigma.tolist(),
                "units": self.units, "left_out": self.left_out,
                "k_scores": {str(k): v for k, v in self.k_scores.items()},
                "taus_s": taus.tolist(),
                "tau_spread": np.sqrt(np.diag(self.sigma)[:self.k]).tolist(),
                "play": None if self.play is None else self.play.as_dict(taus),
                "structure_misfit": self.structure_misfit}

    def to_cache(self) -> dict:
        """Everything, exactly (arrays as float64 bytes): `from_cache` gives back a prior
        that fits a new unit bit for bit as this one (the fleet's cache keeps it)."""
        d = {k: v for k, v in vars(self).items() if k not in ("reference", "play")}
        d = {k: _pack64(v) if isinstance(v, np.ndarray) else v for k, v in d.items()}
        d["k_scores"] = [[k, v] for k, v in self.k_scores.items()]
        d["reference"] = None if self.reference is None else self.reference.as_dict()
        d["play"] = None if self.play is None else [self.play.node, self.play.width_c]
        return d

    @classmethod
    def from_cache(cls, d: dict) -> DesignPrior:
        d = {k: _unpack64(v) if isinstance(v, dict) and "f8" in v else v for k, v in d.items()}
        d["k_scores"] = {int(k): float(v) for k, v in d["k_scores"]}
        d["reference"] = None if d["reference"] is None else StepSeries.from_dict(d["reference"])
        d["play"] = None if d["play"] is None else Play(int(d["play"][0]), float(d["play"][1]))
        return cls(**d)


def _pack64(a: np.ndarray) -> dict:
    return {"f8": base64.b64encode(np.ascontiguousarray(a, dtype="<f8").tobytes()).decode(),
            "shape": list(a.shape)}


def _unpack64(d: dict) -> np.ndarray:
    return np.frombuffer(base64.b64decode(d["f8"]), dtype="<f8").reshape(d["shape"]).copy()


def choose_k(series: dict[str, StepSeries], fits: dict[int, dict[str, UnitFit]]
             ) -> tuple[int, dict[int, float]]:
    """The node count whose fits leave the least misfit per unit (the median over units of
    the mean square of the residuals' WINDOW_S means: the noise of single steps averaged
    out), the smallest within STRUCTURE_TOLERANCE of the best."""
    scores = {k: float(np.median([window_misfit(series[sn], f) for sn, f in fk.items()]))
              for k, fk in fits.items()}
    best = min(scores.values())
    k = min(k for k, s in scores.items() if s <= best * (1.0 + STRUCTURE_TOLERANCE))
    return k, scores


def window_misfit(series: StepSeries, fit: UnitFit) -> float:
    """Mean square (ppm^2) of the fit's residuals averaged over WINDOW_S windows."""
    r = series.y - predict(series, fit.theta, fit.k)
    means, _ = window_means(r, series.step_s)
    return float(np.mean(means**2)) if means.size else float(r @ r)


def robust_keep(thetas: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """Mask of units whose fit lies inside the others' spread: per parameter the distance
    from the units' median in units of max(1.4826 MAD, the median estimation standard
    deviation); a unit with any distance over OUTLIER_Z (1 + sqrt(log p) / 2) is left out
    (p parameters: the largest of p distances grows so). Needs MIN_UNITS units to judge."""
    n, p = thetas.shape
    if n < MIN_UNITS:
        return np.ones(n, dtype=bool)
    med = np.median(thetas, axis=0)
    mad = 1.4826 * np.median(np.abs(thetas - med), axis=0)
    est = np.sqrt(np.median(np.stack([np.diag(c) for c in covs]), axis=0))
    scale = np.maximum(mad, est)
    scale = np.where(scale > 0, scale, 1.0)
    d = np.abs(thetas - med) / scale
    return d.max(axis=1) <= OUTLIER_Z * (1.0 + np.sqrt(np.log(p)) / 2.0)


def learn(series: dict[str, StepSeries], k: int | None = None,
          first: dict[int, dict[str, UnitFit]] | None = None) -> DesignPrior:
    """The design's prior from the units' step series (`k`: force the node count;
    `first`: the units' fits from the grid start per node count, when known: the
    summaries keep them)."""
    if len(series) < 2:
        raise UserError(f"the design's prior needs at least two units, the fleet has "
                        f"{len(series)}")
    ks = (k,) if k is not None else K_CHOICES
    first = dict(first or {})
    for kk in ks:  # refitted where missing or of another layout (a summary of an older fogsf)
        if kk not in first or set(first[kk]) != set(series) or any(
                f.theta.size != kk + n_coef(kk) for f in first[kk].values()):
            first[kk] = {sn: fit_unit(s, kk) for sn, s in series.items()}
    first = {kk: first[kk] for kk in ks}
    k, scores = choose_k(series, first) if k is None else (k, {k: float("nan")})
    med = np.exp(np.median(np.stack([f.theta[:k] for f in first[k].values()]), axis=0))
    fits = {sn: fit_unit(s, k, med) for sn, s in series.items()}
    # the better of the two fits per unit (the common start unless it fits much worse)
    for sn, f in fits.items():
        if first[k][sn].sse < 0.9 * f.sse:
            fits[sn] = first[k][sn]
    names = sorted(fits)
    thetas = np.stack([fits[sn].theta for sn in names])
    covs = np.stack([fits[sn].cov for sn in names])
    keep = robust_keep(thetas, covs)
    left = [{"unit": sn, "why": "its physics fit lies outside the other units' spread"}
            for sn, kp in zip(names, keep, strict=True) if not kp]
    kept = [sn for sn, kp in zip(names, keep, strict=True) if kp]
    # the play's form at the time constants of the law without the nodes' cubes: with them
    # the time constants move to mimic a play, and the play's width with them (a planted
    # 5 C play read as 11 C)
    play = choose_play([series[sn] for sn in kept[:PLAY_UNITS]],
                       [fit_taus(series[sn], k, med, node_cubes=False)
                        for sn in kept[:PLAY_UNITS]], k)
    if play is not None:  # every unit fitted again with it: the parameters hold the play
        fits = {sn: fit_unit(series[sn], k, fits[sn].taus_s, play) for sn in names}
        thetas = np.stack([fits[sn].theta for sn in names])
        covs = np.stack([fits[sn].cov for sn in names])
    th, cv = thetas[keep], covs[keep]
    mu = th.mean(axis=0)
    n, p = th.shape
    between = np.cov(th.T, ddof=1) if n > 1 else np.zeros((p, p))
    noise = cv.mean(axis=0)
    sigma = spread(between, noise, n, SHRINK)
    unit_thetas = np.stack([plain_refit(series[sn], fits[sn].theta, k, play) for sn in kept])
    misfit = float(np.median([
        np.sqrt(correlation_factor(series[sn].y - predict(series[sn], t, k, play),
                                   series[sn].step_s))
        for sn, t in zip(kept, unit_thetas, strict=True)]))
    return DesignPrior(k, mu, sigma, kept, left, scores, between, noise,
                       spread(between, noise, n, None),
                       float(np.median([fits[sn].sse / fits[sn].n for sn in names])),
                       unit_thetas, all_steps(series[kept[0]]), play, misfit)


def choose_play(series: list[StepSeries], taus: list[np.ndarray], k: int) -> Play | None:
    """The play (of T or of a node no slower than MAX_SOURCE_TAU_S, a width of
    PLAY_WIDTHS_C) whose column, at each unit's own time constants `taus`, lowers the units'
    pooled least-squares error most against the law without the nodes' cubes (fitted beside
    the play, they trade with its width; `taus` that law's time constants); kept when it
    lowers the pooled error of the whole law (the cubes in) by more than PLAY_GAIN (against
    the law without them a play stands in for the cubes on a line that has none). (Each
    unit's law without the play is built once, the play's column beside it: the error does
    not depend on the columns' order.)"""
    med = np.median(np.stack(taus), axis=0)
    nodes = [0] + [j + 1 for j in range(k) if med[j] <= MAX_SOURCE_TAU_S]
    widths = np.asarray(PLAY_WIDTHS_C)
    sse = np.zeros((len(nodes), widths.size))
    for s, t in zip(series, taus, strict=True):
        x0 = design_matrix(s, t, node_cubes=False)
        for a, j in enumerate(nodes):
            xs = Play(j, 0.0).source(s, t)
            h = np.vstack([plays_batch(np.repeat(x[:, None], widths.size, axis=1), widths)
                           for x in xs])[s.rows] / PHYSICAL_SCALE_C
            sse[a] += [_sse(np.column_stack([x0, h[:, i]]), s.y) for i in range(widths.size)]
    ia, iw = np.unravel_index(int(np.argmin(sse)), sse.shape)
    play = Play(nodes[int(ia)], float(widths[iw]))
    base = sum(_sse(design_matrix(s, t), s.y) for s, t in zip(series, taus, strict=True))
    with_play = sum(_sse(design_matrix(s, t, play), s.y)
                    for s, t in zip(series, taus, strict=True))
    gain = 1.0 - with_play / base if base > 0 else 0.0
    return play if gain > PLAY_GAIN else None


def _sse(x: np.ndarray, y: np.ndarray) -> float:
    r = y - x @ np.linalg.lstsq(x, y, rcond=None)[0]
    return float(r @ r)


def spread(between: np.ndarray, noise: np.ndarray, n: int, shrink: float | None
            ) -> np.ndarray:
    """Sigma = between - noise, eigenvalues floored, shrunk toward the diagonal by `shrink`
    (None: p / (p + n))."""
    p = between.shape[0]
    d = np.sqrt(np.maximum(np.diag(between), 1e-300))
    corr_b = between / np.outer(d, d)
    corr_n = noise / np.outer(d, d)
    ev, vec = np.linalg.eigh(corr_b - corr_n)
    ev = np.maximum(ev, FLOOR)
    s = (vec * ev) @ vec.T
    a = p / (p + n) if shrink is None else shrink
    s = (1.0 - a) * s + a * np.diag(np.diag(s))
    return s * np.outer(d, d)
