"""`fogsf diagnose` on logs on disk: the JSON contract, the report, the simulator config."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogsf.cli import main as cli
from fogsf.diagnose import report
from fogsf.diagnose.cases import build as case_build
from fogsf.diagnose.cases import planted as cases
from fogsf.logs.logio import read_log
from fogsf.logs.writer import write_log
from fogsf.sim.config import SimConfig

CONTRACT_CANDIDATE = {"effect", "params", "heldout_rms_before_ppm", "heldout_rms_after_ppm",
                      "gain_pct", "evidence"}


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("diag")
    case = cases.draw("effect", "bias_drift", 11)
    logs, truth = case_build.build(case)
    log_path = tmp / "run.csv"
    write_log(log_path, logs[0])
    out = tmp / "out"
    rc = cli.main(["diagnose", str(log_path), "--json", str(out / "d.json"),
                   "--report", str(out / "d.md")])
    assert rc == 0
    return {"dir": out, "truth": truth, "json": json.loads((out / "d.json").read_text()),
            "log": log_path}


@pytest.mark.slow
def test_json_has_the_contract(diagnosed: dict) -> None:
    j = diagnosed["json"]
    assert {"base", "candidates", "cause", "unexplained", "extended_model"} <= set(j)
    assert {"rms_ppm", "whiteness_p"} <= set(j["base"])
    assert {c["effect"] for c in j["candidates"]} == set(cases.CATALOGUE_EFFECTS)
    for c in j["candidates"]:
        assert CONTRACT_CANDIDATE <= set(c)
    assert j["cause"] == "bias_drift"
    assert j["unexplained"] is False
    c = next(c for c in j["candidates"] if c["effect"] == "bias_drift")
    lo, hi = c["params"]["strength_dph_per_c_ci95"]
    assert lo <= diagnosed["truth"]["strength"] <= hi
    assert c["heldout_rms_after_ppm"] < c["heldout_rms_before_ppm"]


def test_extended_model_is_a_simulator_config_that_comes_closer(diagnosed: dict,
                                                                tmp_path: Path) -> None:
    j = diagnosed["json"]
    cfg_path = diagnosed["dir"] / "d.sim.json"
    assert json.loads(cfg_path.read_text()) == j["extended_model"]
    cfg = SimConfig.load(cfg_path)
    assert [e.name for e in cfg.effects][-1] == "bias_drift"
    sim = j["simulation"]
    assert sim["rms_extended_sim_ppm"] < sim["rms_base_sim_ppm"]
    # the extended simulation is within 1.3x the noise floor of the measured windows
    assert sim["rms_extended_sim_ppm"] < 1.3 * sim["noise_floor_ppm"]
    out = tmp_path / "sim.csv"
    assert cli.main(["simulate", "--config", str(cfg_path), "--out", str(out)]) == 0
    assert len(read_log(out)) > 1000


def test_report_has_plots(diagnosed: dict) -> None:
    md = (diagnosed["dir"] / "d.md").read_text()
    assert "## Candidates" in md and "bias_drift" in md
    assert (diagnosed["dir"] / "d_residual.png").stat().st_size > 10_000


def test_bad_input_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["diagnose", str(tmp_path / "nope.csv")]) == 2
    assert "no such file" in capsys.readouterr().err
    case = cases.draw("null", "", 3)
    logs, _ = case_build.build(case)
    short = tmp_path / "short.csv"
    write_log(short, logs[0].slice(0, 3000))  # 5 minutes
    assert cli.main(["diagnose", str(short)]) == 2
    assert "windows" in capsys.readouterr().err
    assert cli.main(["diagnose", str(short), "--cv", "runs"]) == 2


def test_noise_floor_is_inspects_window_noise_and_the_base_resolution(
        diagnosed: dict, capsys: pytest.CaptureFixture[str]) -> None:
    b = diagnosed["json"]["base"]
    capsys.readouterr()
    assert cli.main(["inspect", str(diagnosed["log"]), "--window-s", f"{b['window_s']:g}",
                     "--json"]) == 0
    inspected = json.loads(capsys.readouterr().out)["metrics"]["noise_floor_ppm"]
    assert b["window_noise_ppm"] == pytest.approx(inspected, rel=1e-9)
    assert b["noise_floor_ppm"] ** 2 == pytest.approx(
        b["window_noise_ppm"] ** 2 + b["model_floor_ppm"] ** 2, rel=1e-9)
    assert b["noise_floor_ppm"] > b["window_noise_ppm"]
    text = report.summary_text(diagnosed["json"])  # what `fogsf diagnose` prints
    assert (f"noise floor = window noise {inspected:.2f} ppm (one log's is what `fogsf inspect "
            f"--window-s {b['window_s']:g}` reports) and the base's resolution "
            f"{b['model_floor_ppm']:.2f} ppm in quadrature") in text
