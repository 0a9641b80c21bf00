"""fogsf as a user installs it: a wheel (not editable) in a fresh venv, run outside the repo."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_every_package_is_in_pyproject() -> None:
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for top in ("trainer", "export", "bindings")
             for p in (ROOT / top).rglob("__init__.py")}
    assert found <= listed, f"add to [tool.setuptools] packages: {sorted(found - listed)}"


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
    for name in ("trainer", "export", "bindings"):
        shutil.copytree(ROOT / name, src / name, ignore=skip)
    shutil.copytree(ROOT / "firmware" / "c", src / "firmware" / "c", ignore=skip)
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
    work = tmp_path / "work"
    work.mkdir()
    fogsf = str(env_dir / "bin" / "fogsf")
    where = _run([str(py), "-c", "import bindings.kernel as k; print(k.C_DIR)"], work, env)
    assert where.strip().startswith(purelib), where  # the installed sources, not the repo's
    c_dir = Path(where.strip())
    shipped = {p.relative_to(ROOT / "firmware" / "c") for p in (ROOT / "firmware" / "c").rglob("*")
               if p.is_file() and "__pycache__" not in p.parts}
    missing = [str(p) for p in shipped if not (c_dir / p).is_file()]
    assert not missing, f"firmware/c files not in the wheel: {missing}"
    from trainer import __version__

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
    installed_after = sorted(p for p in Path(purelib).rglob("*") if "__pycache__" not in p.parts)
    assert installed_after == installed_before, "the run wrote into the installed package"
