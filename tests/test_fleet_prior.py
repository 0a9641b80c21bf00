"""The design's prior on synthetic units of a known physics-node design: the structure and
the spread it learns, the unit unlike the line it leaves out, the MAP and the fit in the
space of responses that beat a unit's short run alone, the check that refuses a unit unlike
the design, the summary round trip.

Units are drawn at the model rate (no simulator): a design's time constants and law, each
unit's drawn around them by a stated spread, white noise; the effect's strength, the design
and the seed come from a seeded generator and are printed on failure."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fogsf.prior import design_prior as fp
from fogsf.prior.map_estimate import NOISE_SCALE, check_chi2, map_fit
from fogsf.prior.response_prior import FunctionFit, function_fit
from fogsf.prior.unit_fit import StepSeries, all_steps, design_matrix, fit_unit, n_coef

STEP_S = 5.0
SEED = 3802


def _program(hours: float, rate: float, soak_min: float, rng: np.random.Generator
             ) -> np.ndarray:
    """Board temperature minus 20 C per step: soak, up, soak, down, ... at `rate` C/min."""
    lo, hi = -55.0 + rng.uniform(-2, 2), 30.0 + rng.uniform(-2, 2)
    pts_t, pts_c, t, c = [0.0], [lo], 0.0, lo
    while t < hours * 3600:
        t += soak_min * 60
        pts_t.append(t)
        pts_c.append(c)
        nxt = hi if c == lo else lo
        t += abs(nxt - c) / rate * 60
        pts_t.append(t)
        pts_c.append(nxt)
        c = nxt
    tt = np.arange(0, hours * 3600, STEP_S)
    return np.interp(tt, pts_t, pts_c)


def _design(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    taus = np.sort(np.exp(rng.uniform(np.log(300), np.log(4000), 2)))
    taus[1] = max(taus[1], 2.5 * taus[0])
    coef = np.zeros(n_coef(2))
    coef[1:4] = rng.uniform(-150, 150, 3)  # linear in T and the nodes (ppm per 50 C)
    coef[4:10] = rng.uniform(-40, 40, 6)  # quadratic and cross
    coef[10:13] = rng.uniform(-10, 10, 3)  # the cubes of T and the nodes
    return np.log(taus), coef


def _unit(design: tuple[np.ndarray, np.ndarray], t_rel: np.ndarray, rng: np.random.Generator,
          noise: float, tau_spread: float = 0.10, coef_spread: float = 0.15
          ) -> tuple[StepSeries, np.ndarray]:
    lt, coef = design
    theta = np.concatenate([lt + rng.uniform(-tau_spread, tau_spread, lt.size),
                            coef * (1 + rng.uniform(-coef_spread, coef_spread, coef.size))])
    s = StepSeries([t_rel], np.zeros(t_rel.size), np.arange(t_rel.size), STEP_S)
    y = design_matrix(s, np.exp(theta[:2])) @ theta[2:]
    s.y = y + rng.normal(0, noise, y.size)
    return s, theta


def _truth_rms(s: StepSeries, theta: np.ndarray, truth: np.ndarray) -> float:
    a = design_matrix(s, np.exp(theta[:2])) @ theta[2:]
    b = design_matrix(s, np.exp(truth[:2])) @ truth[2:]
    return float(np.sqrt(np.mean((a - b) ** 2)))


@pytest.fixture(scope="module")
def line() -> dict:
    """A design, its noise, 8 units on a 6 h program."""
    rng = np.random.default_rng(SEED)
    design = _design(rng)
    noise = float(rng.uniform(2.0, 5.0))
    full = _program(6.0, 1.5, 30, rng)
    units = {f"u{i}": _unit(design, full, rng, noise) for i in range(8)}
    return {"rng": rng, "design": design, "noise": noise, "units": units}


@pytest.fixture(scope="module")
def prior(line: dict) -> fp.DesignPrior:
    return fp.learn({sn: s for sn, (s, _) in line["units"].items()}, k=2)


@pytest.mark.slow
def test_prior_learns_the_design_and_its_spread(line: dict, prior: fp.DesignPrior) -> None:
    p = prior
    truth = np.stack([th for _, th in line["units"].values()])
    msg = f"seed {SEED}, noise {line['noise']:.2f}"
    # the design's time constants within the units' spread of their mean
    assert np.allclose(p.mu[:2], truth[:, :2].mean(axis=0), atol=0.08), msg
    # the spread of the log time constants: the units' own, estimation noise taken out
    sd = np.sqrt(np.diag(p.sigma)[:2])
    true_sd = truth[:, :2].std(axis=0, ddof=1)
    assert np.all(sd < 2.5 * true_sd + 0.02) and np.all(sd > 0.3 * true_sd), msg
    assert not p.left_out, msg


@pytest.mark.slow
def test_structure_misfit_says_when_the_structure_misses(line: dict,
                                                         prior: fp.DesignPrior) -> None:
    """The structure leaves noise only on a line of its own form; on a line whose units all
    carry a slow form it cannot express (a 20-40 min sine, 1-2 x the noise) it says so."""
    from fogsf.training.with_prior import STRUCTURE_MISS, prior_lines

    assert prior.structure_misfit < 1.1, f"seed {SEED}: {prior.structure_misfit:.2f}"
    rng = np.random.default_rng(SEED + 6)
    amp, period = rng.uniform(1.0, 2.0) * line["noise"], rng.uniform(1200.0, 2400.0)
    odd = {}
    for sn, (s, _) in line["units"].items():
        t_s = np.arange(s.y.size) * STEP_S
        odd[sn] = StepSeries(s.t_rel, s.y + amp * np.sin(2 * np.pi * t_s / period
                                                          + rng.uniform(0, 2 * np.pi)),
                             s.rows, STEP_S)
    missed = fp.learn(odd, k=2)
    assert missed.structure_misfit > STRUCTURE_MISS, \
        f"seed {SEED}: {missed.structure_misfit:.2f} with a {amp:.1f} ppm sine"
    rec = {"prior_share": {}, "design_taus_s": [1.0, 2.0], "nodes": 2, "units": 6,
           "left_out": [], "chi2": 1.0, "chi2_limit": 2.0, "level": 1e-3, "used": False,
           "structure_misfit": missed.structure_misfit}
    assert "the design's structure misses them" in prior_lines(rec)[0]
    rec["structure_misfit"] = prior.structure_misfit
    assert "misses" not in prior_lines(rec)[0]


@pytest.mark.slow
def test_stored_fits_of_another_layout_are_refitted(line: dict, prior: fp.DesignPrior
                                                    ) -> None:
    """A fleet's summaries written by an older fogsf keep fits without the nodes' cubes
    (a shorter theta): the prior refits them (the node count chosen on the refits) and
    learns what it learns without them. The old fits' values are never read, only their
    layout: each is one fit's with its theta cut to the old size (one fit a unit)."""
    from dataclasses import replace

    series = {sn: s for sn, (s, _) in line["units"].items()}
    one = {sn: fit_unit(s, 1) for sn, s in series.items()}
    old = {kk: {sn: replace(f, theta=np.zeros(kk + n_coef(kk) - kk))  # no nodes' cubes
                for sn, f in one.items()} for kk in fp.K_CHOICES}
    p = fp.learn(series, first=old)
    assert p.mu.size == p.k + n_coef(p.k), f"seed {SEED}"
    alone = prior if p.k == prior.k else fp.learn(series, k=p.k)  # the fixture's: k = 2
    assert np.allclose(p.mu, alone.mu), f"seed {SEED}"


@pytest.mark.slow
def test_unit_unlike_the_line_is_left_out(line: dict) -> None:
    rng = np.random.default_rng(SEED + 1)
    lt, coef = line["design"]
    odd = (lt, coef.copy())
    odd[1][1:4] *= -2.0  # its linear law far off the design's
    series = {sn: s for sn, (s, _) in line["units"].items()}
    series["odd"] = _unit(odd, line["units"]["u0"][0].t_rel[0], rng, line["noise"])[0]
    p = fp.learn(series, k=2)
    assert [x["unit"] for x in p.left_out] == ["odd"], f"seed {SEED}"


def test_map_beats_the_short_run_alone(line: dict, prior: fp.DesignPrior) -> None:
    rng = np.random.default_rng(SEED + 2)
    p = prior
    full = line["units"]["u0"][0]
    better = 0
    for i in range(2):
        short, truth = _unit(line["design"], _program(1.5, 2.0, 10, rng), rng, line["noise"])
        mf = map_fit(short, p)
        alone = fit_unit(short, 2)
        e_map, e_alone = _truth_rms(full, mf.theta, truth), _truth_rms(full, alone.theta, truth)
        assert not mf.disagrees, f"seed {SEED} unit {i}: chi2 {mf.chi2:.1f}"
        assert all(0.0 <= v <= 1.0 for v in mf.prior_share.values())
        better += e_map < e_alone
        assert e_map < 3.0 * line["noise"], f"seed {SEED} unit {i}: {e_map:.2f} ppm off"
    assert better == 2, f"seed {SEED}"


def test_response_prior_beats_the_short_run_alone(line: dict, prior: fp.DesignPrior) -> None:
    """The posterior mean response beats the unit's short run alone; the law it exports is
    that response (a projection of it), and the interval narrows with the unit's data."""
    rng = np.random.default_rng(SEED + 4)
    full = all_steps(line["units"]["u0"][0])
    for i in range(2):
        t_short = _program(1.5, 2.0, 10, rng)
        short, truth = _unit(line["design"], t_short, rng, line["noise"])
        mf = map_fit(short, prior)
        ff = function_fit(short, prior, mf.s2)
        law = ff.law()
        alone = fit_unit(short, 2)
        e_law, e_alone = _truth_rms(full, law, truth), _truth_rms(full, alone.theta, truth)
        zero = FunctionFit(prior, np.zeros_like(ff.a), ff.a_cov, ff.s2, short)
        e_mean = float(np.sqrt(np.mean((zero.predict(full) - design_matrix(
            full, np.exp(truth[:2])) @ truth[2:]) ** 2)))
        msg = (f"seed {SEED} unit {i}: {e_law:.2f} ppm against {e_alone:.2f} alone, "
               f"{e_mean:.2f} for the units' mean")
        assert e_law < e_alone and e_law < e_mean and e_law < 3.0 * line["noise"], msg
        mean = ff.predict(full)
        exported = design_matrix(full, np.exp(law[:2])) @ law[2:]
        assert np.sqrt(np.mean((mean - exported) ** 2)) < 0.2 * line["noise"], msg
        more = StepSeries([t_short, full.t_rel[0]], np.concatenate(
            [short.y, design_matrix(full, np.exp(truth[:2])) @ truth[2:]
             + rng.normal(0, line["noise"], full.rows.size)]),
            np.arange(t_short.size + full.rows.size), STEP_S)
        assert np.mean(function_fit(more, prior, mf.s2).variance(full)) \
            < np.mean(ff.variance(full)), msg
        # a slow form no unit of the design has, planted in the run, is read as misfit
        amp = float(rng.uniform(1.0, 2.0)) * line["noise"]
        t_s = np.arange(short.y.size) * STEP_S
        odd = StepSeries(short.t_rel, short.y + amp * np.sin(2 * np.pi * t_s / 1500.0),
                         short.rows, STEP_S)
        m_odd = function_fit(odd, prior, mf.s2).misfit_ppm2()
        assert m_odd > 4.0 * ff.misfit_ppm2() and m_odd > 0.1 * amp**2, \
            f"{msg}; misfit {m_odd:.2f} ppm^2 with a {amp:.1f} ppm sine"


def test_short_run_noise_is_scaled(line: dict, prior: fp.DesignPrior) -> None:
    """The short run is weighed at NOISE_SCALE times the unit's noise estimate (the design's
    common misfit on a run the fleet never ran counted as noise): the same posterior as the
    scaled variance at scale 1, a wider one than at scale 1."""
    rng = np.random.default_rng(SEED + 5)
    short, _ = _unit(line["design"], _program(1.5, 2.0, 10, rng), rng, line["noise"])
    mf = map_fit(short, prior)
    s2 = mf.s2
    # the check reads the run at the same noise
    alone = fit_unit(short, prior.k, np.exp(prior.mu[:prior.k]), prior.play)
    alone = min(alone, fit_unit(short, prior.k, play=prior.play), key=lambda f: f.sse)
    assert mf.chi2 == pytest.approx(check_chi2(short, prior, alone.sigma2 * NOISE_SCALE,
                                               alone, 30), rel=1e-6)
    ff, same = function_fit(short, prior, s2), function_fit(short, prior, s2 * NOISE_SCALE,
                                                           noise_scale=1.0)
    assert NOISE_SCALE > 1.0 and ff.s2 == pytest.approx(s2 * NOISE_SCALE)
    np.testing.assert_allclose(ff.a, same.a, rtol=1e-9, atol=1e-12)
    full = all_steps(line["units"]["u0"][0])
    assert np.mean(ff.variance(full)) > np.mean(
        function_fit(short, prior, s2, noise_scale=1.0).variance(full)), f"seed {SEED}"


def test_unit_unlike_the_design_disagrees(line: dict, prior: fp.DesignPrior) -> None:
    rng = np.random.default_rng(SEED + 3)
    p = prior
    lt, coef = line["design"]
    odd = (lt, coef.copy())
    odd[1][1:4] *= float(rng.uniform(2.5, 4.0))
    short, _ = _unit(odd, _program(2.0, 2.0, 15, rng), rng, line["noise"])
    mf = map_fit(short, p)
    assert mf.disagrees, f"seed {SEED}: chi2 {mf.chi2:.1f} limit {mf.chi2_limit:.1f}"


def test_series_and_fit_round_trip_through_json(line: dict) -> None:
    s, _ = line["units"]["u1"]
    back = StepSeries.from_dict(json.loads(json.dumps(s.as_dict())))
    assert np.allclose(back.y, s.y, rtol=1e-6, atol=1e-3)
    assert np.array_equal(back.rows, s.rows)
    f = fit_unit(s, 2)
    g = type(f).from_dict(json.loads(json.dumps(f.as_dict())))
    assert np.allclose(g.theta, f.theta) and np.allclose(g.cov, f.cov)
