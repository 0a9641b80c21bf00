"""`fogsf train --prior FLEET --unit SN`: the prior learned from the database alone, what it
prints, an ordinary model written, the unit recorded; refusals in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.fleet.store import open_store
from tests.fleet_units import small_line

SEED = 3803


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return small_line(tmp_path_factory.mktemp("fleet"), SEED, 4, (2.0, 1.0))


@pytest.mark.slow
def test_train_with_the_prior_records_the_unit(fleet: dict, capsys: pytest.CaptureFixture
                                               ) -> None:
    out = fleet["tmp"] / "m-new"
    assert main(["train", "--prior", fleet["db"], "--unit", "SN-new", "--train",
                 str(fleet["new"]), "--test", str(fleet["test"]), "--out", str(out),
                 "--iters", "2", "--no-progress"]) == 0
    text = capsys.readouterr().out
    msg = f"design {fleet['design']} (seed {SEED})"
    assert "design's prior: " in text and "learned from 4 units" in text, msg
    m = json.loads((out / "metrics.json").read_text())
    rec = m["prior"]
    assert rec["units"] == 4 and rec["nodes"] in (1, 2, 3), msg
    assert rec["structure_misfit"] >= 1.0 and "x their noise" in text, msg
    if rec["used"]:
        assert "share of the posterior precision" in text
        assert (out / "stream.json").is_file()  # an ordinary model: export reads it
        assert m["features"][0] == "T" and len(m["filter_tau_s"]) == rec["nodes"]
        lo, hi = rec["interval_ppm"]
        assert lo == m["noise_floor_ppm"] and hi > lo, msg
        assert "expected test RMS with the prior's spread" in text
    else:
        assert "fitted alone" in text
    with open_store(fleet["db"]) as store:
        assert store.has("SN-new")
        assert store.unit("SN-new").summary["series"]


def test_refusals_in_one_line(fleet: dict, capsys: pytest.CaptureFixture) -> None:
    base = ["train", "--train", str(fleet["new"]), "--out", str(fleet["tmp"] / "x")]
    assert main([*base, "--unit", "SN9"]) == 2
    assert main([*base, "--prior", fleet["db"], "--structure", "bank"]) == 2
    missing = Path(fleet["tmp"]) / "missing.fleet"
    assert main([*base, "--prior", str(missing)]) == 2
    assert not missing.exists()  # the prior reads a fleet, it does not create one
    one = str(Path(fleet["tmp"]) / "one.fleet")
    with open_store(one) as store:
        store.add(open_store(fleet["db"]).unit("SN0"))
    assert main([*base, "--prior", one]) == 2
    err = capsys.readouterr().err
    assert "--prior FLEET" in err and "drop --model" in err and "no such fleet" in err
    assert "at least two units" in err
