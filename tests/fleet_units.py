"""What the fleet tests share: made-up unit records, the backends a store test runs on
(SQLite always; PostgreSQL when a server is at hand) and waiting for another process."""

from __future__ import annotations

import atexit
import math
import os
import shutil
import subprocess
import tempfile
import time
import uuid
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fogsf.fleet.records import LogRecord, UnitRecord

PG_ENV = "FOGSF_TEST_POSTGRES_URL"  # a server to use instead of starting one


def fake_record(sn: str, seed: int = 0, structure: str = "physics2") -> UnitRecord:
    """A unit record with made-up logs, figures and parameters (no training)."""
    rng = np.random.default_rng(seed)
    logs = [LogRecord(path=f"/lab/{sn}/loop{i}.csv", sha256=f"{seed:02d}{i:062d}",
                      rows=36000 + i, span_s=3600.0 + 60 * i, sample_rate_hz=10.0,
                      ramp_rates_c_per_min=[2.0, 1.0], temp_min_c=-20.0, temp_max_c=40.0,
                      role="train") for i in range(2)]
    logs.append(LogRecord(path=f"/lab/{sn}/test.csv", sha256="ab" * 32, rows=7200,
                          span_s=7200.0, sample_rate_hz=1.0, ramp_rates_c_per_min=[1.0],
                          temp_min_c=-20.0, temp_max_c=40.0, role="test"))
    floor = 8.0 + rng.uniform(0, 1)
    return UnitRecord(
        unit=sn, logs=logs, model_id=f"{seed:016x}", model_dir="",
        fitted_with={"model": "lag-lstm", "structure": structure, "options": {"seed": seed}},
        figures={"noise_floor_ppm": floor, "test_after_rms_ppm": floor * 1.2,
                 "test_rms_over_floor": 1.2, "train_rms_over_floor": 1.0,
                 "sf_curve_log": "test",
                 "sf_curve": {"temp_c": [-20.0, 0.0, 20.0, 40.0],
                              "before_ppm": [-300.0, -100.0, 0.0, 150.0],
                              "after_ppm": [3.0, -2.0, 1.0, 0.5]}},
        interval={"rms_lo_ppm": floor, "rms_hi_ppm": 1.5 * floor, "noise_floor_ppm": floor,
                  "test_rms_ppm": 1.2 * floor, "held": True, "covered": True},
        summary={"structure": structure,
                 "params": {"tau_s": sorted(float(t) for t in rng.uniform(200, 3000, 2)),
                            "lin_ppm": [float(v) for v in rng.normal(0, 50, 3)]}},
        fogsf_version="0.1.0", created_utc="2026-11-27T10:00:00Z")


# A child process's start-up code (sitecustomize.py on its PYTHONPATH) that pauses inside
# every store write that bumps the fleet's state (add and remove), after its statements and
# before COMMIT, once it has said so in a file: a kill lands there deterministically, with
# nothing in fogsf for the tests.
PAUSE_SITE = """
import os, time
from pathlib import Path
import fogsf.fleet.store as store
_bump = store.bump_state
def _bump_then_pause(db):
    _bump(db)
    Path({marker!r}).write_text(str(os.getpid()))
    end = time.monotonic() + {pause_s!r}
    while time.monotonic() < end and not ({go!r} and Path({go!r}).exists()):
        time.sleep(0.05)
store.bump_state = _bump_then_pause
"""
ROOT = Path(__file__).resolve().parents[1]


def pause_in_add(folder: Path, marker: Path, pause_s: float = 120.0,
                 go: Path | None = None) -> dict[str, str]:
    """The environment of a child process whose store writes pause `pause_s` inside their
    transaction (or until the file `go` exists), `marker` written when one is there
    (PAUSE_SITE, written into `folder`)."""
    site = folder / "pause-in-add"
    site.mkdir(parents=True, exist_ok=True)
    (site / "sitecustomize.py").write_text(PAUSE_SITE.format(
        marker=str(marker), pause_s=float(pause_s), go=str(go) if go else None))
    path = [str(site), str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path)}


# A child process's start-up code whose training entries raise: a command that would train
# fails loudly, so one that succeeds did not train (`fleet add --model-dir`).
NO_TRAINING_SITE = """
import fogsf.training.rate.plateau_train as plateau_train
import fogsf.training.sf.fit as sf_fit
import fogsf.training.train as train
def _no_training(*args, **kwargs):
    raise RuntimeError("training entered")
train.run_training = train.train_model = sf_fit.fit_sf = _no_training
plateau_train.train_plateaus = _no_training
"""


def no_training(folder: Path) -> dict[str, str]:
    """The environment of a child process in which any training raises (NO_TRAINING_SITE,
    written into `folder`)."""
    site = folder / "no-training"
    site.mkdir(parents=True, exist_ok=True)
    (site / "sitecustomize.py").write_text(NO_TRAINING_SITE)
    path = [str(site), str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path)}


def wait_for(cond: Callable[[], bool], timeout_s: float, what: str) -> None:
    t_end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > t_end:
            raise AssertionError(what)
        time.sleep(0.05)


# --- PostgreSQL -------------------------------------------------------------------------------

def _pg_bin() -> Path | None:
    found = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"))
    return found[-1].parent if found else None


@cache
def pg_server() -> str | None:
    """A PostgreSQL server for the session: FOGSF_TEST_POSTGRES_URL's, or Debian's postgresql
    started in a temporary folder (as the postgres user when we are root: initdb refuses
    root), listening on a Unix socket only; None when there is neither."""
    if os.environ.get(PG_ENV):
        return os.environ[PG_ENV]
    bindir = _pg_bin()
    if bindir is None:
        return None
    try:
        import psycopg  # noqa: F401
    except ImportError:
        return None
    root = Path(tempfile.mkdtemp(prefix="fogsf-pg-"))
    data, sock = root / "data", root / "sock"
    sock.mkdir()
    as_user: list[str] = []
    user = os.environ.get("USER") or "postgres"
    if os.geteuid() == 0:
        user = "postgres"
        shutil.chown(root, user)
        shutil.chown(sock, user)
        root.chmod(0o755)
        as_user = ["runuser", "-u", user, "--"]
    run = [*as_user, str(bindir / "initdb"), "-D", str(data), "-A", "trust", "-U", user,
           "--no-sync"]
    subprocess.run(run, check=True, capture_output=True)
    opts = f"-c listen_addresses='' -k {sock} -c fsync=off"
    subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-l",
                    str(root / "log"), "-o", opts, "-w", "start"], check=True,
                   capture_output=True)

    def stop() -> None:
        subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate",
                        "stop"], capture_output=True)
        shutil.rmtree(root, ignore_errors=True)

    atexit.register(stop)
    return f"postgresql://{user}@/postgres?host={sock}"


def _fresh_pg_database(server: str) -> str:
    """A new empty database on `server` (its URL)."""
    import psycopg
    from psycopg import sql

    name = f"fleet_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(server, autocommit=True) as db:
        db.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
    base, _, query = server.partition("?")
    head = base.rsplit("/", 1)[0]
    return f"{head}/{name}" + (f"?{query}" if query else "")


def _sqlite(tmp_path: Path) -> str:
    return str(tmp_path / "line.fleet")


def _postgres(tmp_path: Path) -> str:
    server = pg_server()
    if server is None:
        pytest.skip("no PostgreSQL server: Debian's postgresql is not installed (scripts/"
                    f"toolchain.sh installs it) and {PG_ENV} is not set")
    return _fresh_pg_database(server)


# backend -> a function of tmp_path giving a fresh fleet on it
FLEETS: dict[str, Callable[[Path], str]] = {"sqlite": _sqlite, "postgresql": _postgres}


def fleet_urls() -> list:
    """pytest params: a function of tmp_path giving a fresh fleet, on each backend."""
    return [pytest.param(make, id=name) for name, make in FLEETS.items()]


def raw_execute(fleet: str, statements: list[str]) -> None:
    """Run SQL on the fleet's database directly (a database an older fogsf wrote)."""
    if fleet.startswith("postgres"):
        import psycopg

        with psycopg.connect(fleet, autocommit=True) as db:
            for s in statements:
                db.execute(s)
        return
    import sqlite3

    db = sqlite3.connect(fleet)
    with db:
        for s in statements:
            db.execute(s)
    db.close()


# --- simulated units of one design ------------------------------------------------------------
# Units from the simulator's designs (`fogsf.sim.fleet_units`: time constants +/-15 %, SF
# coefficients +/-25 %, bias, hysteresis and ARW around the design's); the defect drawn here,
# its strength from a stated range.

DEFECTS = ("slope", "tau", "mode_hop")
SLOPE_FACTOR = (3.0, 5.0)  # a defective part's SF slope: the design's x this, either sign
TAU_FACTOR = (2.5, 4.0)  # the slowest part an SF factor reads: its time constant x this
MODE_HOP_PPM = (150.0, 400.0)  # a mode hop: an SF step of this size, either sign,
MODE_HOP_AT_C = (5.0, 25.0)  # above this source temperature


def unit_config(design_seed: int, index: int):  # noqa: ANN201 - SimConfig
    """Unit `index` of design `design_seed` (`fogsf.sim.fleet_units.unit_for`)."""
    from fogsf.sim.fleet_units import unit_for

    return unit_for(design_seed, index)


def loop_program(rate: float = 2.0, lo: float = -20.0, hi: float = 40.0, soak_s: float = 1200.0
                 ) -> list[list[float]]:
    """lo -> hi -> lo at `rate` C/min with soaks at each end: [[time_s, temp_c], ...]."""
    ramp = (hi - lo) / rate * 60.0
    pts = [[0.0, lo], [soak_s, lo], [soak_s + ramp, hi], [2 * soak_s + ramp, hi],
           [2 * soak_s + 2 * ramp, lo], [3 * soak_s + 2 * ramp, lo]]
    return pts


def unit_log(cfg, seed: int, defect: dict | None = None, sample_rate_hz: float = 1.0,
             rate: float = 2.0):  # noqa: ANN001, ANN201
    """A chamber log of unit `cfg` on `loop_program(rate)`; `defect`: {"kind": "mode_hop",
    "ppm": step, "at_c": T} adds an SF step where the source is above T."""
    from fogsf.sim.config import ProfileConfig
    from fogsf.sim.gyro import simulate
    from fogsf.sim.population import run_on_gyro

    run = run_on_gyro(cfg, ProfileConfig(kind="program", points=loop_program(rate)), seed,
                      "fleet-unit")
    run.dt_s = 1.0 / sample_rate_hz
    res = simulate(run)
    log = res.log
    if defect and defect["kind"] == "mode_hop":
        part = "source" if "source" in res.nodes else "board"
        step = np.where(res.nodes[part] > defect["at_c"], defect["ppm"] * 1e-6, 0.0)
        log.gyro_dps = log.gyro_dps + (log.table_rate_dps + log.earth_rate_dps) * step
    return log


def draw_defect(rng: np.random.Generator, cfg) -> tuple[dict, object]:  # noqa: ANN001
    """A defect drawn from DEFECTS and its ranges: (what it is, the unit's config with a
    slope or tau defect applied; a mode hop is applied to the log by `unit_log`)."""
    import copy

    kind = str(rng.choice(DEFECTS))
    sign = float(rng.choice([-1.0, 1.0]))
    cfg = copy.deepcopy(cfg)
    if kind == "slope":
        term = max(cfg.sf.terms, key=lambda t: abs(t.lin_ppm_per_c))  # the strongest part
        factor = sign * float(rng.uniform(*SLOPE_FACTOR))
        term.lin_ppm_per_c *= factor
        return {"kind": kind, "part": term.name, "factor": round(factor, 3)}, cfg
    if kind == "tau":
        read = {name for t in cfg.sf.terms for name in t.nodes}
        part = max((n for n in cfg.thermal.nodes[2:] if n.name in read), key=lambda n: n.tau_s)
        factor = float(rng.uniform(*TAU_FACTOR))
        part.tau_s *= factor
        return {"kind": kind, "part": part.name, "factor": round(factor, 3)}, cfg
    return {"kind": kind, "ppm": round(sign * float(rng.uniform(*MODE_HOP_PPM)), 1),
            "at_c": round(float(rng.uniform(*MODE_HOP_AT_C)), 1)}, cfg


FAST_TRAIN = {"model": "lag-lstm", "structure": "physics", "nodes": 2, "iters": 2,
              "hysteresis": "off", "transfer_check": False, "progress": False}


def fit_unit(sn: str, train_logs: list, out_dir: Path, test_log=None,  # noqa: ANN001
             **options: object) -> UnitRecord:
    """Train a unit as `fogsf fleet add` does (the training code directly, few LSTM
    iterations) and build its record."""
    from fogsf.fleet.records import unit_record
    from fogsf.training.net.loops import torch_threads
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    opts = TrainOptions(**{**FAST_TRAIN, **options})  # type: ignore[arg-type]
    with torch_threads(1):  # a 1 x 16 net: one thread is fastest (several on a busy machine)
        metrics, fitted = run_training(opts, train_logs, test_log, out_dir)
        return unit_record(sn, train_logs, test_log, metrics, fitted, out_dir, dict(options),
                           keep_dir=False)


def small_line(folder: Path, seed: int, units: int, rates: tuple[float, ...]) -> dict:
    """A fleet of `units` units of a development design the seed draws, each trained on a
    loop at every one of `rates` (C/min), and a new unit's 2 C/min loop and 1 C/min test
    loop: {"db", "new", "test", "tmp", "design"}."""
    from fogsf.fleet.store import open_store
    from fogsf.logs.writer import write_log
    from fogsf.sim.fleet_units import unit_for

    design = int(np.random.default_rng(seed).integers(1, 10_000))
    db = str(folder / "line.fleet")
    with open_store(db) as store:
        for i in range(units):
            cfg = unit_for(design, i)
            logs = [unit_log(cfg, 10 * i + j, rate=r) for j, r in enumerate(rates)]
            store.add(fit_unit(f"SN{i}", logs, folder / f"m{i}"))
    new, test = folder / "new.csv", folder / "test.csv"
    write_log(new, unit_log(unit_for(design, 50), 999, rate=2.0))
    write_log(test, unit_log(unit_for(design, 50), 998, rate=1.0))
    return {"db": db, "new": new, "test": test, "tmp": folder, "design": design}


# the kernel's float32 prediction vs the torch net's (tests/test_train.py), and the record's
# rounding of the response and the SF curve to 0.001 ppm
KERNEL_PPM = 0.01 + 0.001


def same_record(a: Any, b: Any, path: str = "") -> list[str]:
    """Where two records differ: to the bit, but the model's predictions (the response and
    the SF curve after the model) within KERNEL_PPM."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b))
                for d in same_record(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True))
                for d in same_record(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    predicted = path.startswith((".figures.response_ppm", ".figures.sf_curve.after_ppm"))
    if predicted and isinstance(a, float) and isinstance(b, float):
        return [] if abs(a - b) <= KERNEL_PPM else [f"{path}: {a} vs {b}"]
    return [] if a == b else [f"{path}: {a!r} vs {b!r}"]
