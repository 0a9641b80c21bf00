"""fogsf as a user installs it: a wheel (not editable) in a fresh venv, run outside the repo."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_every_package_is_in_pyproject() -> None:
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "fogsf").rglob("*") if p.is_file() and "__pycache__" not in p.parts}
    # every folder of firmware/ holding files ships as fogsf.firmware.*
    found |= {".".join(("fogsf", *p.parent.relative_to(ROOT).parts))
              for p in (ROOT / "firmware").rglob("*") if p.is_file()}
    assert found <= listed, f"add to [tool.setuptools] packages: {sorted(found - listed)}"
    assert {name.split(".")[0] for name in listed} == {"fogsf"}, "one top-level package"


DECOYS = ("export", "cli", "logs", "sim", "bindings", "stream", "logio", "metrics")


def plant_decoys(folder: Path) -> None:
    """Modules named like fogsf's own, as a user's working folder may hold them: importing
    one fails loudly."""
    for name in DECOYS:
        (folder / f"{name}.py").write_text(f"raise ImportError('decoy {name}.py was imported')\n")


@pytest.mark.slow
def test_every_module_imports_beside_decoys(tmp_path: Path) -> None:
    """Every fogsf module, the lazily imported ones too, with the decoys first on the path."""
    plant_decoys(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    code = ("import importlib, pkgutil, fogsf\n"
            "names = [m.name for m in pkgutil.walk_packages(fogsf.__path__, 'fogsf.')\n"
            "         if not m.name.endswith('__main__')]\n"
            "for n in names:\n"
            "    importlib.import_module(n)\n"
            "print(len(names))\n")
    n = int(_run([sys.executable, "-c", code], tmp_path, env))
    assert n > 50, n


@pytest.mark.slow
def test_decoy_modules_in_the_working_folder_do_not_break_the_cli(tmp_path: Path) -> None:
    plant_decoys(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    fogsf = [sys.executable, "-m", "fogsf"]
    _run([*fogsf, "simulate", "--scenario", "paper", "--start-c", "10", "--stop-c", "30",
          "--ramp-rate", "2", "--seed", "1", "--out", "a.csv"], tmp_path, env)
    _run([*fogsf, "inspect", "a.csv"], tmp_path, env)
    _run([*fogsf, "train", "--train", "a.csv", "--iters", "10", "--out", "m"], tmp_path, env)
    _run([*fogsf, "export", "m", "--out", "build"], tmp_path, env)
    out = _run([*fogsf, "replay", "m", "a.csv", "--out", "c.csv"], tmp_path, env)
    assert "replayed" in out


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> str:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{' '.join(cmd)}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.mark.slow
def test_a_wheel_in_a_fresh_venv_runs_from_a_temporary_folder(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(ROOT / "pyproject.toml", src)
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info")
    shutil.copytree(ROOT / "fogsf", src / "fogsf", ignore=skip)
    shutil.copytree(ROOT / "firmware", src / "firmware", ignore=skip)
    env = {k: v for k, v in os.environ.items() if k not in ("FOGSF_BUILD_DIR", "PYTHONPATH")}
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
          "-w", str(tmp_path / "dist"), str(src)], tmp_path, env)
    (wheel,) = (tmp_path / "dist").glob("fogsf-*.whl")
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    purelib = _run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                   tmp_path, env).strip()
    # the pinned dependencies (torch among them) come from the project's venv, not the net
    Path(purelib, "fogsf-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    _run([str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], tmp_path, env)
    top = {name.split("/")[0] for name in zipfile.ZipFile(wheel).namelist()}
    assert {n for n in top if not n.endswith(".dist-info")} == {"fogsf"}, sorted(top)
    work = tmp_path / "work"
    work.mkdir()
    plant_decoys(work)
    env["PYTHONPATH"] = str(work)
    fogsf = str(env_dir / "bin" / "fogsf")
    where = _run([str(py), "-c", "import fogsf, fogsf.bindings.kernel as k; "
                  "print(k.C_DIR); print(fogsf.cmake_dir); print(fogsf.toolchain_file)"],
                 work, env).split()
    assert where[0].startswith(purelib), where  # the installed sources, not the repo's
    # an install reached through a symlinked folder is still an install, not a checkout
    linked = tmp_path / "linked-site"
    linked.symlink_to(purelib, target_is_directory=True)
    flags = _run([str(py), "-c", f"import sys; sys.path.insert(0, {str(linked)!r}); "
                  "import fogsf, fogsf.bindings.kernel as k; "
                  "print(fogsf.__file__, fogsf.in_checkout, k.default_build_root())"],
                 work, env).split()
    assert flags[0].startswith(str(linked)) and flags[1] == "False", flags
    assert not flags[2].startswith((purelib, str(linked))), flags
    assert where[0] == where[1] and Path(where[1], "CMakeLists.txt").is_file(), where
    assert Path(where[2]).is_file(), where
    firmware = Path(where[1]).parent
    shipped = {p.relative_to(ROOT / "firmware") for p in (ROOT / "firmware").rglob("*")
               if p.is_file() and "__pycache__" not in p.parts}
    missing = [str(p) for p in shipped if not (firmware / p).is_file()]
    assert not missing, f"firmware files not in the wheel: {missing}"
    from fogsf import __version__

    assert _run([fogsf, "--version"], work, env).strip() == f"fogsf {__version__}"
    installed_before = sorted(p for p in Path(purelib).rglob("*") if "__pycache__" not in p.parts)
    _run([fogsf, "simulate", "--scenario", "paper", "--start-c", "10", "--stop-c", "30",
          "--ramp-rate", "2", "--seed", "1", "--out", "a.csv"], work, env)
    _run([fogsf, "train", "--train", "a.csv", "--iters", "10", "--out", "m"], work, env)
    _run([fogsf, "export", "m", "--out", "build"], work, env)
    out = _run([fogsf, "replay", "m", "a.csv", "--out", "c.csv"], work, env)
    assert "replayed" in out and (work / "c.csv").is_file()
    assert (work / "build" / "model.onnx").is_file()
    kernels = list((tmp_path / "cache" / "fogsf" / "kernels").glob("*/libfogsf.so"))
    assert len(kernels) == 1, "the kernel build cache belongs in the user's cache directory"
    assert not any(Path(purelib).rglob("libfogsf.so")), "nothing is built inside the install"
    out = _run([fogsf, "replay", "m", "a.csv", "--out", "c2.csv", "--build-dir", "kernels"],
               work, env)
    assert len(list((work / "kernels").glob("*/libfogsf.so"))) == 1, out
    assert (work / "c.csv").read_bytes() == (work / "c2.csv").read_bytes()
    if shutil.which("cmake") and shutil.which("cc"):  # a firmware project on the installed C
        app = work / "app"
        app.mkdir()
        (app / "main.c").write_text('#include "imu_x.h"\nint main(void)\n{\n    fogsf_state s;\n'
                                    "    return (int)fogsf_init(&imu_x, &s, sizeof s);\n}\n")
        (app / "CMakeLists.txt").write_text(
            "cmake_minimum_required(VERSION 3.13)\nproject(app C)\n"
            "add_subdirectory(${FOGSF_DIR} fogsf)\nadd_executable(app main.c)\n"
            "fogsf_add_model(app NAME imu_x MODEL ${MODEL})\n")
        _run(["cmake", "-S", str(app), "-B", str(work / "app-build"), f"-DFOGSF_DIR={where[1]}",
              f"-DMODEL={work / 'm'}", f"-DFOGSF_EXECUTABLE={fogsf}"], work, env)
        _run(["cmake", "--build", str(work / "app-build")], work, env)
        assert subprocess.run([str(work / "app-build" / "app")]).returncode == 0
    installed_after = sorted(p for p in Path(purelib).rglob("*") if "__pycache__" not in p.parts)
    assert installed_after == installed_before, "the run wrote into the installed package"
