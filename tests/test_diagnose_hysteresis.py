"""A hidden SF hysteresis planted in simulated logs: does diagnose name it `hysteresis`?

Cases (`cases.draw_population("effect", "hysteresis", "", seed)`, ranges stated in
fogsf.diagnose.cases.planted): a population gyro (without its own hysteresis), a play of its
coil temperature of width 4-10 C and strength 3-8 ppm/C, partial cycles of 3.5-5 h (turns,
rate, soaks drawn), table and simulator seed, all from a seeded generator. CI runs the fixed
small sample below; `make bench-diagnose` states the rate over many. A failure prints the
case and its seed: `cases.draw_population("effect", "hysteresis", "", seed)` rebuilds it.

Rules (case_judge.judge): never another cause; named with the loop's height (strength x width)
within 50 %, or, when its visible part stays under 3x the noise floor, not named.
Out-of-catalogue residuals (test_diagnose_planted) must stay `unexplained` with the
hysteresis form in the catalogue.
"""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.diagnose import report, verdict
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import judge as case_judge
from fogsf.diagnose.cases import planted as cases
from fogsf.sim.population import DEV_SEEDS

MASTER_SEED = 20261123
N_CASES = 4


def _seeds() -> list[int]:
    rng = np.random.default_rng([MASTER_SEED, 19])
    return [int(s) for s in rng.integers(1, DEV_SEEDS.stop, N_CASES)]


@pytest.mark.slow
def test_planted_hysteresis_is_named_and_never_misnamed() -> None:
    results = []
    named = 0
    for seed in _seeds():
        case = cases.draw_population("effect", "hysteresis", "", seed)
        logs, truth = case_build.build(case)
        j = report.to_json(verdict.diagnose(logs), {}, None)
        out = case_judge.judge_report(case, truth, j)
        where = f"seed {seed}: [{case.describe()}] -> {out.reason}"
        assert out.cause in (None, "hysteresis"), f"wrong cause {where}"
        named += out.cause == "hysteresis"
        results.append((out.ok, where))
    bad = [w for ok, w in results if not ok]
    assert len(bad) <= 1, "\n".join(bad)
    assert named >= 1, "no planted hysteresis named in the sample:\n" + "\n".join(
        w for _, w in results)


def test_partial_cycle_profiles_turn_back_inside_their_range() -> None:
    for seed in _seeds():
        case = cases.draw_population("effect", "hysteresis", "", seed)
        levels = case.config.profile.levels_c
        d = np.diff(levels)
        assert np.all(d[:-1] * d[1:] < 0)  # every leg turns back
        assert 4.0 <= case.config.effects[0].params["width_c"] <= 10.0
        assert 3.0 <= case.config.effects[0].strength <= 8.0
