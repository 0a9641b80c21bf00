"""The fleet's commands at a line's scale: add, list, check, report and `train --prior` on
fleets of 10, 100 and 500 units, on SQLite and PostgreSQL.

Units are made cheaply, not trained (training 500 units takes hours): BASE simulated units
of one development design (`tests.fleet_units.unit_log`: a 2 C/min loop, 20 min soaks, 1 Hz)
give real summaries (`prior.unit_summary.summarize_unit`: the step series and the fits the
design's prior learns from); unit i of a fleet is base unit i % BASE with its series' SF
target jittered by white noise (seeded by i: every unit refitted differs), its figures
drawn around a line (the reference-program response, the residual, the interval, the SF
curve) with one unit in 50 defective (its response 10 spreads off), written through the
store's API (`FleetStore.add`, one transaction each, as `fleet add` writes). The new unit
is another unit of the design, trained by the CLI on a 2 C/min loop and tested on a 1 C/min
loop, with and without `--prior`, `--iters 20` both.

Timed, in this process (`fogsf.cli.main.main`, python's start and the first call's imports
left out: the plain `train` runs once before it is timed): `add` (the last
unit's transaction), `list`, `check` cold (the fleet just changed: computed and cached) and
warm (read from the cache), `report` (its check cached) and `train --prior` cold (the prior
learned and cached) and warm (read), against the plain `train` on the same logs and options,
the two taken in turns three times (medians; warm / plain the median of the three pairs'
ratios, in wall time and in this process's CPU time: a shared machine's load moves the
first, much less the second).

    python -m benchmarks.probes.fleet_scale --sizes 10,100,500 --backends sqlite,postgresql
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fogsf.cli.main import main as cli
from fogsf.fleet import check
from fogsf.fleet.records import LogRecord, UnitRecord
from fogsf.fleet.store import open_store

BASE = 8
DESIGN = 3  # a development design (docs/fleet.md's examples)
POINTS = ("soak -10 C", "up +0 C", "up +10 C", "up +25 C", "soak +35 C", "down +25 C",
          "down +10 C", "down +0 C", "soak -10 C again")


def base_summaries(cache: Path) -> list[dict]:
    """BASE real unit summaries (simulated logs), kept in `cache` between runs."""
    if cache.is_file():
        return json.loads(cache.read_text())
    from fogsf.prior.unit_summary import summarize_unit
    from fogsf.sim.fleet_units import unit_for
    from tests.fleet_units import unit_log

    out = [summarize_unit([unit_log(unit_for(DESIGN, i), 100 + i, rate=2.0)])
           for i in range(BASE)]
    cache.write_text(json.dumps(out))
    return out


def synthetic_unit(i: int, base: list[dict]) -> UnitRecord:
    """Unit i of a made-up line (see the module's docstring)."""
    from fogsf.prior.unit_fit import StepSeries

    rng = np.random.default_rng(1000 + i)
    summary = copy.deepcopy(base[i % len(base)])
    s = StepSeries.from_dict(summary["series"])
    s.y = s.y + rng.normal(0.0, 2.0, s.y.size)
    summary["series"] = s.as_dict()
    floor = float(rng.uniform(6.0, 9.0))
    shape = np.array([230.0, -40.0, -90.0, -130.0, 60.0, 10.0, 20.0, 40.0, 230.0])
    resp = shape * rng.normal(1.0, 0.08) + rng.normal(0.0, 8.0, shape.size)
    if i % 50 == 49:  # a defective unit
        resp[3] -= 250.0
    resp -= resp.mean()
    ratio = float(np.exp(rng.normal(0.0, 0.08)))
    hi = floor * float(rng.uniform(1.1, 2.2))
    temp = np.arange(-20.0, 41.0, 2.0)
    before = 0.02 * temp**3 * rng.normal(1.0, 0.1) - 3.0 * temp
    logs = [LogRecord(path=f"/lab/SN{i:05d}/loop.csv", sha256=f"{i:064x}", rows=9000,
                      span_s=9000.0, sample_rate_hz=1.0, ramp_rates_c_per_min=[2.0],
                      temp_min_c=-20.0, temp_max_c=40.0, role="train"),
            LogRecord(path=f"/lab/SN{i:05d}/test.csv", sha256=f"{i + 1:064x}", rows=9000,
                      span_s=9000.0, sample_rate_hz=1.0, ramp_rates_c_per_min=[1.0],
                      temp_min_c=-20.0, temp_max_c=40.0, role="test")]
    day, sec = divmod(i * 1800, 86400)
    return UnitRecord(
        unit=f"SN{i:05d}", logs=logs, model_id=f"{rng.integers(1 << 62):016x}",
        fitted_with={"model": "lag-lstm", "structure": "physics2", "options": {}},
        figures={"noise_floor_ppm": floor, "train_rms_over_floor": ratio,
                 "test_rms_over_floor": ratio * 1.2, "test_after_rms_ppm": floor * ratio * 1.2,
                 "response_ppm": {p: round(float(v), 3) for p, v in zip(POINTS, resp,
                                                                        strict=True)},
                 "sf_curve_log": "test",
                 "sf_curve": {"temp_c": temp.tolist(), "before_ppm": before.tolist(),
                              "after_ppm": rng.normal(0.0, 3.0, temp.size).tolist()}},
        interval={"rms_lo_ppm": floor, "rms_hi_ppm": hi, "noise_floor_ppm": floor,
                  "test_rms_ppm": floor * ratio * 1.2, "held": True, "covered": True,
                  "source": "rate transfer"},
        summary=summary, fogsf_version="bench",
        created_utc=f"2026-{1 + day // 28:02d}-{1 + day % 28:02d}T{sec // 3600:02d}:"
                    f"{sec % 3600 // 60:02d}:00Z")


CPU_S: list[float] = [0.0]  # the last `timed` call's CPU seconds (this process, all threads)


def timed(argv: list[str]) -> float:
    """Seconds `fogsf ARGV` takes here (its output swallowed); it must succeed. Its CPU
    seconds in CPU_S[0]: what a shared machine's load does not stretch."""
    buf = io.StringIO()
    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(buf):
        code = cli(argv)
    dt = time.perf_counter() - t0
    CPU_S[0] = time.process_time() - c0
    if code != 0:
        raise SystemExit(f"fogsf {' '.join(argv)} failed ({code}):\n{buf.getvalue()}")
    return dt


def fleet_url(backend: str, tmp: Path, n: int) -> str:
    if backend == "sqlite":
        return str(tmp / f"line-{n}.fleet")
    from tests.fleet_units import _fresh_pg_database, pg_server

    server = pg_server()
    if server is None:
        raise SystemExit("no PostgreSQL server (Debian's postgresql, or FOGSF_TEST_POSTGRES_URL)")
    return _fresh_pg_database(server)


def bench(backend: str, n: int, base: list[dict], tmp: Path, new: Path, test: Path,
          spec: float) -> dict:
    url = fleet_url(backend, tmp, n)
    units = [synthetic_unit(i, base) for i in range(n)]
    t0 = time.perf_counter()
    with open_store(url) as store:
        for u in units[:-1]:
            store.add(u)
        build = time.perf_counter() - t0
        t0 = time.perf_counter()
        store.add(units[-1])
        add = time.perf_counter() - t0
    row = {"backend": backend, "units": n, "build_s": build, "add_s": add}
    row["list_s"] = timed(["fleet", "list", url, "--spec-ppm", str(spec)])
    check.NULL_KNOWN.clear()  # cold: no threshold this process drew for another fleet
    check.null_maxima.cache_clear()
    row["check_cold_s"] = timed(["fleet", "check", url])
    row["check_warm_s"] = timed(["fleet", "check", url])
    out = tmp / f"report-{backend}-{n}"
    row["report_s"] = timed(["fleet", "report", url, "--out", str(out), "--spec-ppm",
                             str(spec)])
    prior = ["train", "--prior", url, "--train", str(new), "--test", str(test), "--iters",
             "20", "--no-progress", "--seed", "1"]
    row["prior_cold_s"] = timed([*prior, "--out", str(tmp / f"p-{backend}-{n}-cold")])
    # warm, and the plain train on the same logs and options, taken in turns (a shared
    # machine's load moves: each figure the median of 3, the ratio of runs side by side)
    warm, plain, cpu = [], [], []
    for r in range(3):
        warm.append(timed([*prior, "--out", str(tmp / f"p-{backend}-{n}-warm{r}")]))
        cpu.append(CPU_S[0])
        plain.append(timed([*prior[:1], *prior[3:], "--out", str(tmp / f"t-{backend}-{n}-{r}")]))
        cpu[-1] /= CPU_S[0]
    row["prior_warm_s"], row["train_s"] = float(np.median(warm)), float(np.median(plain))
    row["warm_over_plain"] = float(np.median(np.array(warm) / np.array(plain)))
    row["warm_over_plain_cpu"] = float(np.median(cpu))
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="10,100,500")
    ap.add_argument("--backends", default="sqlite,postgresql")
    ap.add_argument("--spec-ppm", type=float, default=12.0)
    ap.add_argument("--out", default="out/fleet-scale.json")
    ap.add_argument("--base-cache", default="out/fleet-scale-base.json")
    a = ap.parse_args(argv)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    base = base_summaries(Path(a.base_cache))
    from fogsf.logs.writer import write_log
    from fogsf.sim.fleet_units import unit_for
    from tests.fleet_units import unit_log

    rows = []
    with tempfile.TemporaryDirectory(prefix="fleet-scale-") as t:
        tmp = Path(t)
        new, test = tmp / "new.csv", tmp / "test.csv"
        write_log(new, unit_log(unit_for(DESIGN, 50), 999, rate=2.0))
        write_log(test, unit_log(unit_for(DESIGN, 50), 998, rate=1.0))
        plain = ["train", "--train", str(new), "--test", str(test), "--iters", "20",
                 "--no-progress", "--seed", "1"]
        timed([*plain, "--out", str(tmp / "warm-up")])  # imports and first calls left out
        for backend in a.backends.split(","):
            for n in (int(x) for x in a.sizes.split(",")):
                row = bench(backend, n, base, tmp, new, test, a.spec_ppm)
                print(json.dumps({k: round(v, 2) if isinstance(v, float) else v
                                  for k, v in row.items()}), file=sys.stderr, flush=True)
                rows.append(row)
    Path(a.out).write_text(json.dumps(rows, indent=2) + "\n")
    print("| backend | units | add | list | check cold | check warm | report | "
          "train --prior cold | warm | plain train | warm / plain | in CPU time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['backend']} | {r['units']} | {1000 * r['add_s']:.0f} ms | {r['list_s']:.2f} | "
              f"{r['check_cold_s']:.2f} | {r['check_warm_s']:.2f} | {r['report_s']:.1f} | "
              f"{r['prior_cold_s']:.1f} | {r['prior_warm_s']:.1f} | {r['train_s']:.1f} | "
              f"{r['warm_over_plain']:.2f} | {r['warm_over_plain_cpu']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
