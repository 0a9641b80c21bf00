"""Three axes in one run (`--axis all`, commands/axes.py) and the earth rate per axis
(`--axis-cosine`), on a generated 3-axis log: one chamber run, three gyros whose SF errors
differ (the default gyro's temperature laws times 1, -0.5 and 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli import main as cli
from fogsf.logs.chamber_log import EARTH_RATE_DPS, ChamberLog
from fogsf.sim.gyro import simulate
from fogsf.sim.scenarios import paper

AXES = "xyz"
GAINS = (1.0, -0.5, 2.0)  # each axis' SF temperature law, times the default gyro's


def _gyro_log(gain: float, seed: int) -> ChamberLog:
    """-20 -> 40 C at 2 C/min after a 10 min soak: 40 min at 10 Hz."""
    cfg = paper(2.0, seed)
    cfg.profile.start_c, cfg.profile.stop_c = -20.0, 40.0
    cfg.profile.soak_before_s = 600.0
    for term in cfg.sf.terms:
        term.lin_ppm_per_c *= gain
        term.quad_ppm_per_c2 *= gain
    return simulate(cfg).log


def write_csv(path: Path, cols: dict[str, np.ndarray]) -> Path:
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(cols) + "\n")
        np.savetxt(f, np.column_stack(list(cols.values())), fmt="%.12g", delimiter=",")
    return path


@pytest.fixture(scope="module")
def imu_log(tmp_path_factory) -> Path:
    """time_s,temp_c,table_rate_dps,earth_rate_dps,gyro_x_dps,gyro_y_dps,gyro_z_dps (the
    board thermometer of axis x: the three differ by their quantisation only)."""
    logs = [_gyro_log(g, seed) for seed, g in enumerate(GAINS, start=1)]
    x = logs[0]
    cols = {"time_s": x.time_s, "temp_c": x.temp_c, "table_rate_dps": x.table_rate_dps,
            "earth_rate_dps": x.earth_rate_dps,
            **{f"gyro_{a}_dps": lg.gyro_dps for a, lg in zip(AXES, logs, strict=True)}}
    return write_csv(tmp_path_factory.mktemp("imu") / "imu.csv", cols)


def drop_earth(log: Path, out: Path) -> Path:
    """The log without its earth_rate_dps column."""
    rows = [line.split(",") for line in log.read_text().splitlines()]
    i = rows[0].index("earth_rate_dps")
    out.write_text("\n".join(",".join(r[:i] + r[i + 1:]) for r in rows) + "\n")
    return out


def fogsf(*argv: object) -> int:
    return cli.main([str(a) for a in argv])


def without_time(metrics: Path) -> dict:
    m = json.loads(metrics.read_text())
    m.pop("train_seconds")
    return m


def test_train_all_writes_one_model_per_axis_as_single_axis_runs_do(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fogsf("train", "--train", imu_log, "--axis", "all", "--model", "poly",
                 "--out", tmp_path / "all", "--no-progress") == 0
    out = capsys.readouterr().out
    summary = out[out.index("summary, SF error RMS"):].splitlines()
    assert summary[1].split()[:5] == ["axis", "model", "train", "before", "train"]
    assert [line.split()[0] for line in summary[2:]] == list(AXES)
    coefs = []
    for a in AXES:
        assert fogsf("train", "--train", imu_log, "--axis", a, "--model", "poly",
                     "--out", tmp_path / "one" / a, "--no-progress") == 0
        got, one = tmp_path / "all" / a, tmp_path / "one" / a
        assert sorted(p.name for p in got.iterdir()) == sorted(p.name for p in one.iterdir())
        assert (got / "train_info.json").read_bytes() == (one / "train_info.json").read_bytes()
        assert without_time(got / "metrics.json") == without_time(one / "metrics.json")
        coefs.append(json.loads((got / "train_info.json").read_text())["coef"])
        after = json.loads((got / "metrics.json").read_text())["train"]["after"]["rms_ppm"]
        row = next(line.split() for line in summary[2:] if line.split()[0] == a)
        assert row[3] == f"{after:.2f}"  # the summary's "train after"
    # three gyros, three models: the linear terms follow the gains 1, -0.5, 2
    lin = [c[1] for c in coefs]
    assert lin[0] * lin[1] < 0 and abs(lin[2]) > abs(lin[0]) > abs(lin[1])


def test_all_on_a_one_axis_log_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    t = np.arange(0, 600, 0.1)
    log = write_csv(tmp_path / "one.csv", {"time_s": t, "temp_c": 20 + 0 * t,
                                           "table_rate_dps": 10 + 0 * t,
                                           "gyro_dps": 10 + 0 * t})
    for argv in (["train", "--train", log, "--model", "poly", "--out", tmp_path / "m"],
                 ["inspect", log]):
        assert fogsf(*argv, "--axis", "all", "--latitude-deg", "45") == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "has no per-axis gyro columns (gyro_A_dps" in err[0], err
    assert not (tmp_path / "m").exists()


def test_all_refusals_name_the_axis_or_come_before_any_work(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "afile").write_text("")
    assert fogsf("train", "--train", imu_log, "--axis", "all", "--model", "poly",
                 "--out", tmp_path / "afile") == 2
    assert "afile is a file" in capsys.readouterr().err
    assert fogsf("inspect", imu_log, "--axis", "all", "--skip-s", "1e9") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("fogsf inspect: error: axis x: ")


def test_all_needs_the_same_axes_in_every_log(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = [line.split(",") for line in imu_log.read_text().splitlines()]
    xy = tmp_path / "xy.csv"  # without gyro_z_dps, the last column
    xy.write_text("\n".join(",".join(r[:-1]) for r in rows) + "\n")
    assert fogsf("train", "--train", imu_log, "--test", xy, "--axis", "all", "--model", "poly",
                 "--out", tmp_path / "m") == 2
    err = capsys.readouterr().err
    assert "has axes x, y" in err and "give logs of the same axes" in err
    assert not (tmp_path / "m").exists()


def test_all_is_refused_by_commands_that_do_not_take_it(
        imu_log: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fogsf("diagnose", imu_log, "--axis", "all") == 2
    assert "here give one axis" in capsys.readouterr().err


def test_export_all_names_each_c_model_after_its_axis(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from fogsf.models import samples

    for i, a in enumerate(AXES):
        samples.random_model(1, 1, 1, 8, decimation=10, seed=40 + i).save(tmp_path / "m" / a)
    assert fogsf("export", tmp_path / "m", "--axis", "all", "--name", "imu",
                 "--out", tmp_path / "c") == 0
    assert "C model" in capsys.readouterr().out
    for a in AXES:
        h = (tmp_path / "c" / a / f"imu_{a}.h").read_text()
        assert f"extern const fogsf_model imu_{a};" in h
        assert fogsf("export", tmp_path / "m" / a, "--name", f"imu_{a}",
                     "--out", tmp_path / "one" / a) == 0
        for name in (f"imu_{a}.h", f"imu_{a}.c", "model.onnx"):
            assert (tmp_path / "c" / a / name).read_bytes() == \
                (tmp_path / "one" / a / name).read_bytes(), name
    assert fogsf("export", tmp_path / "c", "--axis", "all", "--out", tmp_path / "d") == 2
    assert "holds no model folder per axis" in capsys.readouterr().err


def test_inspect_all_json_is_one_object_keyed_by_axis(
        imu_log: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fogsf("inspect", imu_log, "--axis", "all", "--json") == 0
    doc = json.loads(capsys.readouterr().out)
    assert list(doc) == list(AXES)
    rms = [doc[a]["metrics"]["rms_ppm"] for a in AXES]
    assert rms[2] > rms[0] > rms[1]  # gains 2, 1, -0.5


@pytest.mark.slow
def test_replay_all_writes_one_output_per_axis(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from fogsf.models import samples

    for i, a in enumerate(AXES):
        samples.random_model(1, 1, 1, 4, decimation=10, seed=70 + i).save(tmp_path / "m" / a)
    assert fogsf("replay", tmp_path / "m", imu_log, "--axis", "all",
                 "--out", tmp_path / "r" / "corr.csv", "--json", tmp_path / "r" / "r.json",
                 "--build-dir", tmp_path / "k") == 0
    assert "summary, SF error RMS" in capsys.readouterr().out
    ids = {json.loads((tmp_path / "r" / f"r_{a}.json").read_text())["model_id"] for a in AXES}
    assert len(ids) == 3 and all((tmp_path / "r" / f"corr_{a}.csv").is_file() for a in AXES)
    (tmp_path / "m" / "z" / "stream.json").unlink()  # a model missing: refused before any run
    assert fogsf("replay", tmp_path / "m", imu_log, "--axis", "all",
                 "--out", tmp_path / "s" / "corr.csv") == 2
    assert "has no model for axis z" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


# --axis-cosine: the earth rate from --latitude-deg on a tilted axis


def test_earth_rate_from_latitude_is_scaled_by_the_axis_cosine() -> None:
    t = np.arange(10.0)
    log = ChamberLog(t, 20 + 0 * t, 10 + 0 * t, 10 + 0 * t, axis_cosine=0.5)
    want = EARTH_RATE_DPS * np.sin(np.radians(30.0)) * 0.5
    np.testing.assert_allclose(log.earth(30.0), want, rtol=1e-15)
    assert log.slice(2, 5).axis_cosine == 0.5


def test_axis_cosine_gives_the_sf_of_a_log_with_that_earth_column(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A gyro tilted to cos = 0.3 from the vertical: its log with the earth column, and
    without it with --latitude-deg --axis-cosine 0.3, give the same reference SF."""
    lat, c = 34.26, 0.3
    lg = _gyro_log(1.0, 5)
    vertical = lg.earth_rate_dps
    gyro = lg.gyro_dps - vertical * (1 - c)  # the SF seen about the tilted axis' earth rate
    base = {"time_s": lg.time_s, "temp_c": lg.temp_c, "table_rate_dps": lg.table_rate_dps}
    with_col = write_csv(tmp_path / "col.csv", {**base, "earth_rate_dps": vertical * c,
                                                "gyro_dps": gyro})
    bare = write_csv(tmp_path / "bare.csv", {**base, "gyro_dps": gyro})

    def ref(*argv: object) -> float:
        assert fogsf("inspect", *argv, "--json") == 0
        return json.loads(capsys.readouterr().out)["ref_sf_ratio"]

    def noted(*argv: object) -> tuple[float, str]:
        assert fogsf("inspect", *argv, "--json") == 0
        cap = capsys.readouterr()
        return json.loads(cap.out)["ref_sf_ratio"], cap.err

    want = ref(with_col)
    assert ref(bare, "--latitude-deg", lat, "--axis-cosine", c) == pytest.approx(want, abs=1e-9)
    vert = ref(bare, "--latitude-deg", lat)  # the vertical assumption: off by (1 - c) earth
    assert vert - want == pytest.approx(-(1 - c) * vertical[0] / 10.0, rel=0.01)
    # the log's own earth column takes precedence, and says so
    got, err = noted(with_col, "--latitude-deg", lat, "--axis-cosine", 1)
    assert got == want and "--axis-cosine not used" in err


def test_axis_cosine_per_axis_under_all(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bare = drop_earth(imu_log, tmp_path / "bare.csv")
    lat = ("--latitude-deg", "34.26")
    assert fogsf("inspect", bare, "--axis", "all", *lat, "--axis-cosine", "x=1,y=0.5,z=-1",
                 "--json") == 0
    refs = {a: s["ref_sf_ratio"] for a, s in json.loads(capsys.readouterr().out).items()}
    for a, c in zip(AXES, ("1", "0.5", "-1"), strict=True):
        assert fogsf("inspect", bare, "--axis", a, *lat, "--axis-cosine", c, "--json") == 0
        assert json.loads(capsys.readouterr().out)["ref_sf_ratio"] == refs[a]
    assert fogsf("inspect", bare, "--axis", "all", *lat, "--axis-cosine", "x=1,y=0.5") == 2
    err = capsys.readouterr()
    assert "no cosine for axis z" in err.err and "axis x:" not in err.out  # before any run


@pytest.mark.parametrize("text, says", [
    ("1.5", "a cosine lies in -1 .. 1"),
    ("x=0.5,x=0.2", "expected C or AXIS=C pairs"),
    ("x=up", "expected a number -1 .. 1 for axis x"),
])
def test_bad_axis_cosines_are_refused_in_one_line(
        text: str, says: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        fogsf("inspect", "x.csv", "--axis-cosine", text)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err


@pytest.mark.parametrize("command", ["train", "inspect", "replay", "diagnose", "plan",
                                     "simulate"])
def test_latitude_help_states_the_vertical_assumption(command: str) -> None:
    parser = cli.build_parser()._subparsers._group_actions[0].choices[command]
    text = " ".join(parser.format_help().split())
    if command == "simulate":  # what it writes: a vertical axis' earth rate
        assert "sensitive axis is vertical" in text
    else:
        assert "assumes a vertical sensitive axis" in text and "--axis-cosine" in text


def test_plan_from_logs_takes_latitude_to_the_fit(
        imu_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogsf.diagnose import verdict

    seen = {}

    def stop(logs: list, **kw: object) -> None:
        seen.update(kw, earth=logs[0].earth(kw["latitude_deg"])[0])
        raise KeyboardInterrupt  # the fit's options are all this test needs

    monkeypatch.setattr(verdict, "diagnose", stop)
    bare = drop_earth(imu_log, tmp_path / "bare.csv")
    assert fogsf("plan", "--from-logs", bare, "--axis", "x", "--latitude-deg", "45",
                 "--axis-cosine", "0.5", "--out", tmp_path / "p") == 130
    assert seen["latitude_deg"] == 45.0 and seen["window_s"] == 60.0
    assert seen["earth"] == pytest.approx(EARTH_RATE_DPS * np.sin(np.radians(45)) * 0.5)


def test_a_skew_mounted_imu_reads_as_three_vertical_gyros(
        imu_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Each axis at its own cosine to a vertical table: the table rate per axis from the map,
    the earth rate by --axis-cosine; every axis' SF as the same gyro's on a vertical axis."""
    cos = {"x": 0.8, "y": 0.36, "z": 0.48}
    rows = [line.split(",") for line in imu_log.read_text().splitlines()]
    head = rows[0]
    data = np.array(rows[1:], dtype=np.float64)
    col = {h: data[:, i] for i, h in enumerate(head)}
    skew = write_csv(tmp_path / "skew.csv", {
        "time_s": col["time_s"], "temp_c": col["temp_c"], "table": col["table_rate_dps"],
        **{f"g{a}": col[f"gyro_{a}_dps"] * c for a, c in cos.items()}})
    (tmp_path / "fogsf-columns.toml").write_text("".join(
        f'gyro_{a}_dps = "g{a}"\ntable_rate_{a}_dps = "table * {c}"\n' for a, c in cos.items()))
    lat = 34.26  # the simulator's, whose earth column the vertical log holds
    assert fogsf("inspect", skew, "--axis", "all", "--latitude-deg", lat, "--axis-cosine",
                 ",".join(f"{a}={c}" for a, c in cos.items()), "--json") == 0
    got = json.loads(capsys.readouterr().out)
    assert fogsf("inspect", imu_log, "--axis", "all", "--json") == 0
    want = json.loads(capsys.readouterr().out)
    for a in AXES:
        assert got[a]["ref_sf_ratio"] == pytest.approx(want[a]["ref_sf_ratio"], abs=1e-9)
        assert got[a]["metrics"]["rms_ppm"] == pytest.approx(want[a]["metrics"]["rms_ppm"],
                                                             abs=0.01)


@pytest.mark.slow
def test_a_stationary_imu_trains_a_bias_only_model_per_axis_titled_as_the_bias(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A skew IMU logged with the table stopped, in the rig's own columns: `--axis all`
    trains a bias-only model per axis, and the summary is titled as the bias (no SF); replay
    of one axis's model over its log reports the bias too."""
    from dataclasses import replace

    from fogsf.sim.rigs import benches, chambers
    from fogsf.sim.rigs import protocols as rigs

    still = rigs.stationary_protocol(chamber=chambers.loop(-10.0, 20.0, 2.0, 2.0, 300.0),
                                     bias=None, thermal_bias=True)
    case = benches.BenchCase("imu3", still, replace(still), "stationary IMU")
    train, test = benches.write_case(tmp_path / "logs", case, (20000, 20001, 20002), 5)
    assert fogsf("train", "--train", train.path, "--test", test.path, "--axis", "all",
                 "--out", tmp_path / "m") == 0
    out = capsys.readouterr().out
    summary = out[out.index("summary, "):].splitlines()
    assert summary[0].startswith("summary, the bias") and "SF error" not in summary[0]
    assert summary[1].split()[:3] == ["axis", "model", "bias"]
    assert [line.split()[0] for line in summary[2:]] == list(AXES)
    for a in AXES:
        m = json.loads((tmp_path / "m" / a / "metrics.json").read_text())
        assert m["bias_only"] and m["bias"]["test"]["after"]["std_dph"] > 0
    assert fogsf("replay", tmp_path / "m", test.path, "--axis", "all", "--out",
                 tmp_path / "r" / "corr.csv", "--build-dir", tmp_path / "k") == 0
    out = capsys.readouterr().out
    summary = out[out.index("summary, "):].splitlines()
    assert "bias after deg/h" in summary[1] and summary[0].startswith("summary, the bias")


def test_the_summary_is_titled_as_the_bias_only_when_every_row_is_the_bias_alone() -> None:
    """A replay row with no SF figures (its log never passes 20 C) is still an SF model's:
    the bias title needs every row marked bias-only (a bias-only model, a stationary log)."""
    from fogsf.cli.axes import BIAS_ONLY, BIAS_TITLE, SF_TITLE, summary_table
    from fogsf.cli.axes import summary_title as title

    sf_row = {"model": "abc", "out": "r.csv", "flags": "none"}
    bias_row = {"model": "def", "bias before deg/h": "0.5", BIAS_ONLY: True}
    assert title(SF_TITLE, {"x": sf_row, "y": sf_row}) == SF_TITLE
    assert title(SF_TITLE, {"x": sf_row, "y": bias_row}) == SF_TITLE
    assert title(SF_TITLE, {"x": bias_row, "y": bias_row}) == BIAS_TITLE
    assert title("one C model per axis", {"x": bias_row}) == "one C model per axis"
    assert BIAS_ONLY not in summary_table({"x": bias_row}, BIAS_TITLE)
