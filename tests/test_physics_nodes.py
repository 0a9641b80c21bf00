"""Physics nodes: the shared physics fit (variable projection), the node model, its export,
and the default's structure choice."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from ramp_logs import short_ramp

from fogsf.models import reference
from fogsf.models.stream import StreamModel
from fogsf.models.structures.node_fit import discrete_lag, lag_alpha, ridge_fit
from fogsf.models.structures.physics_nodes import (
    NodeTemperatures,
    fit_coefficients,
    identify_taus,
    node_design,
)
from fogsf.training.fitted_model import per_sample_prediction
from fogsf.training.options import TrainOptions
from fogsf.training.structure.choice import (
    CANDIDATES,
    EVIDENCE_FACTOR,
    MULTI_SEGMENT_ORDER,
    PHYSICS,
    choice_message,
    choose,
)
from fogsf.training.structure.heldout import (
    MAX_CHOICE_STEPS,
    MAX_PART_FOLDS,
    SPLIT_PARTS,
    StepData,
    choice_step_s,
    heldout_score,
    part_folds,
)
from fogsf.training.train import run_training

FAST = {"iters": 20, "hidden": 8, "layers": 1, "batch_size": 8}
STEP_S = 5.0


def _program(n: int = 4000, seed: int = 0) -> np.ndarray:
    """A board temperature (C - 20) per 5 s step: soaks and ramps at 0.5, 2 and 1 C/min
    up and down, with a little thermometer noise."""
    pts = [(0, -60.0), (400, -60.0), (1480, 30.0), (1840, 30.0), (2110, -60.0),
           (2300, -60.0), (2840, 30.0), (3400, 30.0), (n, -10.0)]
    t = np.arange(n)
    base = np.interp(t, [p[0] for p in pts], [p[1] for p in pts])
    return base + np.random.default_rng(seed).normal(0.0, 0.01, n)


def test_discrete_lag_is_the_firmware_filter() -> None:
    """The fit's float64 lag is the contract's y += alpha (x - y), primed with x[0]."""
    x = _program(3000)
    for tau in (60.0, 700.0, 7200.0):
        a = lag_alpha(tau, STEP_S)
        ref = reference.lag_filters(x.astype(np.float32), np.array([a], np.float32))[:, 0]
        y = discrete_lag(x, a)
        assert y[0] == x[0]
        assert np.max(np.abs(y - ref)) < 1e-3, tau  # float32 rounding over 3000 steps
    loop = np.empty_like(x)
    acc = x[0]
    for i, v in enumerate(x):
        acc += lag_alpha(700.0, STEP_S) * (v - acc)
        loop[i] = acc
    assert np.allclose(discrete_lag(x, lag_alpha(700.0, STEP_S)), loop, atol=1e-9)


def test_ridge_fit_is_least_squares_without_penalty() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(500, 4))
    y = 3.0 + x @ [1.0, -2.0, 0.5, 0.0] + rng.normal(0, 0.01, 500)
    f = ridge_fit(x, y, 0.0)
    ls, *_ = np.linalg.lstsq(np.column_stack([np.ones(500), x]), y, rcond=None)
    assert f.intercept == pytest.approx(ls[0]) and np.allclose(f.coef, ls[1:])
    assert f.dof == pytest.approx(5.0)
    shrunk = ridge_fit(x, y, 1.0)
    assert np.linalg.norm(shrunk.coef) < np.linalg.norm(f.coef) and shrunk.dof < f.dof


def test_variable_projection_finds_the_time_constants() -> None:
    """SF error from two nodes (300 s and 2400 s behind the board) through a quadratic law
    with a cross term: the fit finds both time constants off the start grid and leaves the
    noise."""
    t = _program()
    nodes = NodeTemperatures([t], STEP_S)
    z = nodes.z((300.0, 2400.0))
    truth = 40.0 + 300.0 * z[:, 1] - 150.0 * z[:, 2] + 80.0 * z[:, 1] * z[:, 2] \
        + 60.0 * z[:, 2] ** 2
    y = truth + np.random.default_rng(2).normal(0.0, 0.5, t.size)
    taus = identify_taus(nodes, y, 2, lam=1e-8)
    assert taus[0] == pytest.approx(300.0, rel=0.05) and taus[1] == pytest.approx(2400.0,
                                                                                    rel=0.05)
    fit = fit_coefficients(nodes.z(taus), y, taus, lam=1e-8)
    assert math.sqrt(np.mean((fit.predict(nodes.z(taus)) - truth) ** 2)) < 0.3
    assert node_design(nodes.z(taus)).shape[1] == 3 + 6 + 1  # linear, products, T^3


def test_heldout_score_prefers_the_true_structure() -> None:
    """Leave one segment out on a log with ramps at three rates: two nodes (the truth)
    predict held-out ramps better than one; a log with one segment is split in three."""
    t = _program()
    nodes = NodeTemperatures([t], STEP_S)
    z = nodes.z((200.0, 3000.0))
    y = 300.0 * z[:, 1] - 250.0 * z[:, 2] + 100.0 * z[:, 1] ** 2 \
        + np.random.default_rng(3).normal(0.0, 0.5, t.size)
    fold = np.searchsorted([1480, 2110, 2840], np.arange(t.size), side="right")
    from fogsf.models.features import front_end_for

    fe = front_end_for([short_ramp(1.0, 1)], STEP_S, ())
    sd = StepData(fe, [t], y, fold)
    one, two = heldout_score("physics1", sd), heldout_score("physics2", sd)
    assert two < 0.1 * one, (one, two)


def test_physics_model_exports_and_the_reference_matches(tmp_path: Path) -> None:
    """A physics-node model goes through the existing artifact (feature rows and the full
    polynomial head): what torch trained is what the numpy reference (the kernel's bits)
    computes, and `fogsf export` writes it with its cross terms."""
    from fogsf.export import export_model

    train = [short_ramp(0.6, 41, gyro_seed=3), short_ramp(2.4, 42, gyro_seed=3)]
    test = short_ramp(1.2, 43, gyro_seed=3)
    opts = TrainOptions(model="lag-lstm", structure="physics", nodes=2, progress=False,
                        **FAST)
    m, fitted = run_training(opts, train, test, tmp_path / "m")
    sm = StreamModel.load(tmp_path / "m")
    assert sm.poly_head and not sm.quad_diag and sm.n_features == 3
    assert len(sm.filter_tau_s) == 2 and m["features"][0] == "T"
    assert fitted.info["physics_nodes"]["taus_s"] == sm.filter_tau_s
    quad = sm.weights["quad_w"]
    assert quad.shape == (3, 3) and quad[0, 1] != 0 and quad[1, 2] != 0  # cross terms
    assert sm.feat_diag and np.allclose(sm.weights["feat_w"], np.full(3, 1 / 50.0))
    want = per_sample_prediction(fitted, test, None)
    got = reference.replay(sm, test.temp_c, test.gyro_dps).sf_ppm.astype(np.float64)
    assert np.max(np.abs(got - want)) < 0.01
    assert m["test"]["after"]["rms_ppm"] < 0.1 * m["test"]["before"]["rms_ppm"]
    export_model(sm, tmp_path / "b", "imu_z")
    text = (tmp_path / "b" / "imu_z.c").read_text()
    assert "quad_w[9]" in text and "IMU_Z_QUAD_DIAG" in (tmp_path / "b" / "imu_z.h").read_text()


@pytest.mark.slow
def test_choice_is_the_first_within_tolerance() -> None:
    """The rule on the training logs alone: several ramps score every candidate on held-out
    parts and keep the bank unless a physics structure is EVIDENCE_FACTOR x better; one ramp
    scores every candidate and takes the first in the rule's order within the tolerance of
    the best (the smaller physics structures first), and a tolerance of 0 takes the best."""
    logs = [short_ramp(0.6, 51, gyro_seed=4), short_ramp(2.4, 52, gyro_seed=4)]
    c = choose(logs)
    assert not c.one_segment and c.folds == 2 and list(c.scores) == [*PHYSICS, "bank"]
    best = min(c.scores[k] for k in PHYSICS)
    if EVIDENCE_FACTOR * best <= c.scores["bank"]:
        assert c.name == next(k for k in PHYSICS if c.scores[k] <= (1 + c.tolerance) * best)
        assert "better than the lag bank" in c.message()
    else:
        assert c.name == "bank" and "no physics structure predicts" in c.message()
    assert "2 ramps, each in 3 parts" in c.message()
    # the parts are held out, not the whole ramps: the development-gyro rule scores differ
    tuned = choose(logs, candidates=MULTI_SEGMENT_ORDER)  # the development-gyro rule
    assert list(tuned.scores) == list(MULTI_SEGMENT_ORDER)
    best = min(tuned.scores.values())
    first = next(k for k in tuned.scores if tuned.scores[k] <= (1 + tuned.tolerance) * best)
    assert tuned.name == first
    assert tuned.scores["bank"] != c.scores["bank"]
    exact = choose(logs, candidates=MULTI_SEGMENT_ORDER, tolerance=0.0)
    assert exact.scores == tuned.scores and exact.scores[exact.name] == best
    one = choose(logs[1:])  # one ramp: in parts, the smaller structures first
    assert one.one_segment and one.folds == 3 and list(one.scores) == list(CANDIDATES)
    assert "one ramp, in 3 parts" in one.message()
    assert f"structure {one.name}" in one.message()
    assert one.name == next(k for k in CANDIDATES
                            if one.scores[k] <= (1 + one.tolerance) * min(one.scores.values()))


def test_two_rates_on_the_default_gyro_take_physics_nodes() -> None:
    """The default gyro trained on 0.5 and 2 C/min: physics nodes predict the held-out parts
    several times better than the lag bank (which interpolates in rate worse: 1.64 x the
    noise floor on the 1 C/min test against 1.17-1.44 x, docs/decisions.md), so the rule
    takes one, and says so."""
    from fogsf.sim.gyro import simulate
    from fogsf.sim.scenarios import paper

    logs = [simulate(paper(0.5, seed=1002)).log, simulate(paper(2.0, seed=4002)).log]
    c = choose(logs)
    assert c.name in PHYSICS, c.scores
    assert c.scores["bank"] >= EVIDENCE_FACTOR * c.scores[c.name] / (1 + c.tolerance)
    assert "better than the lag bank" in c.message()


def _segments(steps: list[int]) -> StepData:
    """Steps data of segments `steps` long (no temperatures: for the folds alone)."""
    from types import SimpleNamespace

    fold = np.repeat(np.arange(len(steps)), steps)
    return StepData(SimpleNamespace(step_s=5.0), [np.zeros(fold.size)], np.zeros(fold.size),
                    fold)


def test_part_folds_are_the_parts_then_dealt_to_a_bounded_number() -> None:
    """Up to MAX_PART_FOLDS parts every part is a fold of its own (contiguous, a third of its
    segment); beyond, part i goes to fold i mod MAX_PART_FOLDS, so the cost of the choice
    grows with the log, not with its square, and no fold holds two parts of one segment."""
    few = MAX_PART_FOLDS // SPLIT_PARTS
    sd = _segments([30] * few)
    f = part_folds(sd)
    assert f.max() + 1 == few * SPLIT_PARTS
    for k in range(few * SPLIT_PARTS):
        idx = np.flatnonzero(f == k)
        assert idx.size == 10 and np.all(np.diff(idx) == 1) and np.all(sd.fold[idx] == k // 3)
    many = _segments([30] * 34)
    g = part_folds(many)
    assert g.max() + 1 == MAX_PART_FOLDS
    for k in range(MAX_PART_FOLDS):
        segs = many.fold[g == k]
        assert np.unique(segs).size == segs.size // 10  # whole parts, each of its own segment
    d = {"chosen": "bank", "heldout_rms_ppm": {"physics1": 2.0, "bank": 1.0}, "segments": 34,
         "one_segment": False, "tolerance": 0.2, "evidence_factor": EVIDENCE_FACTOR}
    assert f"34 ramps, each in 3 parts dealt to {MAX_PART_FOLDS} folds" in choice_message(d)
    assert "dealt" not in choice_message({**d, "segments": few})


def test_long_logs_are_scored_at_a_whole_multiple_of_the_model_step() -> None:
    """The choice keeps the model step for up to MAX_CHOICE_STEPS steps of logs (every bench
    program), and scores longer logs (a week) at the smallest whole multiple under it."""
    from types import SimpleNamespace

    day, week = SimpleNamespace(duration_s=86_400.0), SimpleNamespace(duration_s=604_800.0)
    assert choice_step_s([day], 5.0) == 5.0
    assert choice_step_s([day, day], 5.0) == 10.0
    step = choice_step_s([week], 5.0)
    assert step % 5.0 == 0 and week.duration_s / step <= MAX_CHOICE_STEPS
    assert week.duration_s / (step - 5.0) > MAX_CHOICE_STEPS


@pytest.mark.parametrize("bank, phys, chosen", [
    (10.0, (4.0, 3.9, 4.1), "physics1"),  # 2.5 x better: the first within 20 % of 3.9
    (9.7, (4.0, 3.9, 4.1), "bank"),  # 9.7 < 2.5 x 3.9: not evidence enough
    (10.0, (4.7, 3.9, 4.1), "physics2"),  # physics1 is over 1.2 x 3.9
])
def test_several_ramps_keep_the_bank_unless_physics_is_evident(
        monkeypatch: pytest.MonkeyPatch, bank: float, phys: tuple[float, ...],
        chosen: str) -> None:
    """The several-ramp rule on given held-out scores: the bank unless the best physics
    structure scores EVIDENCE_FACTOR x better, then the smallest within the tolerance."""
    import fogsf.training.structure.choice as sc

    scores = {"bank": bank, **dict(zip(PHYSICS, phys, strict=True))}
    monkeypatch.setattr(sc, "heldout_folds", lambda name, sd, **kw: [[scores[name] ** 2]])
    c = choose([short_ramp(0.6, 51, gyro_seed=4), short_ramp(2.4, 52, gyro_seed=4)])
    assert c.name == chosen and c.scores == {**dict(zip(PHYSICS, phys, strict=True)),
                                             "bank": bank}
    assert c.as_dict()["evidence_factor"] == EVIDENCE_FACTOR


def test_choose_scores_long_logs_at_the_coarser_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """`choose` builds its steps at `choice_step_s` (here forced coarse by a small
    MAX_CHOICE_STEPS) and still chooses among every candidate."""
    import fogsf.training.structure.choice as sc
    import fogsf.training.structure.heldout as sh

    logs = [short_ramp(0.6, 51, gyro_seed=4), short_ramp(2.4, 52, gyro_seed=4)]
    seen: list[float] = []
    real = sh.step_data

    def spy(lg, step_s=5.0, latitude_deg=None):
        seen.append(step_s)
        return real(lg, step_s, latitude_deg)

    monkeypatch.setattr(sc, "step_data", spy)
    choose(logs)
    assert seen == [5.0]
    monkeypatch.setattr(sh, "MAX_CHOICE_STEPS", 200)
    c = choose(logs)
    total = sum(lg.duration_s for lg in logs)
    assert seen[-1] > 5.0 and seen[-1] % 5.0 == 0 and total / seen[-1] <= 200
    assert set(c.scores) == {*PHYSICS, "bank"} and all(np.isfinite(list(c.scores.values())))


def test_part_folds_of_short_segments_leave_no_empty_fold() -> None:
    """A segment shorter than SPLIT_PARTS steps gives fewer parts; the folds are numbered
    without gaps, so every fold holds steps and no held-out score is a mean of nothing."""
    sd = _segments([31, 2, 1])
    f = part_folds(sd)
    assert np.array_equal(np.unique(f), np.arange(f.max() + 1)) and f.max() + 1 == 6


@pytest.mark.slow
def test_choice_progress_bar_counts_every_fit(capsys: pytest.CaptureFixture[str]) -> None:
    """`choose(progress=True)` draws a bar over candidates x folds on stderr (what `fogsf
    train` shows while a week of logs is scored); without it nothing is printed."""
    logs = [short_ramp(0.6, 51, gyro_seed=4), short_ramp(2.4, 52, gyro_seed=4)]
    quiet = choose(logs)
    assert capsys.readouterr().err == ""
    loud = choose(logs, progress=True)
    err = capsys.readouterr().err
    assert "structure choice:" in err and f"/{4 * 2 * SPLIT_PARTS} [" in err  # 4 x 6 fits
    assert loud.scores == quiet.scores
