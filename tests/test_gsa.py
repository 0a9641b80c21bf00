"""GSA: the formulas, benchmark functions at a reduced budget, mixed spaces, determinism."""

from __future__ import annotations

import json
import math
from functools import partial

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.gsa.optimizer import (
    SHORT_BUDGET,
    Param,
    Space,
    SpaceError,
    accelerations,
    gravity,
    kbest,
    keep_in_box,
    masses,
    minimize,
)
from fogsf.gsa.testfunctions import f1_sphere, f6_step, shifted_sphere

# Seeds for the randomised tests come from one seeded generator; failures print theirs.
SEEDS = [int(s) for s in np.random.default_rng(20260522).integers(0, 2**31, size=3)]

LSTM_SPACE = [Param("batch_size", 8, 256, "int"), Param("layers", 1, 4, "int"),
              Param("hidden", 8, 256, "int"), Param("lr", 1e-4, 1e-1, "log-real")]


# --- schedules and formulas -------------------------------------------------------------

def test_gravity_follows_g0_exp_minus_alpha_t_over_t() -> None:
    t = np.arange(0, 1001)
    assert np.allclose(gravity(t, 1000), 100.0 * np.exp(-20.0 * t / 1000), rtol=1e-15)
    assert gravity(0, 50) == pytest.approx(100.0)
    assert gravity(50, 50) == pytest.approx(100.0 * math.exp(-20.0))
    assert gravity(10, 40, g0=3.0, alpha=25.0) == pytest.approx(3.0 * math.exp(-25.0 / 4))


def test_kbest_falls_linearly_from_n_to_1() -> None:
    n, big_t = 50, 1000
    ks = [kbest(t, big_t, n) for t in range(big_t + 1)]
    assert ks[0] == n and ks[-1] == 1
    assert all(a >= b for a, b in zip(ks, ks[1:], strict=False))
    for t in range(big_t + 1):                       # the formula, rounding half up
        assert ks[t] == math.floor(1 + (n - 1) * (1 - t / big_t) + 0.5)
        # Rashedi's reference code: final_per = 2 %, identical for N = 50
        assert ks[t] == math.floor(n * (2 + (1 - t / big_t) * 98) / 100 + 0.5)
    assert kbest(500, 1000, 50) == 26                # 1 + 49 * 0.5 = 25.5 -> 26
    assert kbest(10, 10, 20, final_kbest=4) == 4


def test_a_run_uses_both_schedules_at_every_iteration(monkeypatch) -> None:
    import fogsf.gsa.optimizer as gsa

    g_calls, k_calls, k_used = [], [], []
    real_gravity, real_kbest, real_acc = gsa.gravity, gsa.kbest, gsa.accelerations
    monkeypatch.setattr(gsa, "gravity", lambda t, T, g0, a: g_calls.append((t, T, g0, a))
                        or real_gravity(t, T, g0, a))
    monkeypatch.setattr(gsa, "kbest", lambda t, T, n, f: k_calls.append((t, T, n, f))
                        or real_kbest(t, T, n, f))
    monkeypatch.setattr(gsa, "accelerations", lambda x, m, g, k, *r: k_used.append((g, k))
                        or real_acc(x, m, g, k, *r))
    gsa.minimize(f1_sphere, [Param("x", -1, 1), Param("y", -1, 1)], n_agents=9, n_iters=12,
                 seed=1, vectorized=True, progress=False)
    assert g_calls == [(t, 12, 100.0, 20.0) for t in range(1, 13)]
    assert k_calls == [(t, 12, 9, 1) for t in range(1, 13)]
    assert k_used == [(pytest.approx(100 * math.exp(-20 * t / 12)), real_kbest(t, 12, 9))
                      for t in range(1, 13)]
    assert k_used[0][1] == 8 and k_used[-1][1] == 1     # t = 1: round(1 + 8 * 11/12) = 8


def test_masses_for_minimisation() -> None:
    f = np.array([3.0, 1.0, 5.0, 2.0])
    m = masses(f)
    assert m.sum() == pytest.approx(1.0)
    assert np.argmax(m) == 1 and m[2] == 0.0              # best heaviest, worst weightless
    raw = (f - 5.0) / (1.0 - 5.0)
    assert np.allclose(m, raw / raw.sum())
    assert np.allclose(masses(np.full(5, 7.0)), 0.2)       # all equal: equal masses


def _accelerations_by_loops(x, m, g, k, rand, eps):
    """Rashedi's reference Gfield, loop by loop (rand indexed [i, k, d])."""
    n, dim = x.shape
    heavy = np.argsort(-m, kind="stable")[:k]
    a = np.zeros_like(x)
    for i in range(n):
        for kk, j in enumerate(heavy):
            if j == i:
                continue
            r = math.sqrt(sum((x[i, d] - x[j, d]) ** 2 for d in range(dim)))
            for d in range(dim):
                a[i, d] += rand[i, kk, d] * m[j] * (x[j, d] - x[i, d]) / (r + eps)
    return g * a


@pytest.mark.parametrize("seed", SEEDS)
def test_acceleration_matches_the_force_law_with_r_not_r2(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, dim, k, g, eps = 7, 3, 4, 12.5, 1e-9
    x = rng.normal(size=(n, dim)) * rng.uniform(0.1, 10)
    m = masses(rng.random(n))
    got = accelerations(x, m, g, k, np.random.default_rng(seed + 1), eps)
    rand = np.random.default_rng(seed + 1).random((n, k, dim))
    assert np.allclose(got, _accelerations_by_loops(x, m, g, k, rand, eps)), f"seed {seed}"
    # the literal eq. (6): one rand_j per pair
    got1 = accelerations(x, m, g, k, np.random.default_rng(seed + 2), eps, rand_per_dim=False)
    rand1 = np.random.default_rng(seed + 2).random((n, k))
    rand1 = np.repeat(rand1[:, :, None], dim, axis=2)
    assert np.allclose(got1, _accelerations_by_loops(x, m, g, k, rand1, eps)), f"seed {seed}"


def test_acceleration_magnitude_does_not_shrink_with_distance() -> None:
    """Force ~ 1/R with the (x_j - x_i) factor: the pull is independent of the distance."""
    m = np.array([1.0, 0.0])
    for dist in (0.01, 1.0, 1e4):
        x = np.array([[0.0, 0.0], [dist, 0.0]])
        a = accelerations(x, m, 2.0, 1, np.random.default_rng(0), eps=0.0, rand_per_dim=False)
        r = np.random.default_rng(0).random((2, 1))[1, 0]
        assert a[1] == pytest.approx([-2.0 * r, 0.0])
        assert np.all(a[0] == 0.0)                     # the single attractor feels nothing


def test_keep_in_box_reflect_clip_random() -> None:
    lo, hi = np.array([0.0, -1.0]), np.array([10.0, 1.0])
    x = np.array([[13.0, 0.5], [-4.0, 2.5], [5.0, -7.5]])
    v = np.ones_like(x)
    keep_in_box(x, v, lo, hi, "reflect", np.random.default_rng(0))
    assert np.allclose(x, [[7.0, 0.5], [4.0, -0.5], [5.0, 0.5]])
    assert np.allclose(v, [[-1, 1], [-1, -1], [1, 1]])  # -7.5 folds 4 times: v kept
    x = np.array([[13.0, 0.5], [-4.0, 2.5]])
    v = np.ones_like(x)
    keep_in_box(x, v, lo, hi, "clip", np.random.default_rng(0))
    assert np.allclose(x, [[10.0, 0.5], [0.0, 1.0]]) and np.allclose(v, [[0, 1], [0, 0]])
    x = np.random.default_rng(1).normal(scale=100, size=(200, 2))
    v = np.ones_like(x)
    keep_in_box(x, v, lo, hi, "random", np.random.default_rng(0))
    assert np.all((x >= lo) & (x <= hi)) and np.all(v == 1.0)


# --- benchmark functions at a reduced budget --------------------------------------------

@pytest.mark.parametrize("seed", SEEDS)
def test_sphere_f1_reaches_1e_10(seed: int) -> None:
    """F1, n=10, N=30, T=300: 200 seeds all ended below 1e-16 when this was written."""
    space = [Param(f"x{i}", -100, 100) for i in range(10)]
    res = minimize(f1_sphere, space, n_agents=30, n_iters=300, seed=seed, vectorized=True,
                   progress=False)
    assert res.best_fitness < 1e-10, f"seed {seed}: F1 best {res.best_fitness:.3g}"
    assert len(res.best_curve) == 300 and res.best_curve[-1] == res.best_fitness
    assert all(a >= b for a, b in zip(res.best_curve, res.best_curve[1:], strict=False))
    assert res.mean_curve[0] > 1000 * max(res.mean_curve[-1], 1e-30)


@pytest.mark.parametrize("seed", SEEDS)
def test_step_f6_reaches_its_exact_minimum(seed: int) -> None:
    space = [Param(f"x{i}", -100, 100) for i in range(10)]
    res = minimize(f6_step, space, n_agents=30, n_iters=300, seed=seed, vectorized=True,
                   progress=False)
    assert res.best_fitness == 0.0, f"seed {seed}: F6 best {res.best_fitness}"
    assert np.all(np.abs(res.best_position) < 0.5), f"seed {seed}"


# --- mixed spaces, the dict-in fitness path -----------------------------------------------

@pytest.mark.parametrize("settings", [{}, SHORT_BUDGET, {"bounds": "clip"}])
def test_integer_parameters_are_ints_inside_the_box(settings: dict) -> None:
    seen: list[dict] = []

    def fitness(p: dict) -> float:
        seen.append(p)
        return (p["batch_size"] - 40) ** 2 / 1e3 + (p["layers"] - 2) ** 2 \
            + (p["hidden"] - 100) ** 2 / 1e4 + math.log10(p["lr"] / 0.01) ** 2

    res = minimize(fitness, LSTM_SPACE, n_agents=12, n_iters=25, seed=SEEDS[0],
                   executor=None, progress=False, **settings)
    assert len(seen) == res.n_evals > 0
    for p in [*seen, res.best_params]:
        assert list(p) == ["batch_size", "layers", "hidden", "lr"]
        for name, low, high in (("batch_size", 8, 256), ("layers", 1, 4), ("hidden", 8, 256)):
            assert type(p[name]) is int and low <= p[name] <= high, p
        assert type(p["lr"]) is float and 1e-4 <= p["lr"] <= 1e-1, p
    assert res.best_fitness == pytest.approx(min(
        (p["batch_size"] - 40) ** 2 / 1e3 + (p["layers"] - 2) ** 2
        + (p["hidden"] - 100) ** 2 / 1e4 + math.log10(p["lr"] / 0.01) ** 2 for p in seen))


def test_every_integer_gets_an_equal_share_of_the_box() -> None:
    space = Space([Param("k", 1, 4, "int"), Param("lr", 1e-3, 1e-1, "log-real")])
    u = np.random.default_rng(SEEDS[1]).random((40_000, 2))
    vals = space.decode(space.lo + u * (space.hi - space.lo))
    counts = np.bincount(vals[:, 0].astype(int), minlength=5)[1:]
    assert counts.sum() == 40_000 and np.all(np.abs(counts / 10_000 - 1) < 0.05), counts
    assert np.all((vals[:, 1] >= 1e-3) & (vals[:, 1] <= 1e-1))
    assert np.mean(vals[:, 1] < 1e-2) == pytest.approx(0.5, abs=0.02)   # log-uniform


def test_cache_evaluates_each_distinct_parameter_set_once() -> None:
    calls: list[tuple] = []

    def fitness(p: dict) -> float:
        calls.append(tuple(p.values()))
        return (p["a"] - 3) ** 2 + (p["b"] + 1) ** 2

    space = [Param("a", 0, 6, "int"), Param("b", -3, 2, "int")]
    res = minimize(fitness, space, n_agents=10, n_iters=30, seed=SEEDS[2], executor=None,
                   progress=False)
    assert len(calls) == len(set(calls)) == res.n_evals < 10 * 30
    assert res.best_params == {"a": 3, "b": -1} and res.best_fitness == 0.0


def test_non_finite_fitness_counts_as_worst() -> None:
    nans = []

    def fitness(p: dict) -> float:
        if p["x"] > 5:
            nans.append(p)
            return math.nan
        return (p["x"] - 1.0) ** 2 + p["y"] ** 2

    space = [Param("x", -10, 10), Param("y", -10, 10)]
    res = minimize(fitness, space, n_agents=20, n_iters=100, seed=SEEDS[0], executor=None,
                   progress=False)
    assert nans, "the NaN region was never visited: the test tests nothing"
    assert res.best_fitness < 1e-8, f"seed {SEEDS[0]}: best {res.best_fitness:.3g}"
    assert all(math.isfinite(m) for m in res.mean_curve)


# --- determinism --------------------------------------------------------------------------

def _run(seed: int, **kw):
    fit = partial(shifted_sphere, target={"a": 0.3, "n": 7, "lr": 0.003})
    space = [Param("a", -1, 1), Param("n", 1, 20, "int"), Param("lr", 1e-4, 1e-1, "log-real")]
    return minimize(fit, space, n_agents=8, n_iters=15, seed=seed, executor=None,
                    progress=False, **kw)


def test_same_seed_same_run_other_seed_other_run() -> None:
    a, b, c = _run(SEEDS[0]), _run(SEEDS[0]), _run(SEEDS[1])
    assert a.best_params == b.best_params and a.best_curve == b.best_curve
    assert a.mean_curve == b.mean_curve and a.best_position == b.best_position
    assert a.best_curve != c.best_curve


def test_result_json_and_plot(tmp_path) -> None:
    res = _run(SEEDS[0])
    path = res.save_json(tmp_path / "gsa.json")
    back = json.loads(path.read_text())
    assert back["best_params"] == res.best_params and back["best_curve"] == res.best_curve
    assert back["space"][1] == {"name": "n", "low": 1, "high": 20, "kind": "int"}
    png = res.plot(tmp_path / "gsa.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


# --- bad input ----------------------------------------------------------------------------

@pytest.mark.parametrize("spec, message", [
    (("x", 1.0, 1.0), "low .* must be below high"),
    (("x", 2, 1, "int"), "low .* must be below high"),
    (("x", 0, 1, "float"), "unknown kind 'float'"),
    (("x", 0, 1.5, "int"), "integer bounds"),
    (("x", 0, 1, "log-real"), "low > 0"),
    (("x", -math.inf, 1), "finite"),
    (("x", "0", 1), "must be a number"),
    (("", 0, 1), "non-empty string"),
    ({"name": "x", "low": 0}, "missing 'high'"),
    ({"name": "x", "low": 0, "high": 1, "type": "int"}, "unknown keys"),
])
def test_bad_specs_are_refused_with_clear_errors(spec, message) -> None:
    with pytest.raises(SpaceError, match=message):
        Space([spec])


def test_bad_spaces_and_options_are_refused() -> None:
    with pytest.raises(SpaceError, match="empty"):
        Space([])
    with pytest.raises(SpaceError, match="unique.*'x'"):
        Space([("x", 0, 1), ("x", 1, 2)])
    with pytest.raises(SpaceError, match="bounds must be one of"):
        minimize(shifted_sphere, [("x", 0, 1)], bounds="wrap", progress=False)
    with pytest.raises(SpaceError, match="n_agents"):
        minimize(shifted_sphere, [("x", 0, 1)], n_agents=1, progress=False)
    with pytest.raises(SpaceError, match="executor must be"):
        minimize(shifted_sphere, [("x", 0, 1)], executor="threads", progress=False)
    assert issubclass(SpaceError, UserError) and issubclass(SpaceError, ValueError)


def test_normalize_is_the_same_search_with_g0_scaled_by_the_box() -> None:
    """In the unit cube, G0 / width gives the raw-coordinate run (forces scale with G)."""
    space = [Param(f"x{i}", -100, 100) for i in range(5)]
    raw = minimize(f1_sphere, space, n_agents=12, n_iters=40, seed=SEEDS[0], vectorized=True,
                   progress=False)
    unit = minimize(f1_sphere, space, n_agents=12, n_iters=40, seed=SEEDS[0], vectorized=True,
                    progress=False, normalize=True, g0=100.0 / 200.0, eps=1e-30)
    assert np.allclose(unit.best_curve, raw.best_curve, rtol=1e-6, atol=0), f"seed {SEEDS[0]}"
    assert np.allclose(unit.best_position, raw.best_position, rtol=1e-6)
    other = minimize(f1_sphere, space, n_agents=12, n_iters=40, seed=SEEDS[0], vectorized=True,
                     progress=False, normalize=True)
    assert other.best_curve != raw.best_curve
