"""The bank's ridge penalty, lowered from the prior only by logs with many held-out parts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from ramp_logs import short_ramp

from fogsf.trainer.models.lag_bank import BANK_LAMBDA, bank_name, bank_penalty
from fogsf.trainer.models.stream import StreamModel
from fogsf.trainer.training import structure_choice as sc
from fogsf.trainer.training.options import TrainOptions
from fogsf.trainer.training.structure_choice import (
    PENALTIES,
    PENALTY_MIN_FOLDS,
    PHYSICS,
    StepData,
    choose,
    choose_penalty,
)
from fogsf.trainer.training.train import run_training

FAST = {"iters": 30, "hidden": 8, "layers": 1, "batch_size": 8}


def test_bank_names_carry_their_penalty() -> None:
    assert bank_name() == "bank" and bank_penalty("bank") == BANK_LAMBDA
    for lam in PENALTIES:
        assert bank_penalty(bank_name(lam)) == lam and bank_name(lam) != "bank"
    assert bank_penalty("physics2") is None


def _folds(n: int, per_fold: list[float]) -> list[list[float]]:
    """n folds of 3 windows each, fold k's squared error per_fold[k]."""
    return [[per_fold[k]] * 3 for k in range(n)]


@pytest.mark.parametrize("errors, chosen", [
    # every lower penalty better on most parts: down to the lowest
    ({"bank:0.0001": 0.9, "bank:1e-05": 0.8, "bank:1e-06": 0.7}, 1e-6),
    # 1e-5 better in the pooled score but on a minority of parts: stop at 1e-4
    ({"bank:0.0001": 0.9, "bank:1e-05": "minority", "bank:1e-06": 0.1}, 1e-4),
    # the first lower penalty worse: the prior
    ({"bank:0.0001": 1.1, "bank:1e-05": 0.1, "bank:1e-06": 0.1}, BANK_LAMBDA),
])
def test_a_lower_penalty_must_win_most_parts_and_the_score(
        monkeypatch: pytest.MonkeyPatch, errors: dict, chosen: float) -> None:
    n = 18
    prior = _folds(n, [1.0] * n)

    def folds(name: str, sd: StepData, **kw: object) -> list[list[float]]:
        e = errors[name]
        if e == "minority":  # 8 of 18 parts much better, the other 10 slightly worse
            return _folds(n, [0.1] * 8 + [1.05] * (n - 8))
        return _folds(n, [e] * n)

    monkeypatch.setattr(sc, "heldout_folds", folds)
    from types import SimpleNamespace

    sd = StepData(SimpleNamespace(step_s=5.0), [np.zeros(n)], np.zeros(n),  # type: ignore[arg-type]
                  np.arange(n))
    pc = choose_penalty(sd, prior)
    assert pc.penalty == chosen and pc.name == bank_name(chosen)
    assert list(pc.scores)[0] == "bank" and pc.scores["bank"] == pytest.approx(1.0)
    if chosen != BANK_LAMBDA:
        assert pc.wins[pc.name] > n // 2
        assert f"the bank's penalty: {chosen:g}, below the prior" in \
            sc.penalty_message(pc.as_dict())
    else:
        assert "the prior" in sc.penalty_message(pc.as_dict())


def test_logs_with_few_parts_keep_the_prior() -> None:
    """Two ramps hold 6 held-out parts, under PENALTY_MIN_FOLDS: the rule does not run."""
    c = choose([short_ramp(0.6, 51, gyro_seed=4), short_ramp(2.4, 52, gyro_seed=4)])
    assert 2 * sc.SPLIT_PARTS < PENALTY_MIN_FOLDS
    assert c.name == "bank" and c.penalty is None and c.bank == "bank"
    assert "bank_penalty" not in c.as_dict() and "penalty" not in c.message()


@pytest.fixture(scope="module")
def four_ramps() -> list:
    # development gyro 2 at four rates: 12 held-out parts, where a penalty of 1e-4 predicts
    # most of them better than the prior
    return [short_ramp(r, 60 + i, gyro_seed=2) for i, r in enumerate((0.6, 2.4, 1.2, 0.9))]


def test_many_parts_lower_the_penalty_and_the_model_carries_it(
        four_ramps: list, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The choice lowers the penalty; the trained bank is the ridge fit at that penalty, the
    metrics record the rule's scores, and `fogsf train` says so."""
    c = choose(four_ramps)
    assert c.name == "bank" and c.folds == 4 and c.penalty is not None
    assert c.penalty.folds >= PENALTY_MIN_FOLDS and list(c.scores) == [*PHYSICS, "bank"]
    lam = c.penalty.penalty
    assert lam < BANK_LAMBDA and c.bank == bank_name(lam)
    opts = TrainOptions(model="lag-lstm", progress=False, **FAST)
    m, fitted = run_training(opts, four_ramps, None, tmp_path / "m")
    pen = m["structure_choice"]["bank_penalty"]
    assert pen["penalty"] == lam and pen["heldout_rms_ppm"] == pytest.approx(c.penalty.scores)
    assert fitted.info["lag_bank"]["ridge_lambda"] == lam
    forced = TrainOptions(model="lag-lstm", structure="bank", progress=False, **FAST)
    _, prior = run_training(forced, four_ramps, None, tmp_path / "p")
    assert prior.info["lag_bank"]["ridge_lambda"] == BANK_LAMBDA
    a = StreamModel.load(tmp_path / "m").weights["skip_w"]
    b = StreamModel.load(tmp_path / "p").weights["skip_w"]
    assert not np.array_equal(a, b)  # the lower penalty gives another bank
    from fogsf.trainer.commands.train import format_metrics

    text = format_metrics(m).replace("\n", " ")
    assert f"the bank's penalty: {lam:g}, below the prior" in text
