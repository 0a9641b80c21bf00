"""Gravitational search algorithm (GSA): minimise a function over a box of parameters.

Follows the fogsf paper's section 2.1, equations (3)-(9), and Rashedi, Nezamabadi-pour and
Saryazdi (2009), "GSA: A Gravitational Search Algorithm", Information Sciences 179:2232-2248,
with the details of the authors' reference implementation where the paper is silent.

Use (`SHORT_BUDGET`, `Param` and `minimize` from this module)::

    space = [Param("batch_size", 8, 256, "int"), Param("layers", 1, 4, "int"),
             Param("hidden", 8, 256, "int"), Param("lr", 1e-4, 1e-1, "log-real")]
    res = minimize(fitness, space, n_agents=20, n_iters=30, seed=1,
                   executor=None, progress=True, **SHORT_BUDGET)
    res.best_params   # {"batch_size": 32, "layers": 2, "hidden": 200, "lr": 0.02}
    res.best_fitness, res.best_curve, res.mean_curve
    res.save_json("gsa.json"); res.plot("gsa_fitness.png")

``fitness(params: dict[str, int | float]) -> float`` is minimised. It must be deterministic
in its argument (seed any training inside it) and, for worker processes or Dask, picklable:
a module-level function or a `functools.partial` of one. Non-finite fitness values count
as the worst of the iteration. With ``vectorized=True`` it is instead called once per
iteration, inline, with an (n_agents, dim) float array of values (ints already rounded,
log-reals as values) and returns an (n_agents,) array: the benchmark functions use this.

``executor``: ``"local"`` (default) opens ``n_workers`` local processes (default one per
core; ``n_workers=1`` runs inline), ``None`` runs inline, and any `concurrent.futures`
executor (e.g. `fogsf.gsa.executors.open_executor(dask=ADDRESS)`) is used as given and left
open. Results never depend on the executor: the random stream is drawn only in this
process and results are gathered in agent order, so the same seed gives the same run.

The algorithm, iteration t = 1..T (T = ``n_iters``), N agents, positions X, velocities V:

1. fitness f_i of each agent; best-so-far updated (the curve the paper plots in Fig. 8);
2. masses (eq. 3-4, Rashedi eq. 15-18, here for minimisation): m_i = (f_i - worst) /
   (best - worst) with best = min f, worst = max f; M_i = m_i / sum m (all 1/N when every
   f_i is equal);
3. G(t) = G0 * exp(-alpha * t / T) (eq. 5; G0 = 100, alpha = 20);
4. Kbest(t) = round(k_T + (N - k_T) * (1 - t / T)): the heaviest agents that attract, falling
   linearly from N to k_T = ``final_kbest`` (default 1, as the issue asks; Rashedi's code uses
   2 % of N, which for N = 50 is the same 1);
5. acceleration (eq. 6-7 with M_i cancelled, active = passive = inertial mass):
   a_i^d = G(t) * sum_{j in Kbest, j != i} rand_ij^d * M_j * (x_j^d - x_i^d) / (R_ij + eps),
   R_ij the Euclidean distance (R, not R^2), eps = machine epsilon; rand_ij^d uniform in
   [0, 1), drawn per attracting agent *and* per dimension as in Rashedi's reference code
   (``rand_per_dim=False`` draws one rand_j per pair, the literal eq. 6);
6. v_i^d = rand_i^d * v_i^d + a_i^d (eq. 8), x_i^d = x_i^d + v_i^d (eq. 9);
7. keep X in the box (``bounds``): ``"reflect"`` (default) folds a coordinate back into the
   box as often as needed and reverses that velocity component; ``"clip"`` puts it on the
   bound and zeroes the velocity component; ``"random"`` re-draws it uniformly in the box
   and keeps the velocity (Rashedi's reference code).

G is in search-coordinate units: an attracting pull has magnitude at most G(t), whatever
the box, so G0 = 100 makes early steps span any box and the exponential decay brings the
step size down to the box's scale later; Rashedi's constants suit T ~ 1000 iterations on
boxes 2.56..200 wide. Boxes that differ widely between parameters (batch size 8..256 next
to log10 lr -4..-1) make GSA move mostly along the wide ones. ``normalize=True`` moves the
agents in the unit cube instead (each parameter's search range mapped to [0, 1]); with the
same seed it is the raw search with G0 divided by the box width. For hyper-parameter
searches of tens of iterations use ``minimize(..., **SHORT_BUDGET)`` (normalize, G0 = 3,
alpha = 2): ``python -m benchmarks.probes.gsa_short_budget`` measures it against random search
and the defaults at equal evaluation counts.
"""

from __future__ import annotations

import json
import math
import pickle
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.gsa.executors import open_executor
from fogsf.gsa.space import Param, Space, SpaceError

__all__ = ["SHORT_BUDGET", "GSAResult", "Param", "Space", "SpaceError", "gravity", "kbest",
           "minimize"]

BOUNDS = ("reflect", "clip", "random")

# Settings for hyper-parameter searches of a few hundred evaluations (tens of iterations):
# every parameter mapped to [0, 1], gentler gravity. On synthetic problems over the paper's
# Table 1 space (python -m benchmarks.probes.gsa_short_budget) these beat random search at equal
# evaluations, where Rashedi's constants (tuned for T = 1000) do worse than random search.
SHORT_BUDGET: dict[str, Any] = {"normalize": True, "g0": 3.0, "alpha": 2.0}


def gravity(t: int | np.ndarray, n_iters: int, g0: float = 100.0, alpha: float = 20.0):
    """G(t) = G0 * exp(-alpha * t / T), paper eq. (5) / Rashedi eq. (28)."""
    return g0 * np.exp(-alpha * np.asarray(t, dtype=np.float64) / n_iters)


def kbest(t: int, n_iters: int, n_agents: int, final_kbest: int = 1) -> int:
    """Number of attracting agents at iteration t (1..T): linear from N towards final_kbest.

    round(final + (N - final) * (1 - t / T)), rounding half up, never below 1.
    """
    x = final_kbest + (n_agents - final_kbest) * (1.0 - t / n_iters)
    return max(1, min(n_agents, int(math.floor(x + 0.5))))


def masses(f: np.ndarray) -> np.ndarray:
    """Normalised masses for minimisation (paper eq. 3-4, Rashedi eq. 15-18); sum to 1."""
    f = np.asarray(f, dtype=np.float64)
    best, worst = f.min(), f.max()
    if worst == best:
        return np.full(f.shape, 1.0 / f.size)
    m = (f - worst) / (best - worst)
    return m / m.sum()


def accelerations(x: np.ndarray, m: np.ndarray, g: float, k: int, rng: np.random.Generator,
                  eps: float = float(np.finfo(np.float64).eps),
                  rand_per_dim: bool = True) -> np.ndarray:
    """a_i = G * sum_{j in Kbest} rand * M_j (x_j - x_i) / (R_ij + eps)  (eq. 6-7)."""
    n_agents, dim = x.shape
    heavy = np.argsort(-m, kind="stable")[:k]
    diff = x[heavy][None, :, :] - x[:, None, :]              # (N, K, dim): x_j - x_i
    r = np.sqrt(np.einsum("ikd,ikd->ik", diff, diff))        # Euclidean distance R_ij
    # (N, K) weights; j == i (and any agent on the same spot) has diff 0 and pulls nothing
    w = np.divide(m[heavy][None, :], r + eps, out=np.zeros_like(r), where=r > 0)
    if rand_per_dim:
        return g * np.einsum("ik,ikd,ikd->id", w, rng.random((n_agents, k, dim)), diff)
    return g * np.einsum("ik,ikd->id", w * rng.random((n_agents, k)), diff)


def keep_in_box(x: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray, how: str,
                rng: np.random.Generator) -> None:
    """Bring positions back into [lo, hi] in place (see the module doc for the three ways)."""
    out = (x < lo) | (x > hi)
    if not out.any():
        return
    if how == "clip":
        np.clip(x, lo, hi, out=x)
        v[out] = 0.0
    elif how == "reflect":
        width = np.broadcast_to(hi - lo, x.shape)
        u = (x - lo) / width                       # fold the line onto [0, 1]
        folds = np.floor(u)
        frac = u - folds
        odd = out & ((folds.astype(np.int64) % 2) == 1)
        x[out] = (lo + np.where(odd, 1.0 - frac, frac) * width)[out]
        v[odd] = -v[odd]
    else:  # random
        fresh = lo + rng.random(x.shape) * (hi - lo)
        x[out] = fresh[out]


@dataclass
class GSAResult:
    """What a GSA run found and how it got there (curves indexed by iteration 1..T)."""

    best_params: dict[str, int | float]
    best_fitness: float
    best_position: list[float]          # search coordinates of the best agent
    best_curve: list[float]             # best-so-far fitness after each iteration
    mean_curve: list[float]             # mean fitness of the agents (finite ones) per iteration
    n_evals: int                        # fitness calls actually made (after de-duplication)
    n_agents: int
    n_iters: int
    seed: int | Sequence[int] | None
    space: list[dict]
    settings: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def save_json(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=True) + "\n")
        return path

    def plot(self, path: str | Path, title: str = "GSA fitness curve") -> Path:
        """Fitness vs iteration (the paper's Fig. 8): best-so-far and the agents' mean."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.ticker import MaxNLocator

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        it = np.arange(1, len(self.best_curve) + 1)
        fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
        ax.plot(it, self.mean_curve, color="0.6", lw=1.0, label="mean of agents")
        ax.plot(it, self.best_curve, color="C0", lw=1.8, label="best so far")
        finite = np.asarray([*self.best_curve, *self.mean_curve], dtype=np.float64)
        finite = finite[np.isfinite(finite)]
        if finite.size and finite.min() > 0 and finite.max() / finite.min() > 100:
            ax.set_yscale("log")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("iteration")
        ax.set_ylabel("fitness")
        ax.set_title(f"{title}\nbest {self.best_fitness:.4g} "
                     f"({self.n_agents} agents, {self.n_iters} iterations)", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)
        return path


def _evaluate(fn: Callable, params: list[dict], executor: Executor | None) -> list[float]:
    if executor is None:
        return [float(fn(p)) for p in params]
    futures = [executor.submit(fn, p) for p in params]
    try:
        return [float(fut.result()) for fut in futures]
    except BaseException:
        for fut in futures:
            fut.cancel()
        raise


def minimize(fitness_fn: Callable, space: Space | Iterable[Param | Mapping | Sequence], *,
             n_agents: int = 20, n_iters: int = 50, seed: int | Sequence[int] | None = 0,
             executor: Executor | str | None = "local", n_workers: int | None = None,
             progress: bool = True, vectorized: bool = False, cache: bool = True,
             g0: float = 100.0, alpha: float = 20.0, final_kbest: int = 1,
             eps: float = float(np.finfo(np.float64).eps), bounds: str = "reflect",
             rand_per_dim: bool = True, normalize: bool = False,
             callback: Callable[[int, GSAResult], None] | None = None) -> GSAResult:
    """Minimise ``fitness_fn`` over ``space`` with GSA; see the module doc for every argument.

    ``cache``: evaluate each distinct parameter set once per run (integer parameters make
    agents collide); ``callback(t, partial_result)`` is called after every iteration.
    """
    space = Space(space)
    if int(n_agents) != n_agents or n_agents < 2:
        raise SpaceError(f"n_agents must be an integer >= 2, got {n_agents!r}")
    if int(n_iters) != n_iters or n_iters < 1:
        raise SpaceError(f"n_iters must be an integer >= 1, got {n_iters!r}")
    if bounds not in BOUNDS:
        raise SpaceError(f"bounds must be one of {', '.join(BOUNDS)}, got {bounds!r}")
    if not 1 <= final_kbest <= n_agents:
        raise SpaceError(f"final_kbest must be in 1..n_agents, got {final_kbest!r}")
    n_agents, n_iters = int(n_agents), int(n_iters)

    run = partial(_run, fitness_fn, space, n_agents=n_agents, n_iters=n_iters, seed=seed,
                  progress=progress, vectorized=vectorized, cache=cache, g0=g0, alpha=alpha,
                  final_kbest=final_kbest, eps=eps, bounds=bounds, rand_per_dim=rand_per_dim,
                  normalize=normalize, callback=callback)
    if vectorized:                       # one array call per iteration, always inline
        return run(None)
    if isinstance(executor, str):
        if executor != "local":
            raise SpaceError(f"executor must be 'local', None or a concurrent.futures "
                             f"Executor, got {executor!r}")
        with open_executor(workers=n_workers) as ex:
            return run(ex)
    return run(executor)


def _check_picklable(fitness_fn: Callable, executor: Executor | None) -> None:
    """Worker processes receive the fitness function pickled: say so before they fail."""
    if not isinstance(executor, ProcessPoolExecutor):
        return
    try:
        pickle.dumps(fitness_fn)
    except (pickle.PicklingError, AttributeError, TypeError) as e:
        raise TypeError(f"the fitness function {fitness_fn!r} cannot be sent to worker "
                        "processes (it is not picklable: use a module-level function or a "
                        "functools.partial of one), or run inline with executor=None: "
                        f"{e}") from e


def _run(fitness_fn: Callable, space: Space, executor: Executor | None, *, n_agents: int,
         n_iters: int, seed: int | Sequence[int] | None, progress: bool, vectorized: bool,
         cache: bool, g0: float, alpha: float, final_kbest: int, eps: float, bounds: str,
         rand_per_dim: bool, normalize: bool, callback: Callable | None) -> GSAResult:
    from tqdm import tqdm

    _check_picklable(fitness_fn, executor)
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    if normalize:       # agents live in the unit cube, mapped onto the search box
        lo, hi = np.zeros(space.dim), np.ones(space.dim)
    else:
        lo, hi = space.lo, space.hi

    def to_search(u: np.ndarray) -> np.ndarray:
        return space.lo + u * (space.hi - space.lo) if normalize else u

    x = lo + rng.random((n_agents, space.dim)) * (hi - lo)
    v = np.zeros_like(x)
    memo: dict[tuple, float] = {}
    n_evals = 0
    best_f, best_x = math.inf, x[0].copy()
    best_curve: list[float] = []
    mean_curve: list[float] = []
    settings = {"g0": g0, "alpha": alpha, "final_kbest": final_kbest, "eps": eps,
                "bounds": bounds, "rand_per_dim": rand_per_dim, "normalize": normalize,
                "vectorized": vectorized,
                "executor": "inline" if executor is None else type(executor).__name__}

    def result() -> GSAResult:
        return GSAResult(best_params=space.to_params(to_search(best_x)), best_fitness=best_f,
                         best_position=to_search(best_x).tolist(), best_curve=list(best_curve),
                         mean_curve=list(mean_curve), n_evals=n_evals, n_agents=n_agents,
                         n_iters=n_iters, seed=seed, space=space.to_json(), settings=settings,
                         wall_s=time.perf_counter() - t0)

    bar = tqdm(range(1, n_iters + 1), desc="GSA", unit="it", disable=not progress,
               dynamic_ncols=True)
    for t in bar:
        values = space.decode(to_search(x))
        if vectorized:
            f = np.asarray(fitness_fn(values), dtype=np.float64).reshape(n_agents)
            n_evals += n_agents
        else:
            keys = [tuple(row) for row in values.tolist()]
            first = {k: i for i, k in reversed(list(enumerate(keys)))}   # distinct sets
            todo = [k for k in first if k not in memo]
            got = _evaluate(fitness_fn, [space.to_params(to_search(x[first[k]])) for k in todo],
                            executor)
            n_evals += len(todo)
            fresh = dict(zip(todo, got, strict=True))
            f = np.array([fresh[k] if k in fresh else memo[k] for k in keys])
            if cache:
                memo.update(fresh)

        finite = np.isfinite(f)
        if not finite.any():
            f_mass = np.zeros(n_agents)        # nothing to rank: all agents weigh the same
        else:
            f_mass = np.where(finite, f, f[finite].max())
        i_best = int(np.argmin(f_mass))
        if finite[i_best] and f[i_best] < best_f:
            best_f, best_x = float(f[i_best]), x[i_best].copy()
        best_curve.append(best_f)
        mean_curve.append(float(f[finite].mean()) if finite.any() else math.nan)
        bar.set_postfix(best=f"{best_f:.4g}", refresh=False)
        if callback is not None:
            callback(t, result())

        m = masses(f_mass)
        g = float(gravity(t, n_iters, g0, alpha))
        a = accelerations(x, m, g, kbest(t, n_iters, n_agents, final_kbest), rng, eps,
                          rand_per_dim)
        v = rng.random(v.shape) * v + a
        x = x + v
        keep_in_box(x, v, lo, hi, bounds, rng)
    bar.close()
    return result()
