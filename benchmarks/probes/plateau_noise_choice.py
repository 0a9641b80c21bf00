"""Rules for the plateau model's form in noise: every candidate scored once per case (gyro,
kind, split of `benchmarks.plateaus`), then each rule's pick looked up, so rules compare in
seconds. A case keeps, per form, each fold kind's held-out errors (`rate_choice`'s folds on
the training plateaus), and its test RMS fitted in float64 on all training plateaus (the
bench's oracle arithmetic, not the kernel's: within a few % of `make bench-plateaus`).

Beside the rules, two bounds: `oracle` is the bench's (the best polynomial chosen by the noisy
held-out plateaus themselves), `truth` the form whose fit is nearest the noise-free held-out
output (the structure known, the coefficients fitted on the noisy training plateaus): no rule
on the training plateaus can expect to beat `truth`, so its ratio to `oracle` bounds them.

    python -m benchmarks.probes.plateau_noise_choice --gyros 0:8 --noise-dph 100
"""

from __future__ import annotations

import argparse
import pickle
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.plateaus import KINDS, OTHER_RUN, SPLITS, oracle, splits, table_rows
from fogsf.models.structures.rate_choice import RateRows, fold_kinds
from fogsf.models.structures.rate_forms import TEMP_SCALE_C, RateForm, design, forms, solve
from fogsf.training.rate.plateau_model import FS_HEADROOM, PlateauRows, choice_rows


@dataclass
class Case:
    gyro: int
    kind: str
    split: str
    forms: list[RateForm]
    n_terms: np.ndarray  # [F]
    sq: np.ndarray  # [K, F, n] held-out squared error (units of FS^2), nan where not held
    lev: np.ndarray  # [K, F] mean held-out prediction variance per unit noise variance
    train_n: int
    rss_rich: float  # RSS of the richest form the rows can fit, and its terms
    p_rich: int
    pure_var: float  # the variance of repeat plateaus about their (rate, T group) mean
    test: np.ndarray  # [F] noisy test RMS (deg/h)
    test_clean: np.ndarray  # [F] against the noise-free held-out output
    oracle: float
    linear_oracle: float
    fs: float


def _candidates(rows: RateRows, allow: bool) -> list[RateForm]:
    cands = [f for f in forms() if allow or not f.has_rate_part]
    top = np.unique(rows.group).size - 1
    return [f for f in cands if f.temp_degree <= top and f.rate_temp_degree <= top] or [
        f for f in cands if f.temp_degree == 0 and f.rate_temp_degree == 0]


def _kind_errors(rows: RateRows, form: RateForm, masks: list[np.ndarray]
                 ) -> tuple[np.ndarray, float]:
    """Each held-out row's squared error, and the mean over them of the fit's prediction
    variance there per unit noise variance (x_h' (A'A)^+ x_h)."""
    a = design(rows.x, rows.tau, form)
    need = max(form.temp_degree, form.rate_temp_degree) + 1
    out = np.full(len(rows), np.nan)
    lev, count = 0.0, 0
    for held in masks:
        train = ~held
        if train.sum() <= form.n_terms or np.unique(rows.group[train]).size < need:
            continue
        out[held] = (a[held] @ solve(a[train], rows.y[train]) - rows.y[held]) ** 2
        norm = np.linalg.norm(a[train], axis=0)
        norm[norm == 0] = 1.0
        pinv = np.linalg.pinv(a[train] / norm)
        lev += float(np.sum(((a[held] / norm) @ pinv) ** 2))
        count += int(held.sum())
    return out, (lev / count if count else float("nan"))


def _pure_var(rows: PlateauRows, groups: np.ndarray, fs: float) -> float:
    """Pooled variance of plateaus repeated at one rate in one temperature group."""
    key = np.round(rows.rate_dps / fs, 4) * 1000 + groups
    ss, dof = 0.0, 0
    for k in np.unique(key):
        r = (rows.rate_dps - rows.gyro_dps)[key == k] / fs
        if r.size > 1:
            ss, dof = ss + float(np.sum((r - r.mean()) ** 2)), dof + r.size - 1
    return ss / dof if dof else float("nan")


def build_case(gyro: int, kind: str, split: str, train: PlateauRows, test: PlateauRows,
               test_clean: PlateauRows) -> Case:
    fs = float(np.ceil(FS_HEADROOM * np.max(np.abs(train.rate_dps))))
    t_ref = round(0.5 * (float(train.temp_c.min()) + float(train.temp_c.max())), 1)
    rows = choice_rows(train, fs, t_ref)
    cands = _candidates(rows, train.rates_measured >= 2)
    kinds = fold_kinds(rows)
    both = [[_kind_errors(rows, f, ms) for f in cands] for ms in kinds]
    sq = np.array([[e for e, _ in k] for k in both])
    lev = np.array([[v for _, v in k] for k in both])
    rich = max((f for f in cands if f.n_terms < len(rows) - 5), key=lambda f: f.n_terms)
    a = design(rows.x, rows.tau, rich)
    e = a @ solve(a, rows.y) - rows.y
    tau_t = (test.temp_c - t_ref) / TEMP_SCALE_C
    noisy: list[float] = []
    clean: list[float] = []
    for f in cands:
        coef = solve(design(rows.x, rows.tau, f), rows.y)
        for g, out in ((test.gyro_dps, noisy), (test_clean.gyro_dps, clean)):
            pred = g + fs * (design(g / fs, tau_t, f) @ coef)
            out.append(float(np.sqrt(np.mean((pred - test.rate_dps) ** 2))) * 3600.0)
    return Case(gyro, kind, split, cands, np.array([f.n_terms for f in cands]), sq, lev,
                len(rows), float(e @ e), rich.n_terms, _pure_var(train, rows.group, fs),
                np.array(noisy), np.array(clean), oracle(train, test, False)[0],
                oracle(train, test, True)[0], fs)


def build(lo: int, hi: int, noise: float) -> list[Case]:
    out = []
    for gyro in range(lo, hi):
        for kind in KINDS:
            run, _ = table_rows(gyro, kind, gyro, noise)
            other, _ = table_rows(gyro, kind, gyro + OTHER_RUN, noise)
            run0, _ = table_rows(gyro, kind, gyro, 0.0)
            other0, _ = table_rows(gyro, kind, gyro + OTHER_RUN, 0.0)
            clean = splits(run0, other0)
            for name, (train, test) in splits(run, other).items():
                out.append(build_case(gyro, kind, name, train, test, clean[name][1]))
        print(f"  gyro {gyro} scored", file=sys.stderr, flush=True)
    return out


def load(lo: int, hi: int, noise: float, cache: Path) -> list[Case]:
    path = cache / f"plateau_cases3_{lo}_{hi}_{noise:g}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    cases = build(lo, hi, noise)
    cache.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(cases))
    return cases


# ---- rules: a case -> the chosen form's index -------------------------------------------

def _mean_sq(c: Case) -> np.ndarray:
    """[K, F] held-out mean square per kind (nan where a kind cannot score the form)."""
    n = np.isfinite(c.sq).sum(axis=2)
    return np.where(n > 0, np.nansum(c.sq, axis=2) / np.maximum(n, 1), np.nan)


def kind_rms(c: Case) -> np.ndarray:
    """[K, F] held-out RMS per kind (nan where a kind cannot score the form)."""
    return np.sqrt(_mean_sq(c))


def geo(c: Case, extra: np.ndarray | None = None) -> np.ndarray:
    """The default's score (geometric mean over the kinds that score the form); `extra`
    [F] is added to each kind's mean square first."""
    ms = _mean_sq(c) if extra is None else _mean_sq(c) + extra
    with np.errstate(divide="ignore"):
        lg = np.log(np.sqrt(np.maximum(ms, 1e-60)))
    ok = np.isfinite(lg)
    s = np.where(ok.any(axis=0), np.exp(np.nansum(np.where(ok, lg, 0), 0)
                                        / np.maximum(ok.sum(0), 1)), np.inf)
    return s


def noise_var(c: Case, how: str) -> float:
    if how == "rich":
        return c.rss_rich / max(c.train_n - c.p_rich, 1)
    if how == "pure":
        return c.pure_var
    raise ValueError(how)


def rule_default(c: Case) -> int:
    """The rule before this probe: the lowest unpriced score (`old` in the README)."""
    return int(np.argmin(geo(c)))


def rule_penalty(k: float, how: str = "rich") -> Callable[[Case], int]:
    """Each kind's mean square plus k sigma^2 p / n: an information criterion's price of a
    term, in the noise the rows show."""
    def pick(c: Case) -> int:
        return int(np.argmin(geo(c, k * noise_var(c, how) * c.n_terms / c.train_n)))
    return pick


def rule_1se(k: float, how: str = "rich") -> Callable[[Case], int]:
    """The fewest terms whose score is within k sigma / sqrt(2 n) of the best (a noise-aware
    one-standard-error rule: the margin vanishes on quiet rows)."""
    def pick(c: Case) -> int:
        s = geo(c)
        sig = np.sqrt(noise_var(c, how))
        best = float(np.min(s))
        ok = np.flatnonzero(s <= best + k * sig / np.sqrt(2 * c.train_n))
        return int(min(ok, key=lambda i: (c.n_terms[i], s[i])))
    return pick


def _bic_price(c: Case, sub: float = 1.0) -> np.ndarray:
    return (np.log(c.train_n) - sub) * noise_var(c, "rich") * c.n_terms / c.train_n


def _odd(c: Case) -> np.ndarray:
    return np.array([f.odd for f in c.forms])


def rule_bic(sub: float, odd: bool = True) -> Callable[[Case], int]:
    """Each term priced at (log(n) - sub) sigma^2 / n; sub = 1 (the held-out score already
    pays one unit a term: BIC's price in all) is the default since this probe. `odd`: the
    odd-power forms among the candidates (without: the candidates before them)."""
    def pick(c: Case) -> int:
        s = geo(c, _bic_price(c, sub))
        return int(np.argmin(s if odd else np.where(_odd(c), np.inf, s)))
    return pick


def _t_terms(c: Case) -> np.ndarray:
    """[F] the terms a form holds beyond its degree 0 in T."""
    return np.array([2 * f.temp_degree + (f.n_terms - 2 * (f.temp_degree + 1))
                     * f.rate_temp_degree // (f.rate_temp_degree + 1) for f in c.forms])


def rule_kind_price(k: float) -> Callable[[Case], int]:
    """bic-1, the T terms priced k times over in the extrapolating kinds (temperature
    groups, time blocks: every kind but the last)."""
    def pick(c: Case) -> int:
        base = _bic_price(c)
        extra = (k - 1.0) * (np.log(c.train_n) - 1) * noise_var(c, "rich") * _t_terms(c) \
            / c.train_n
        ms = _mean_sq(c) + base
        ms[:-1] += extra
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = np.log(np.sqrt(np.maximum(ms, 1e-60)))
        ok = np.isfinite(lg)
        s = np.where(ok.any(0), np.exp(np.nansum(np.where(ok, lg, 0), 0)
                                       / np.maximum(ok.sum(0), 1)), np.inf)
        return int(np.argmin(s))
    return pick


def rule_t_by_extrap(c: Case) -> int:
    """bic-1's rate powers; their degrees in T chosen by the extrapolating kinds alone."""
    first = c.forms[rule_bic(1.0)(c)]
    same = [i for i, f in enumerate(c.forms) if (f.powers, f.abs_term, f.odd)
            == (first.powers, first.abs_term, first.odd)]
    ms = _mean_sq(c)[:-1][:, same] + _bic_price(c)[same]
    with np.errstate(invalid="ignore"):
        s = np.exp(np.nanmean(np.log(np.sqrt(np.maximum(ms, 1e-60))), axis=0))
    s = np.where(np.isfinite(s), s, np.inf)
    return same[int(np.argmin(s))]


def rule_leverage(k: float) -> Callable[[Case], int]:
    """Each kind's mean square plus k sigma^2 times the form's mean prediction variance at
    the held-out rows (a price that grows where the kind extrapolates)."""
    def pick(c: Case) -> int:
        return int(np.argmin(geo(c, k * noise_var(c, "rich") * c.lev)))
    return pick


def rule_masked(keep: Callable[[RateForm], bool], times: float = 1.0,
                every_kind: bool = False) -> Callable[[Case], int]:
    """bic-1 (its price `times` over) among the forms `keep` holds; `every_kind`: among
    those every kind of fold scores."""
    def pick(c: Case) -> int:
        s = geo(c, times * _bic_price(c))
        ok = np.array([keep(f) for f in c.forms])
        if every_kind:
            ok &= np.isfinite(_mean_sq(c)).all(axis=0)
        return int(np.argmin(np.where(ok, s, np.inf))) if ok.any() else int(np.argmin(s))
    return pick


def rule_t_price(k: float) -> Callable[[Case], int]:
    """bic-1 with the T terms priced k times a rate term's (k < 1: the drift a physical FOG
    always has is cheaper to keep than a rate term)."""
    def pick(c: Case) -> int:
        unit = (np.log(c.train_n) - 1) * noise_var(c, "rich") / c.train_n
        return int(np.argmin(geo(c, unit * (c.n_terms - (1.0 - k) * _t_terms(c)))))
    return pick


def rule_worst_kind(c: Case) -> int:
    """bic-1's priced mean squares, the worst kind's instead of the kinds' mean."""
    ms = _mean_sq(c) + _bic_price(c)
    with np.errstate(invalid="ignore"):
        s = np.nanmax(ms, axis=0)
    return int(np.argmin(np.where(np.isfinite(s), s, np.inf)))


RULES: dict[str, Callable[[Case], int]] = {"default": rule_default,
                                           "bic-1-even": rule_bic(1.0, odd=False),
                                           "bic-1": rule_bic(1.0),
                                           "bic": rule_bic(0.0), "bic-2": rule_bic(2.0)}
for _k in (2.0, 4.0, 8.0):
    RULES[f"pen{_k:g}"] = rule_penalty(_k)
RULES["pen4pure"] = rule_penalty(4.0, "pure")
for _k in (1.0, 2.0, 4.0):
    RULES[f"se{_k:g}"] = rule_1se(_k)
for _k in (0.5, 1.0, 2.0):
    RULES[f"lev{_k:g}"] = rule_leverage(_k)
for _k in (2.0, 3.0):
    RULES[f"kind{_k:g}"] = rule_kind_price(_k)
RULES["t-extrap"] = rule_t_by_extrap
for _k in (0.0, 0.5):
    RULES[f"tprice{_k:g}"] = rule_t_price(_k)
RULES["worst-kind"] = rule_worst_kind
RULES["cap-r"] = rule_masked(lambda f: f.rate_temp_degree <= f.temp_degree)
RULES["min-q1"] = rule_masked(lambda f: f.temp_degree >= 1)
RULES["odd-only"] = rule_masked(lambda f: f.odd or f.powers == 1)
RULES["all-kinds"] = rule_masked(lambda f: True, every_kind=True)
for _k in (1.5, 2.0, 3.0):
    RULES[f"bic-1x{_k:g}"] = rule_masked(lambda f: True, times=_k)


def odd_oracle(cases: list[Case]) -> None:
    """The oracle's family widened by the odd-power forms (each case's oracle lowered in
    place to the best of them on its test plateaus, where that is lower)."""
    for c in cases:
        ok = [i for i, f in enumerate(c.forms) if not f.abs_term]
        c.oracle = min(c.oracle, float(np.min(c.test[ok])))


def table(cases: list[Case], pick: Callable[[Case], int] | None, what: str = "rule") -> str:
    cells = []
    for kind in KINDS:
        for split in SPLITS:
            sel = [c for c in cases if c.kind == kind and c.split == split]
            if what == "truth":
                r = [c.test[int(np.argmin(c.test_clean))] / c.oracle for c in sel]
            elif what == "linear":
                r = [c.linear_oracle / c.oracle for c in sel]
            else:
                assert pick is not None
                r = [c.test[pick(c)] / c.oracle for c in sel]
            cells.append(f"{np.median(r):5.2f}/{np.max(r):4.2f}")
    return "  ".join(cells)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.probes.plateau_noise_choice",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gyros", default="0:8")
    p.add_argument("--noise-dph", type=float, default=100.0)
    p.add_argument("--cache", type=Path, default=Path("out/probe-cache"))
    p.add_argument("--rules", default="", help="comma-separated; all when empty")
    p.add_argument("--odd-oracle", action="store_true",
                   help="the oracle's family with the odd-power forms too")
    args = p.parse_args(argv)
    ranges = [tuple(int(x) for x in r.split(":")) for r in args.gyros.split(",")]
    cases = [c for lo, hi in ranges for c in load(lo, hi, args.noise_dph, args.cache)]
    if args.odd_oracle:
        odd_oracle(cases)
    names = [r for r in args.rules.split(",") if r] or list(RULES)
    head = "  ".join(f"{k[:4]}/{s[:5]:5s}" for k in KINDS for s in SPLITS)
    print(f"gyros {args.gyros}, noise {args.noise_dph:g} deg/h: median/worst of "
          "held-out RMS over the oracle's")
    print(f"{'':14s}{head}")
    print(f"{'truth':14s}{table(cases, None, 'truth')}")
    print(f"{'linear':14s}{table(cases, None, 'linear')}")
    for name in names:
        print(f"{name:14s}{table(cases, RULES[name])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
