"""`benchmarks.population`'s own checks: its protocols' chamber programs, its summary, the
models it trains, and its runs outside the population's forms (moved from
tests/test_lag_bank.py and tests/test_population.py: the library's tests import no bench)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import population as bench
from benchmarks.population import PROTOCOLS, _train_options, run_profile, summarise
from fogsf.sim.profiles import breakpoints
from fogsf.training.options import DEFAULT_MODEL


def test_protocol_programs_hold_what_they_promise() -> None:
    loop = breakpoints(run_profile("loop_train"))
    assert loop[-1, 0] == pytest.approx(3.75 * 3600)
    rates = np.diff(loop[:, 1]) / np.diff(loop[:, 0]) * 60.0
    assert sorted(set(np.round(rates, 3))) == [-2.0, 0.0, 1.0]
    assert set(PROTOCOLS) == {"a", "b", "c", "d", "e", "f"}
    # the envelope holds the test's own program among its training runs (other noise)
    train, test = PROTOCOLS["f"]
    assert test in {r.removesuffix("_again") for r in train} and test not in train
    assert np.array_equal(breakpoints(run_profile("loop_test_again")),
                          breakpoints(run_profile(test)))


def test_summary_counts_interval_coverage() -> None:
    def row(seed: int, ratio: float, inside: bool) -> dict:
        def case(one: bool) -> dict:
            return {"default": {"ratio": ratio, "std_ratio": ratio, "inside": inside,
                                "k_needed": ratio, "train_ratio": 1.0, "one_segment": one,
                                "upper_over_actual": 2.0 * ratio}}

        return {"gyro_seed": seed, "cases": {"a": case(True), "e": case(False)}}

    s = summarise([row(1, 1.0, True), row(2, 2.0, False), row(3, 3.0, True)], ("default",),
                  ("a", "e"))
    cov = s["interval_coverage"]
    assert cov["inside"] == 4 and cov["cases"] == 6
    assert cov["one_segment"]["inside"] == 2 and cov["several"]["cases"] == 3
    assert cov["one_segment"]["upper_over_actual_median"] == 4.0
    assert s["a/default"]["ratio"]["median"] == 2.0 and s["a/default"]["ratio"]["worst"] == 3.0
    assert s["e-train/default"]["ratio"]["median"] == 1.0


@pytest.mark.parametrize("model, structure, nodes", [
    ("default", "auto", 1), ("bank", "bank", 1), ("node", "node", 1),
    ("physics2", "physics", 2)])
def test_bench_population_forces_the_structures_it_names(model: str, structure: str,
                                                         nodes: int) -> None:
    """bench-population's bank, node and physics2 are the default model with its physics
    part forced (`fogsf train --structure ...`), the default model its own choice."""
    opts = _train_options(model, 3)
    assert (opts.model, opts.structure, opts.nodes) == (DEFAULT_MODEL, structure, nodes)
    assert opts.transfer_check == (model == "default")


def test_the_population_bench_runs_gyros_outside_the_forms(
        capsys: pytest.CaptureFixture[str]) -> None:
    """`benchmarks.population --outside FORM` trains and scores the gyros with the form (its
    scenario says so, and the figures differ from the gyro as drawn); an unknown form, or
    one with --magnitudes (which would ignore it), is refused before any work."""
    row = bench.bench_gyro(3, ("poly",), ("a",), "sensor")
    plain = bench.bench_gyro(3, ("poly",), ("a",))
    assert row["gyro"] == plain["gyro"] + ":sensor"
    a, b = row["cases"]["a"]["poly"], plain["cases"]["a"]["poly"]
    assert a["ratio"] != pytest.approx(b["ratio"], rel=1e-3)
    for argv in (["--outside", "draft", "--n", "1"],
                 ["--outside", "vent", "--magnitudes", "--n", "1"]):
        with pytest.raises(SystemExit) as e:
            bench.main(argv)
        assert e.value.code == 2
    err = capsys.readouterr().err
    assert "sensor" in err and "vent" in err and "--magnitudes" in err
