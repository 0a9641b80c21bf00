"""`fogsf export --even-time`: a model for the kernel built with FOGSF_EVEN_TIME is refused
when its step D is below that build's bound, L*H + 3 samples (each step's parts must end
before the next step); an accepted one says so in NAME.h, and its NAME.c compiles only in
the even-time build."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from fogsf.bindings.kernel import C_DIR, STRICT
from fogsf.cli.main import main
from fogsf.export.header import check_even_time, even_time_parts, render_model
from fogsf.models import samples


@pytest.mark.parametrize("layers, hidden, d, ok", [
    (1, 16, 19, True), (1, 16, 18, False), (2, 6, 15, True), (2, 6, 14, False),
    (1, 1, 4, True), (1, 1, 3, False)])
def test_the_bound_is_l_times_h_plus_3(layers, hidden, d, ok) -> None:
    model = samples.random_model(2, 4, layers, hidden, d, seed=1)
    assert even_time_parts(model) == layers * hidden + 3
    if ok:
        check_even_time(model)
        files = render_model(model, "m1", even_time=True)
        assert f"#define M1_EVEN_TIME_PARTS {layers * hidden + 3}\n" in files["m1.h"]
        assert "#if !FOGSF_EVEN_TIME\n#error" in files["m1.c"]
    else:
        with pytest.raises(ValueError, match=rf"D = {d} samples, below the even-time bound "
                                             rf"D >= L\*H \+ 3 = {layers * hidden + 3}"):
            render_model(model, "m1", even_time=True)
    plain = render_model(model, "m1")  # without --even-time: the export as before
    assert "EVEN_TIME" not in plain["m1.h"] + plain["m1.c"]


def test_export_refuses_below_the_bound_and_names_the_fix(tmp_path, capsys) -> None:
    model = samples.random_model(3, 4, 1, 16, 10, seed=2)  # 1x16 at D = 10: bound 19
    model.save(tmp_path / "m")
    assert main(["export", str(tmp_path / "m"), "--out", str(tmp_path / "b"),
                 "--even-time"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "D >= L*H + 3 = 19 (L=1, H=16)" in err and "--sample-rate-hz 19 or more" in err
    assert not (tmp_path / "b").exists()  # nothing written
    assert main(["export", str(tmp_path / "m"), "--blob", str(tmp_path / "u.bin"),
                 "--even-time"]) == 2
    assert not (tmp_path / "u.bin").exists()
    # the fix it names: the same step at 19 Hz is D = 19 samples
    assert main(["export", str(tmp_path / "m"), "--out", str(tmp_path / "b"),
                 "--name", "imu_x", "--sample-rate-hz", "19", "--even-time"]) == 0
    header = (tmp_path / "b" / "imu_x.h").read_text()
    assert "#define IMU_X_DECIMATION 19\n" in header and "#define IMU_X_EVEN_TIME 1\n" in header


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_an_even_time_model_compiles_only_in_the_even_time_build(tmp_path) -> None:
    model = samples.random_model(3, 4, 1, 16, 19, seed=3)
    for name, text in render_model(model, "m1", even_time=True).items():
        (tmp_path / name).write_text(text)

    def compile_model(*defines: str) -> subprocess.CompletedProcess:
        return subprocess.run(["gcc", *STRICT, *defines, "-I", str(C_DIR), "-c",
                               str(tmp_path / "m1.c"), "-o", str(tmp_path / "m1.o")],
                              capture_output=True, text=True)

    assert compile_model("-DFOGSF_EVEN_TIME=1").returncode == 0
    proc = compile_model()
    assert proc.returncode != 0 and "m1 was exported with --even-time" in proc.stderr
