"""The design's hysteresis term in the fleet's prior: a play planted in every unit of a
synthetic design is chosen (its node and width), carried by the units' responses and by the
law `train --prior` exports, and it is what lets a short run at another rate predict the
unit; a line without one gets none.

Units are drawn at the model rate (no simulator), as in test_fleet_prior.py; the play's
node, width and strength, the design and the seed come from a seeded generator and are
printed on failure."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.prior import design_prior as fp
from fogsf.prior.map_estimate import map_fit
from fogsf.prior.response_prior import function_fit
from fogsf.prior.unit_fit import (
    Play,
    StepSeries,
    all_steps,
    design_matrix,
    n_coef,
    play_index,
)
from fogsf.training.with_prior import law_head
from tests.test_fleet_prior import STEP_S, _design, _program

SEED = 3804


def _unit(design: tuple[np.ndarray, np.ndarray], runs: list[np.ndarray], play: Play,
          strength: float, rng: np.random.Generator, noise: float
          ) -> tuple[StepSeries, np.ndarray]:
    """A unit of the design with the play (its coefficient `strength` x 15 %)."""
    lt, coef = design
    theta = np.concatenate([lt + rng.uniform(-0.1, 0.1, lt.size),
                            coef * (1 + rng.uniform(-0.15, 0.15, coef.size))])
    theta = np.insert(theta, play_index(lt.size), strength * (1 + rng.uniform(-0.15, 0.15)))
    n = sum(r.size for r in runs)
    s = StepSeries(runs, np.zeros(n), np.arange(n), STEP_S)
    s.y = design_matrix(s, np.exp(theta[:2]), play) @ theta[2:]
    s.y = s.y + rng.normal(0, noise, n)
    return s, theta


@pytest.fixture(scope="module")
def hysteretic() -> dict:
    """A design with a play of T or of its faster node, 6 units on two loops at 0.7 and 1.5
    C/min (a lag mimics a play at one rate, not at two)."""
    rng = np.random.default_rng(SEED)
    design = _design(rng)
    node = int(rng.integers(0, 2)) if np.exp(design[0][0]) <= 3000 else 0
    play = Play(node, float(rng.integers(4, 10)))
    # ppm per 50 C of (play - x): 2-5 ppm/C, as the population draws
    strength = float(rng.uniform(2.0, 5.0)) * 50.0
    noise = float(rng.uniform(2.0, 4.0))
    runs = [_program(3.0, 0.7, 20, rng), _program(3.0, 1.5, 20, rng)]
    units = {f"u{i}": _unit(design, runs, play, strength, rng, noise) for i in range(6)}
    msg = (f"seed {SEED}: play of node {node}, {play.width_c:g} C, {strength / 50:.1f} ppm/C, "
           f"noise {noise:.1f} ppm")
    return {"rng": rng, "design": design, "play": play, "strength": strength, "noise": noise,
            "units": units, "msg": msg}


@pytest.fixture(scope="module")
def prior(hysteretic: dict) -> fp.DesignPrior:
    return fp.learn({sn: s for sn, (s, _) in hysteretic["units"].items()}, k=2)


@pytest.mark.slow
def test_the_planted_play_is_chosen(hysteretic: dict, prior: fp.DesignPrior) -> None:
    p = prior
    msg = hysteretic["msg"]
    assert p.play is not None, msg
    assert p.play.node == hysteretic["play"].node, f"{msg}: chose {p.play}"
    assert abs(p.play.width_c - hysteretic["play"].width_c) <= 1.0, f"{msg}: chose {p.play}"
    assert p.unit_thetas is not None and p.unit_thetas.shape[1] == 2 + n_coef(2) + 1
    assert p.as_dict()["play"]["form"].startswith("play("), msg


@pytest.mark.slow
def test_the_play_carries_a_short_run_to_another_rate(hysteretic: dict, prior: fp.DesignPrior,
                                                       monkeypatch: pytest.MonkeyPatch
                                                       ) -> None:
    """A 2 h loop at 2 C/min predicts the unit on a program unlike the fleet's (2.5 C/min,
    hour-long soaks, where a lag settles and a play holds) better with the design's play than
    the same prior without it, the exported law's play coefficient near the unit's own."""
    assert prior.play is not None, hysteretic["msg"]
    monkeypatch.setattr(fp, "PLAY_GAIN", float("inf"))
    without = fp.learn({sn: s for sn, (s, _) in hysteretic["units"].items()}, k=2)
    assert without.play is None
    rng = np.random.default_rng(SEED + 1)
    ref = all_steps(StepSeries([_program(4.0, 2.5, 60, rng)], np.zeros(0),
                               np.zeros(0, dtype=np.int64), STEP_S))
    j = play_index(2)
    for i in range(2):
        short, truth = _unit(hysteretic["design"], [_program(2.0, 2.0, 15, rng)],
                             hysteretic["play"], hysteretic["strength"], rng,
                             hysteretic["noise"])
        want = design_matrix(ref, np.exp(truth[:2]), hysteretic["play"]) @ truth[2:]
        errs, laws = [], []
        for p in (prior, without):
            law = function_fit(short, p, map_fit(short, p).s2).law()
            got = design_matrix(ref, np.exp(law[:2]), p.play) @ law[2:]
            errs.append(float(np.sqrt(np.mean((got - want) ** 2))))
            laws.append(law)
        msg = (f"{hysteretic['msg']} unit {i}: {errs[0]:.2f} ppm with the play, {errs[1]:.2f} "
               f"without; its coefficient {laws[0][j]:.1f} against {truth[j]:.1f}")
        assert errs[0] < 0.85 * errs[1], msg
        # the nodes' cubes trade with the play's coefficient on a short run (the prediction
        # above is what a unit gets): its sign and size, not its last digit
        assert abs(laws[0][j] - truth[j]) < 0.6 * abs(truth[j]), msg


def test_the_exported_head_is_the_law_with_its_play(hysteretic: dict) -> None:
    """law_head's NodeFit on [T, nodes, h] / 50 C computes design_matrix @ coefficients."""
    s, theta = hysteretic["units"]["u1"]
    play = hysteretic["play"]
    taus = np.exp(theta[:2])
    offset, scale = 3.0, 40.0
    head = law_head(theta, 2, offset, scale, play=True)
    z = np.column_stack([s.nodes.z(taus), play.column(s, taus)])
    want = design_matrix(s, taus, play) @ theta[2:]
    assert np.allclose(head.predict(z) * scale + offset, want, atol=1e-6 * np.abs(want).max())


@pytest.mark.slow
def test_a_line_without_hysteresis_gets_no_play() -> None:
    from tests.test_fleet_prior import _unit as plain_unit

    rng = np.random.default_rng(SEED + 2)
    design = _design(rng)
    noise = float(rng.uniform(2.0, 5.0))
    full = _program(6.0, 1.5, 30, rng)
    p = fp.learn({f"u{i}": plain_unit(design, full, rng, noise)[0] for i in range(6)}, k=2)
    assert p.play is None, f"seed {SEED + 2}: chose {p.play}"


def test_train_says_the_design_has_a_play(hysteretic: dict, prior: fp.DesignPrior) -> None:
    """What `train --prior` prints names the play the unit's model runs."""
    from fogsf.prior.map_estimate import DISAGREE_LEVEL
    from fogsf.training.with_prior import prior_lines

    s, _ = hysteretic["units"]["u2"]
    mf = map_fit(s, prior)
    law = function_fit(s, prior, mf.s2).law()
    assert prior.play is not None
    term = prior.play.term(np.exp(law[:2]))
    rec = {"used": True, "units": len(prior.units), "left_out": [], "nodes": 2,
           "design_taus_s": np.exp(prior.mu[:2]).tolist(), "level": DISAGREE_LEVEL,
           "structure_misfit": prior.structure_misfit, **mf.as_dict(),
           "taus_s": np.exp(law[:2]).tolist(), "play": term.as_dict()}
    text = "\n".join(prior_lines(rec))
    assert f"the design's hysteresis {term.describe()}" in text, text
    assert term.describe().startswith("play(T," if prior.play.node == 0 else "play(lag(T,")


def test_the_front_end_runs_the_fleet_play() -> None:
    """The exported model's front end (float32, `reference.frontend`) computes the play's
    column `Play.column` fits the law with: the play of the law's node at its time constant,
    primed at the log's first step, over 50 C."""
    from fogsf.models import reference
    from fogsf.models.features import front_end_for, physical_normaliser
    from fogsf.models.structures.hysteresis import spec_with_play
    from fogsf.models.structures.physics_nodes import node_spec
    from fogsf.prior.unit_fit import step_series
    from fogsf.sim import simulate
    from tests.test_hysteresis_term import _partial_run

    log = simulate(_partial_run(0)).log
    taus = np.array([1500.0, 400.0])  # unsorted: node 1 is the faster one
    play = Play(1, 6.0)
    spec = spec_with_play(node_spec(tuple(np.sort(taus))), play.term(taus))
    fe = front_end_for([log], STEP_S, spec.taus_s, plays=spec.plays)
    s = reference.frontend(log.temp_c, fe).s
    feat = (s.astype(np.float64) @ physical_normaliser(spec).feat_w.T.astype(np.float64))[:, -1]
    want = play.column(all_steps(step_series([log], STEP_S)), taus)
    assert play.term(taus).tau_a_s == 400.0
    np.testing.assert_allclose(feat, want, atol=2e-4)
