"""What the fleet caches at its state (`fleet.schema`): `fleet check`'s result and the
design's prior, read back only at the state they were computed at; every add and remove
makes a new state. On SQLite and PostgreSQL."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from fogsf.fleet import check as check_mod
from fogsf.fleet import new_unit
from fogsf.fleet.check import check_fleet, checked
from fogsf.fleet.records import UnitRecord
from fogsf.fleet.schema import state_of
from fogsf.fleet.store import open_store
from fogsf.prior.design_prior import DesignPrior
from fogsf.prior.unit_fit import Play, StepSeries
from tests.fleet_units import fake_record, fleet_urls


def _unit(i: int, far: str = "") -> UnitRecord:
    """A made-up unit; `far`: the feature it lies far off the line in."""
    rec = fake_record(f"SN{i:03d}", seed=i)
    rng = np.random.default_rng(i)
    rec.figures["response_ppm"] = {k: float(rng.normal(m, 1)) + (60.0 if far == k else 0.0)
                                   for k, m in (("soak", 10.0), ("ramp", -5.0))}
    rec.summary["series"] = {"made up": i}  # a summary the prior would read
    return rec


def _fleet(make: Callable[[Path], str], tmp_path: Path, n: int) -> str:
    url = make(tmp_path)
    with open_store(url) as store:
        for i in range(n):
            store.add(_unit(i, far="ramp" if i == 3 else ""))
    return url


def _flags(result: check_mod.CheckResult) -> list[tuple[str, str]]:
    return sorted((o.unit, o.why) for o in result.outliers)


@pytest.mark.parametrize("make", fleet_urls())
def test_check_cached_gives_the_flags_computed_and_recomputes_after_add_and_remove(
        make: Callable[[Path], str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    url = _fleet(make, tmp_path, 8)
    calls: list[int] = []

    def counted(units: list[UnitRecord], false_alarm: float = 0.01) -> check_mod.CheckResult:
        calls.append(len(units))
        return check_fleet(units, false_alarm)

    monkeypatch.setattr(check_mod, "check_fleet", counted)
    first, _, _ = checked(url)
    with open_store(url, "read") as store:
        direct = check_fleet(store.units())
    assert _flags(first) == _flags(direct) and [u for u, _ in _flags(first)] == ["SN003"]
    again, units, _ = checked(url, with_units=True)  # from the cache: not computed again
    assert calls == [8] and units is not None and len(units) == 8
    assert _flags(again) == _flags(first) and again.z == first.z
    assert again.threshold_z == first.threshold_z
    assert again.message() == first.message()
    checked(url, 0.05)  # another level: its own result
    assert calls == [8, 8]

    with open_store(url) as store:
        store.add(_unit(20, far="soak"))
    after_add, _, _ = checked(url)
    assert calls[-1] == 9
    assert [u for u, _ in _flags(after_add)] == ["SN003", "SN020"]
    with open_store(url) as store:
        store.remove("SN003")
    after_remove, _, _ = checked(url)
    assert calls[-1] == 8 and [u for u, _ in _flags(after_remove)] == ["SN020"]
    with open_store(url, "read") as store:
        assert _flags(after_remove) == _flags(check_fleet(store.units()))


def _small_prior(seed: int) -> DesignPrior:
    rng = np.random.default_rng(seed)
    p = 5
    a = rng.normal(size=(p, p))
    t = [rng.normal(size=40).astype(np.float32).astype(np.float64) for _ in range(2)]
    return DesignPrior(
        k=1, mu=rng.normal(size=p), sigma=a @ a.T, units=["SN000", "SN001"],
        left_out=[{"unit": "SN009", "why": "far"}], k_scores={1: 2.5, 2: float("nan")},
        between=a.T @ a, noise=np.eye(p) * 1e-3, sigma_check=a @ a.T + np.eye(p),
        step_noise_ppm2=3.25, unit_thetas=rng.normal(size=(2, p)),
        reference=StepSeries(t, np.zeros(80), np.arange(80), 5.0), play=Play(1, 6.0),
        structure_misfit=1.0123456789)


def test_the_prior_comes_back_from_the_cache_bit_for_bit() -> None:
    prior = _small_prior(1)
    back = DesignPrior.from_cache(json.loads(json.dumps(prior.to_cache())))
    for name, v in vars(prior).items():
        w = getattr(back, name)
        if isinstance(v, np.ndarray):
            assert w.dtype == v.dtype and np.array_equal(w, v), name
        elif isinstance(v, StepSeries):
            assert all(np.array_equal(x, y) for x, y in zip(v.t_rel, w.t_rel, strict=True))
            assert np.array_equal(v.rows, w.rows) and v.step_s == w.step_s
        elif name == "k_scores":
            assert w[1] == v[1] and np.isnan(w[2])
        else:
            assert w == v, name


@pytest.mark.parametrize("make", fleet_urls())
def test_the_prior_is_learned_once_a_state_and_again_after_add_and_remove(
        make: Callable[[Path], str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    url = _fleet(make, tmp_path, 3)
    learned: list[list[str]] = []

    def learn(summaries: dict[str, dict]) -> DesignPrior:
        learned.append(sorted(summaries))
        return _small_prior(len(learned))

    monkeypatch.setattr(new_unit, "prior_from_summaries", learn)
    first = new_unit.design_prior(url)
    again = new_unit.design_prior(url)
    assert len(learned) == 1 and json.dumps(again.to_cache()) == json.dumps(first.to_cache())
    with open_store(url, "read") as store:
        state = state_of(store)
    with open_store(url) as store:
        store.add(_unit(7))
    new_unit.design_prior(url)
    assert learned[-1] == ["SN000", "SN001", "SN002", "SN007"]
    with open_store(url, "read") as store:
        assert state_of(store) == state + 1
    new_unit.design_prior(url)
    assert len(learned) == 2
    with open_store(url) as store:
        store.remove("SN001")
    assert json.dumps(new_unit.design_prior(url).to_cache()) == json.dumps(
        _small_prior(3).to_cache())
    assert learned[-1] == ["SN000", "SN002", "SN007"]
    with pytest.raises(Exception, match="already in"):  # --unit SN refused before learning
        new_unit.design_prior(url, "SN000")
    assert len(learned) == 3


def test_a_fleet_that_cannot_be_written_is_read_without_its_cache(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    url = _fleet(lambda p: str(p / "line.fleet"), tmp_path, 6)
    from fogsf.fleet import store as store_mod

    def refuse(*args: object, **kwargs: object) -> None:
        raise store_mod.UserError("read-only")

    monkeypatch.setattr(store_mod, "open_store",
                        lambda u, mode="create": refuse() if mode == "write"
                        else open_store(u, mode))
    result, _, _ = checked(url)  # computed, nothing kept, nothing said
    with open_store(url, "read") as store:
        assert not store.execute("SELECT * FROM fleet_cache").fetchall()
        assert _flags(result) == _flags(check_fleet(store.units()))
