"""`fogsf plan --prior`'s search: the shortest candidate that reaches the target, none when
the target is beyond every candidate, and a program found only once it is reached."""

from __future__ import annotations

import numpy as np

from fogsf.plan.prior_program import board_steps, shortest
from fogsf.plan.programs import Limits
from fogsf.prior import design_prior as fp
from tests.test_fleet_prior import SEED, _design, _program, _unit


def _prior() -> fp.DesignPrior:
    rng = np.random.default_rng(SEED + 10)
    design = _design(rng)
    full = _program(6.0, 1.5, 30, rng)
    return fp.learn({f"u{i}": _unit(design, full, rng, 3.0)[0] for i in range(5)}, k=2)


def test_shortest_program_reaching_the_target() -> None:
    prior = _prior()
    limits = Limits(-40.0, 50.0, 3.0, 1.6)  # two candidates: 1.25 and 1.5 h
    best, tried = shortest(prior, limits, (0.5, 2.0), target=50.0, n_units=1)
    assert best is not None and best is tried[-1] and best.median <= 50.0
    assert len(tried) == 1  # the first (shortest) candidate already reaches a loose target
    none, tried = shortest(prior, limits, (0.5, 2.0), target=1.0 + 1e-9, n_units=1)
    assert none is None and len(tried) == 2 and all(r.median > 1.0 + 1e-9 for r in tried)
    assert [r.program.hours for r in tried] == sorted(r.program.hours for r in tried)


def test_board_follows_the_chamber_with_a_lag() -> None:
    pts = ((0.0, -40.0), (3600.0, -40.0), (3600.0 + 90 * 60, 50.0), (3600.0 + 150 * 60, 50.0))
    b = board_steps(pts)
    assert abs(b[0] + 60.0) < 0.5 and abs(b[-1] - 30.0) < 1.0  # minus 20 C at both ends
    ramp = b[int(3600 / 5) + 200]  # mid-ramp: behind the chamber (which is 200 steps on)
    assert ramp < -60.0 + 200 * 5 / 60.0
