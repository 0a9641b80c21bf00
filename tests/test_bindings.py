"""cffi bindings and `fogsf replay`: the build cache, the CSV, the printed metrics, the plot."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from fogsf.bindings.kernel import ROOT, Kernel, build_kernel, default_build_root
from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.logio import read_log
from fogsf.logs.writer import write_log
from fogsf.models import reference, samples


def small_log(path, seed: int = 0, hours: float = 1.0) -> ChamberLog:
    temp, gyro = samples.chamber_ramp(hours=hours, seed=seed)
    n = temp.shape[0]
    log = ChamberLog(time_s=np.arange(n) * 0.1, temp_c=temp, table_rate_dps=np.full(n, 10.0),
                     gyro_dps=gyro, earth_rate_dps=np.zeros(n))
    write_log(path, log)
    return read_log(path)  # what replay reads (the CSV's precision)


def test_build_is_cached_by_model_id(tmp_path) -> None:
    model = samples.random_model(seed=4)
    a = build_kernel(model, root=tmp_path)
    mtime = a.shared.stat().st_mtime_ns
    b = build_kernel(samples.random_model(seed=4), root=tmp_path)
    assert b.shared == a.shared and b.shared.stat().st_mtime_ns == mtime
    assert model.model_id in a.directory.name
    other = build_kernel(samples.random_model(seed=5), root=tmp_path)
    assert other.directory != a.directory


def test_a_checkout_builds_in_its_tree_only_when_run_from_inside(tmp_path, monkeypatch
                                                                   ) -> None:
    monkeypatch.delenv("FOGSF_BUILD_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(ROOT / "docs")
    assert default_build_root() == ROOT / "build" / "kernels"
    monkeypatch.chdir(tmp_path)  # a user's lab folder: the user's cache, not the checkout
    assert default_build_root() == tmp_path / "cache" / "fogsf" / "kernels"


def test_kernel_refuses_a_library_of_another_model(tmp_path) -> None:
    a, b = samples.random_model(seed=4), samples.random_model(seed=5)
    with pytest.raises(UserError, match="kernel of model"):
        Kernel(b, build_kernel(a, root=tmp_path))


def test_replay_writes_the_kernel_output_and_prints_metrics(tmp_path, capsys, monkeypatch
                                                             ) -> None:
    monkeypatch.setenv("FOGSF_BUILD_DIR", str(tmp_path / "kernels"))
    model = samples.random_model(3, 4, 1, 8, decimation=10, seed=6)
    model.save(tmp_path / "m")
    log = small_log(tmp_path / "run.csv", hours=2.0)
    rc = main(["replay", str(tmp_path / "m"), str(tmp_path / "run.csv"), "--out",
               str(tmp_path / "out" / "corr.csv"), "--plot", str(tmp_path / "replay.png"),
               "--json", str(tmp_path / "replay.json")])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "before" in printed and "after" in printed and "RMS" in printed
    with open(tmp_path / "out" / "corr.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "gyro_dps", "gyro_corrected_dps", "sf_error_ppm"]
    data = np.array(rows[1:], dtype=np.float64)
    assert data.shape == (len(log), 4)
    corrected, sf, _ = Kernel(model).run(log.temp_c, log.gyro_dps)
    np.testing.assert_array_equal(data[:, 2], corrected)  # shortest form: the same double
    np.testing.assert_array_equal(data[:, 3].astype(np.float32), sf)
    np.testing.assert_array_equal(data[:, 1], log.gyro_dps)
    report = json.loads((tmp_path / "replay.json").read_text())
    assert set(report["before"]) >= {"max_abs_ppm", "pp_ppm", "rms_ppm", "std_ppm",
                                     "noise_floor_ppm", "window_s"}
    assert (tmp_path / "replay.png").stat().st_size > 10_000


@pytest.mark.slow
def test_replay_of_the_true_model_removes_the_sf_error(tmp_path, capsys, monkeypatch) -> None:
    """A model whose prediction is the log's true SF error must flatten it: a planted SF
    error is made with a random model, then replayed with that same model."""
    monkeypatch.setenv("FOGSF_BUILD_DIR", str(tmp_path / "kernels"))
    seed = 8
    rng = np.random.default_rng(seed)
    model = samples.random_model(2, 4, 1, 8, decimation=10, seed=seed,
                            out_scale=float(rng.uniform(200, 600)))
    model.save(tmp_path / "m")
    temp, _ = samples.chamber_ramp(hours=2.0, seed=seed)
    n = temp.shape[0]
    sf_true = reference.replay(model, temp, np.zeros(n)).sf_ppm.astype(np.float64)
    gyro = 10.0 * (1.0 + sf_true * 1e-6) + rng.normal(0, 0.002, n)
    write_log(tmp_path / "run.csv", ChamberLog(np.arange(n) * 0.1, temp, np.full(n, 10.0),
                                               gyro, np.zeros(n)))
    assert main(["replay", str(tmp_path / "m"), str(tmp_path / "run.csv"), "--out",
                 str(tmp_path / "c.csv"), "--json", str(tmp_path / "r.json")]) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["before"]["pp_ppm"] > 50, f"seed {seed}: planted error too small"
    assert rep["after"]["max_abs_ppm"] < 5 * rep["before"]["noise_floor_ppm"] + 1.0, \
        f"seed {seed}: {rep}"


def test_replay_refuses_a_missing_model(tmp_path, capsys) -> None:
    small_log(tmp_path / "run.csv", hours=0.2)
    assert main(["replay", str(tmp_path / "nope"), str(tmp_path / "run.csv"), "--out",
                 str(tmp_path / "c.csv")]) == 2
    assert "no such model directory" in capsys.readouterr().err


def _build_in(root: str) -> str:
    return str(build_kernel(samples.random_model(seed=4), root=root).shared)


@pytest.mark.slow
def test_concurrent_builds_of_one_model_share_one_complete_folder(tmp_path) -> None:
    """The user cache is shared by every run: processes building the same kernel at once
    each compile in a private folder; one folder is kept, complete, and loads."""
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(3) as ex:
        paths = list(ex.map(_build_in, [str(tmp_path)] * 3))
    assert len(set(paths)) == 1
    folders = [p for p in tmp_path.iterdir()]
    assert len(folders) == 1, folders  # no private build folder left behind
    kernel = Kernel(samples.random_model(seed=4), build_kernel(samples.random_model(seed=4),
                                                          root=tmp_path))
    corrected, _, _ = kernel.run(np.full(20, 20.0), np.full(20, 10.0))
    assert np.all(np.isfinite(corrected))
