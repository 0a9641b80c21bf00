"""Other laws on the bank's features, against the bank's own (least squares, no LSTM).

`sf_oracle` shows that on two ramp rates, a loop and partial cycles the training logs hold
the information to reach 0.98-1.05 x the noise floor, and that the bank's generic law (every
feature with its square and cube) spends it on coefficients the gyro does not have. This
probe scores laws that are sparser or closer to the physics, each fitted on the protocol's
training logs and scored on its test log:
- `bank`: the default's bank at its prior (`lag_bank.fit_bank`);
- `linW`: the same ridge with the linear lags' penalty W times the rest (0.1, 0.01);
- `rankK`: the linear lags plus a square and a cube along K fitted directions of the bank's
  features (a sum of ridge functions: each SF factor a polynomial of one mixed temperature),
  the directions by variable projection from the best of a few starts;
- `idN`: the bank's law on T and lags at N time constants identified by variable
  projection on the training logs (`physics_nodes.identify_taus`), at the prior;
- `sub-test` / `sub-held`: squares and cubes on one or two of the bank's curved features
  only, the subset chosen on the test itself (a selection no method has) or by the logs'
  held-out parts.

    python -m benchmarks.probes.bank_laws --first 1 --n 40 --protocols b,e
    python -m benchmarks.probes.bank_laws --partial --first 1 --n 20
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Callable

import numpy as np

from benchmarks.probes import StepScorer, finish, spread_cells
from benchmarks.probes.sf_oracle import Run, partial_case, protocol_cases
from fogsf.models.structures.lag_bank import (
    BANK_LAMBDA,
    CURVED_MAX_TAU_S,
    bank_design,
    fit_bank,
    n_curved,
)
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import varpro
from fogsf.models.structures.physics_nodes import identify_taus
from fogsf.training.structure import heldout as sh

Law = Callable[[np.ndarray], np.ndarray]


def weighted(z: np.ndarray, y: np.ndarray, w_lin: float) -> Law:
    """The bank's ridge with the linear columns' penalty w_lin times the others'."""
    x = bank_design(z, n_curved())
    d = np.ones(x.shape[1])
    d[:z.shape[1]] = w_lin
    xs = x / np.sqrt(d)
    mu, ym = xs.mean(axis=0), float(np.mean(y))
    xc = xs - mu
    scale = float(np.mean(np.linalg.svd(x - x.mean(axis=0), compute_uv=False) ** 2))
    u, sv, vt = np.linalg.svd(xc, full_matrices=False)
    coef = vt.T @ (sv / (sv**2 + BANK_LAMBDA * scale) * (u.T @ (y - ym)))
    return lambda zz: ym + (bank_design(zz, n_curved()) / np.sqrt(d) - mu) @ coef


def _rank_design(z: np.ndarray, theta: np.ndarray, k: int) -> np.ndarray:
    m = theta.reshape(k, z.shape[1])
    u = z @ (m / np.linalg.norm(m, axis=1, keepdims=True)).T
    return np.column_stack([z, u * u, u * u * u])


def rank_law(z: np.ndarray, y: np.ndarray, k: int) -> Law:
    """Linear lags plus curvature along k directions, by variable projection."""
    p = z.shape[1]
    full = fit_bank(z, y, BANK_LAMBDA, curved=n_curved(), cross=True)
    ev, vec = np.linalg.eigh(full.quad + full.quad.T)
    top = [vec[:, i] for i in np.argsort(-np.abs(ev))]
    eye = np.eye(p)
    starts = ([np.array([s]) for s in (eye[0], eye[2], eye[5], eye[8], top[0])] if k == 1
              else [np.vstack(top[:2]), np.vstack([eye[0], top[0]]), np.vstack([eye[0], eye[5]])])
    best = None
    for s in starts:
        th0 = s.ravel()
        vp = varpro(lambda th: _rank_design(z, th, k), y, th0, np.full(th0.size, -10.0),
                    np.full(th0.size, 10.0), BANK_LAMBDA, max_iter=40)
        if best is None or vp.fit.sse < best.fit.sse:
            best = vp
    assert best is not None
    return lambda zz: best.fit.predict(_rank_design(zz, best.theta, k))


def subset_law(z: np.ndarray, y: np.ndarray, sub: tuple[int, ...]) -> Law:
    """The bank with squares and cubes on the features `sub` only."""
    order = list(sub) + [i for i in range(z.shape[1]) if i not in sub]
    f = fit_bank(z[:, order], y, BANK_LAMBDA, curved=len(sub))
    return lambda zz: f.predict(zz[:, order])


def case(train: list[Run], test: Run) -> dict:
    logs = [r.log for r, _ in train]
    full = sh.step_data(logs)
    z, y = full.nodes.z(TAU_GRID_S), full.y
    s = float(np.std(y)) or 1.0
    on_test = StepScorer.of(test[0].log, full.fe)
    nt = on_test.nt
    zt = nt.z(TAU_GRID_S)

    def score(law: Law, zz: np.ndarray = zt) -> float:
        return on_test(law(zz) * s)

    out = {"bank": score(fit_bank(z, y / s, BANK_LAMBDA, curved=n_curved()).predict)}
    for w in (0.1, 0.01):
        out[f"lin{w:g}"] = score(weighted(z, y / s, w))
    for k in (1, 2):
        out[f"rank{k}"] = score(rank_law(z, y / s, k))
    for n in (2, 3):
        taus = identify_taus(full.nodes, y, n)
        f = fit_bank(full.nodes.z(taus), y / s, BANK_LAMBDA,
                     curved=1 + sum(t <= CURVED_MAX_TAU_S for t in taus))
        out[f"id{n}"] = score(f.predict, nt.z(taus))
    # subsets of the curved features: on the test, and by the held-out parts
    nc = n_curved()
    subs = [(i,) for i in range(nc)] + list(itertools.combinations(range(nc), 2))
    on_test = [score(subset_law(z, y / s, sub)) for sub in subs]
    out["sub-test"] = min(on_test)
    sd = sh.step_data(logs, sh.choice_step_s(logs))
    if not sd.one_segment:
        sd.fold = sh.part_folds(sd)
        zs, ss = sd.nodes.z(TAU_GRID_S), float(np.std(sd.y)) or 1.0
        held = []
        for sub in [tuple(range(nc)), *subs]:
            err = 0.0
            for k in range(sd.n_folds):
                tr = sd.fold != k
                e = subset_law(zs[tr], sd.y[tr] / ss, sub)(zs[~tr]) * ss - sd.y[~tr]
                err += float(e @ e)
            held.append(err)
        i = int(np.argmin(held))
        out["sub-held"] = out["bank"] if i == 0 else on_test[i - 1]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.probes.bank_laws",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="example: python -m benchmarks.probes.bank_laws "
                                        "--first 1 --n 8 --protocols b,e")
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--protocols", default="b,e")
    ap.add_argument("--partial", action="store_true",
                    help="the partial-cycle programs, gyros without SF hysteresis")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    from fogsf.sim.population import DEV_SEEDS

    t0 = time.perf_counter()
    rows: list[dict] = []
    if args.partial:
        from benchmarks.hysteresis import pick_seeds

        for seed in pick_seeds(args.first, args.n, DEV_SEEDS)["flat"]:
            rows.append({"seed": seed, "p": "partial-flat", **case(*partial_case(seed, "flat"))})
            print(rows[-1], flush=True)
    else:
        for seed in range(args.first, args.first + args.n):
            assert seed in DEV_SEEDS, "development gyros only"
            for p, (train, test) in protocol_cases(seed, args.protocols.split(",")).items():
                rows.append({"seed": seed, "p": p, **case(train, test)})
                print(rows[-1], flush=True)
    for p in sorted({r["p"] for r in rows}):
        sub = [r for r in rows if r["p"] == p]
        names = [k for k in sub[0] if k not in ("seed", "p") and all(k in r for r in sub)]
        print(f"({p}) {len(sub)} cases; median/p90/worst {spread_cells(sub, names)}")
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
