"""Probe (an oracle): can a line's data show a unit whose slowest SF part is slower?

`fogsf fleet check` compares units by what their models predict; a unit whose slowest
internal part an SF factor reads has a time constant DEFECT_TAU_FACTOR (2.5) x the design's
(`fogsf.sim.fleet_units.defective_unit(..., "tau")`) is rarely flagged. Two questions:

- oracle: with the truth's structure known (the simulator's nodes and SF terms), how far
  is the defective unit's exact SF response on its training program from the closest
  NORMAL unit of the design: the slow part's time constant within the units' +/-15 %
  (a grid), every term's coefficient within the units' +/-25 % (box-bounded least
  squares), any SF offset. Its squared distance per 5 s step over the unit's noise
  variance (`unit_fit.fit_unit(..., 2).sigma2`) is the chi-square a perfect detector
  would see; a normal unit's own distance (other parts at the design's) is the yardstick.
- practical (`--practical N`, lines of N normal units and the defective one): the slowest
  time constant of each unit's 1- and 2-node fit against the line's, leave one out.
- check (`--check N`): `fogsf fleet check` itself on such a line, units trained as its
  tests train them; with `--normal-lines M` also M lines of N + 1 normal units (other unit
  indices) a design, none defective: the false flags.
- feature (`--feature N`): the slow-part features alone (`fogsf.prior.slow_part`: the
  effective time constant, the curve misfit and the chi-square against the prior of the
  line's others; the check's machinery on them and nothing else; records hold the units'
  summaries, no training): on the line with the defective unit and on `--normal-lines M`
  normal lines a design (cheap: many lines for their false-flag rate).
- time (`--time 100,500`): the slow-part features' cost on soak lines of those sizes of the
  first design (one unit in 50 with the slower part), the design's prior and the
  chi-square apart (summaries kept in `--time-cache`).
`--records DIR` keeps `--check`'s trained lines (records, not models) and reads them on
another run: the check's figures again without training.

Programs: `loop2h` (2 C/min up and down, -20..40 C, 20 min soaks: the check's tests) and
`soak1h` (1 C/min, 60 min soaks). Tune on development designs (`--designs 1:61`), report
on evaluation designs.

    python -m benchmarks.probes.fleet_slow_part --designs 20000:20010 --programs loop2h,soak1h
"""

from __future__ import annotations

import argparse
import copy
import json
import sys

import numpy as np

from fogsf.sim.config import ProfileConfig, SimConfig
from fogsf.sim.fleet_units import SF_SPREAD, TAU_SPREAD, defective_unit, design_for_seed, unit_for

FIRST_UNIT = 1000  # unit indices no bench or test uses
STEP = 5  # samples a model step at 1 Hz
PROGRAMS = {"loop2h": (2.0, 1200.0), "soak1h": (1.0, 3600.0)}  # C/min, soak s
TAU_GRID = 7


def program(name: str) -> ProfileConfig:
    rate, soak = PROGRAMS[name]
    lo, hi = -20.0, 40.0
    ramp = (hi - lo) / rate * 60.0
    pts = [[0.0, lo], [soak, lo], [soak + ramp, hi], [2 * soak + ramp, hi],
           [2 * soak + 2 * ramp, lo], [3 * soak + 2 * ramp, lo]]
    return ProfileConfig(kind="program", points=pts)


def run(cfg: SimConfig, name: str, seed: int, quiet: bool = False):  # noqa: ANN201
    from fogsf.sim.gyro import simulate
    from fogsf.sim.population import run_on_gyro

    cfg = copy.deepcopy(cfg)
    if quiet:
        cfg.noise.arw_deg_per_sqrt_h = cfg.noise.pulse_arcsec = cfg.noise.temp_noise_c = 0.0
    r = run_on_gyro(cfg, program(name), seed, "fleet-unit")
    r.dt_s = 1.0
    return simulate(r)


def steps(x: np.ndarray) -> np.ndarray:
    return x[: x.size // STEP * STEP].reshape(-1, STEP).mean(axis=1)


def slow_part(cfg: SimConfig) -> str:
    read = {n for t in cfg.sf.terms for n in t.nodes}
    return max((n for n in cfg.thermal.nodes[2:] if n.name in read), key=lambda n: n.tau_s).name


def box_lsq(x: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min |y - x v|^2 with lo <= v <= hi, by coordinate descent (convex: it converges)."""
    g, b = x.T @ x, x.T @ y
    v = np.clip(np.linalg.lstsq(x, y, rcond=None)[0], lo, hi)
    for _ in range(400):
        for j in range(v.size):
            v[j] = np.clip(v[j] + (b[j] - g[j] @ v) / g[j, j], lo[j], hi[j])
    return v


def oracle_distance(y: np.ndarray, design: SimConfig, part: str, name: str) -> float:
    """Squared distance per step (ppm^2) from response `y` to the closest normal unit."""
    best = np.inf
    for f in np.linspace(1 - TAU_SPREAD, 1 + TAU_SPREAD, TAU_GRID):
        c = copy.deepcopy(design)
        for n in c.thermal.nodes:
            if n.name == part:
                n.tau_s *= f
        res = run(c, name, 0, quiet=True)
        cols, total = [], np.zeros_like(res.sf_ppm)
        for t in c.sf.terms:
            dt = sum(w * res.nodes[nm] for nm, w in t.nodes.items()) - t.ref_c
            for term in (t.lin_ppm_per_c * dt, t.quad_ppm_per_c2 * dt**2,
                         t.cube_ppm_per_c3 * dt**3):
                if np.any(term):
                    cols.append(steps(term))
                    total = total + term
        rest = steps(res.sf_ppm - total)  # what the terms' coefficients do not scale
        x = np.stack([*cols, np.ones_like(rest)], axis=1)
        lo = np.r_[np.full(len(cols), 1 - SF_SPREAD), -1e9]
        hi = np.r_[np.full(len(cols), 1 + SF_SPREAD), 1e9]
        r = y - rest - x @ box_lsq(x, y - rest, lo, hi)
        best = min(best, float(r @ r))
    return best


def noise_s2(log) -> float:  # noqa: ANN001
    from fogsf.prior.unit_fit import fit_unit, step_series

    return fit_unit(step_series([log]), 2).sigma2


def oracle(design_seed: int, name: str) -> dict:
    design = design_for_seed(design_seed)
    bad = defective_unit(design_seed, FIRST_UNIT, "tau")
    good = unit_for(design_seed, FIRST_UNIT + 1)
    part = slow_part(design)
    out = {}
    for label, cfg in (("defective", bad), ("normal", good)):
        y = steps(run(cfg, name, 0, quiet=True).sf_ppm)
        s2 = noise_s2(run(cfg, name, 7).log)
        out[label] = oracle_distance(y, design, part, name) / s2
    return out


def practical(design_seed: int, name: str, n_normal: int) -> dict:
    """The slowest time constant of each unit's k-node fit (`unit_fit.fit_unit`, k = 1, 2),
    each unit against the others: z = (x - mean) / sqrt(s^2 - mean se^2 + se^2 + s^2 / m)
    on log tau, se from the fit's covariance (`fleet check`'s statistic)."""
    from fogsf.prior.unit_fit import fit_unit, step_series

    cfgs = [unit_for(design_seed, FIRST_UNIT + 1 + i) for i in range(n_normal)]
    cfgs.append(defective_unit(design_seed, FIRST_UNIT, "tau"))
    series = [step_series([run(c, name, 200 + i).log]) for i, c in enumerate(cfgs)]
    out = {}
    for k in (1, 2):
        fits = [fit_unit(s, k) for s in series]
        x = np.array([f.theta[k - 1] for f in fits])
        se = np.array([np.sqrt(max(f.cov[k - 1, k - 1], 0.0)) for f in fits])
        z = []
        for i in range(x.size):
            o = np.arange(x.size) != i
            s2 = x[o].var(ddof=1)
            z.append((x[i] - x[o].mean())
                     / np.sqrt(max(s2 - np.mean(se[o] ** 2), 0.0) + se[i] ** 2 + s2 / o.sum()))
        out[f"k{k}"] = {"defective_z": round(float(z[-1]), 2),
                        "normal_max_abs_z": round(float(np.max(np.abs(z[:-1]))), 2)}
    return out


CHECK_TRAIN = {"model": "lag-lstm", "structure": "physics", "nodes": 1, "iters": 2,
               "hysteresis": "off", "transfer_check": False, "progress": False}


def check_line(design_seed: int, name: str, n_normal: int) -> dict:
    """`fleet check` on the line (units trained as tests/test_fleet_check.py trains them):
    is the defective unit flagged, and is any unit of the normal units' line."""
    from fogsf.fleet.check import check_fleet

    units = trained_line(line_configs(design_seed, n_normal, 0), name,
                         _kept_as(design_seed, name, n_normal, 0))
    bad = units[-1].unit
    return {"found": bad in check_fleet(units).flagged,
            "normal_flagged": len(check_fleet(units[:-1]).flagged)}


def normal_line(design_seed: int, name: str, n_normal: int, line: int) -> bool:
    """Is a line of n_normal + 1 normal units (line `line` >= 1) flagged anywhere?"""
    from fogsf.fleet.check import check_fleet

    return bool(check_fleet(trained_line(line_configs(design_seed, n_normal, line), name,
                                         _kept_as(design_seed, name, n_normal, line))).flagged)


RECORDS: list[str] = [""]  # --records: trained lines kept in this directory ("": not kept)


def _kept_as(design_seed: int, name: str, n_normal: int, line: int) -> str:
    return f"{RECORDS[0]}/{name}-d{design_seed}-n{n_normal}-l{line}.json" if RECORDS[0] else ""


def trained_line(cfgs: list, name: str, kept: str = "") -> list:
    """The units `cfgs` on program `name`, trained as the check's tests train them (read
    from `kept` when it holds them, else kept there: the records, not the models)."""
    import tempfile
    from pathlib import Path

    from fogsf.fleet.records import UnitRecord, unit_record
    from fogsf.training.options import TrainOptions
    from fogsf.training.train import run_training

    if kept and Path(kept).is_file():
        return [UnitRecord.from_dict(d) for d in json.loads(Path(kept).read_text())]
    units = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, c in enumerate(cfgs):
            log = run(c, name, 200 + i).log
            out = Path(tmp) / f"u{i}"
            metrics, fitted = run_training(TrainOptions(**CHECK_TRAIN),  # type: ignore[arg-type]
                                           [log], None, out)
            units.append(unit_record(f"SN{i:03d}", [log], None, metrics, fitted, out,
                                     dict(CHECK_TRAIN), keep_dir=False))
    if kept:
        Path(kept).parent.mkdir(parents=True, exist_ok=True)
        Path(kept).write_text(json.dumps([u.as_dict() for u in units]))
    return units


def line_configs(design_seed: int, n_normal: int, line: int) -> list:
    """Line `line` of a design: 0, n_normal normal units and the defective one last; 1..,
    n_normal + 1 normal units of other indices."""
    if line == 0:
        return [*(unit_for(design_seed, FIRST_UNIT + 1 + i) for i in range(n_normal)),
                defective_unit(design_seed, FIRST_UNIT, "tau")]
    return [unit_for(design_seed, FIRST_UNIT + 100 * line + i) for i in range(n_normal + 1)]


def feature_lines(design_seed: int, name: str, n_normal: int, lines: int) -> dict:
    """The slow-part feature alone through `check_fleet` (made-up figures, real summaries)."""
    from fogsf.fleet.check import check_fleet
    from fogsf.fleet.records import UnitRecord
    from fogsf.prior.unit_fit import step_series

    flagged, found = 0, False
    for line in range(lines + 1):
        recs = [UnitRecord(f"SN{i:03d}", [], "", summary={
            "structure": "physics1",
            "series": step_series([run(c, name, 200 + i).log]).as_dict()})
                for i, c in enumerate(line_configs(design_seed, n_normal, line))]
        got = check_fleet(recs).flagged
        if line == 0:
            found = recs[-1].unit in got
            got = check_fleet(recs[:-1]).flagged
        flagged += bool(got)
    return {"found": found, "normal_lines": lines + 1, "normal_lines_flagged": flagged}


def line_summaries(design_seed: int, n: int, cache: str | None) -> list[dict]:
    """Summaries (`prior.unit_summary.summarize_unit`, as a record keeps them) of n units of a
    design on `soak1h`, unit 50 j + 49 defective (the slower part), kept in `cache`."""
    from pathlib import Path

    from fogsf.prior.unit_summary import summarize_unit

    path = Path(cache) if cache else None
    got: list[dict] = json.loads(path.read_text()) if path and path.is_file() else []
    for i in range(len(got), n):
        c = defective_unit(design_seed, FIRST_UNIT, "tau") if i % 50 == 49 else \
            unit_for(design_seed, FIRST_UNIT + 1 + i)
        got.append(summarize_unit([run(c, "soak1h", 200 + i).log]))
    if path and n > 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(got))
    return got[:n]


def timing(design_seed: int, sizes: list[int], cache: str | None) -> list[dict]:
    """Wall and CPU seconds of the slow-part features of a soak line of each size (`slow_part
    .line_features`, every unit's summary holding its fits and "slow"), of the design's
    prior alone (`design_prior.learn`, what the chi-square starts from) and of the
    chi-square (`slow_part.prior_chi2`, the prior included)."""
    import time

    from fogsf.prior.design_prior import learn
    from fogsf.prior.slow_part import line_features, prior_chi2
    from fogsf.prior.unit_fit import StepSeries, UnitFit

    everything = line_summaries(design_seed, max(sizes), cache)
    rows = []
    for n in sizes:
        summ = everything[:n]
        first: dict[int, dict[str, UnitFit]] = {}
        for i, x in enumerate(summ):
            for k, f in x["fits"].items():
                first.setdefault(int(k), {})[str(i)] = UnitFit.from_dict(f)
        series = {str(i): StepSeries.from_dict(x["series"]) for i, x in enumerate(summ)}
        row: dict = {"design": design_seed, "units": n}
        for name in ("learn", "prior_chi2", "line_features"):
            t0, c0 = time.perf_counter(), time.process_time()
            if name == "learn":
                learn(series, first=first)
            elif name == "prior_chi2":
                prior_chi2(summ)
            else:
                line_features(summ)
            row[f"{name}_s"] = round(time.perf_counter() - t0, 2)
            row[f"{name}_cpu_s"] = round(time.process_time() - c0, 2)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", default="20000:20010", help="design seeds FIRST:END")
    ap.add_argument("--programs", default="loop2h,soak1h")
    ap.add_argument("--practical", type=int, default=0,
                    help="also the leave-one-out statistic on lines of this many normal units")
    ap.add_argument("--check", type=int, default=0,
                    help="also `fleet check` on lines of this many normal units")
    ap.add_argument("--normal-lines", type=int, default=0,
                    help="with --check or --feature: this many lines of normal units a design")
    ap.add_argument("--feature", type=int, default=0,
                    help="the slow-part feature alone on lines of this many normal units")
    ap.add_argument("--time", default="",
                    help="only time the slow-part features on soak lines of these sizes "
                         "(e.g. 100,500) of the first design")
    ap.add_argument("--time-cache", default="out/fleet-slow-part-line.json",
                    help="with --time: the line's unit summaries kept here between runs")
    ap.add_argument("--records", default="",
                    help="with --check: keep the trained lines' records in this directory and "
                         "read them from there on another run (no training again; named by "
                         "design and line only: clear it when training changes)")
    ap.add_argument("--no-oracle", action="store_true")
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    lo, hi = (int(v) for v in a.designs.split(":"))
    if a.time:
        timing(lo, [int(v) for v in a.time.split(",")], a.time_cache)
        return 0
    RECORDS[0] = a.records
    rows = []
    for name in a.programs.split(","):
        for d in range(lo, hi):
            row: dict = {"design": d, "program": name}
            if not a.no_oracle:
                row["oracle"] = oracle(d, name)
            if a.practical:
                row["practical"] = practical(d, name, a.practical)
            if a.check:
                row["check"] = check_line(d, name, a.check)
                row["check"]["more_normal_lines_flagged"] = [
                    normal_line(d, name, a.check, j) for j in range(1, a.normal_lines + 1)]
            if a.feature:
                row["feature"] = feature_lines(d, name, a.feature, a.normal_lines)
            rows.append(row)
            print(json.dumps(row), flush=True)
    for name in a.programs.split(","):
        got = [r for r in rows if r["program"] == name]
        feats = [r["feature"] for r in got if "feature" in r]
        if feats:
            print(f"{name}: slow-part feature alone: found {sum(f['found'] for f in feats)} "
                  f"of {len(feats)}; normal lines flagged "
                  f"{sum(f['normal_lines_flagged'] for f in feats)} of "
                  f"{sum(f['normal_lines'] for f in feats)}", file=sys.stderr)
        if "oracle" in got[0]:
            yard = max(r["oracle"]["normal"] for r in got)
            seen = sum(r["oracle"]["defective"] > max(yard, 1.0) * 2 for r in got)
            bad = sorted(round(r["oracle"]["defective"], 1) for r in got)
            good = sorted(round(r["oracle"]["normal"], 1) for r in got)
            print(f"{name}: oracle distance of the slower part {bad}; normal units {good}; "
                  f"over twice the largest normal: {seen} of {len(got)}", file=sys.stderr)
        for k in ("k1", "k2"):
            sep = [r["practical"][k] for r in got if "practical" in r]
            if sep:
                n = sum(abs(p["defective_z"]) > max(3.0, 2 * p["normal_max_abs_z"]) for p in sep)
                print(f"  time constant z ({k}): separated (|z| > 3 and > 2 x the normals') "
                      f"{n} of {len(sep)}", file=sys.stderr)
        checks = [r["check"] for r in got if "check" in r]
        if checks:
            more = [f for c in checks for f in c["more_normal_lines_flagged"]]
            print(f"{name}: fleet check: found {sum(c['found'] for c in checks)} of "
                  f"{len(checks)}; "
                  f"normal lines with a flag "
                  f"{sum(c['normal_flagged'] > 0 for c in checks) + sum(more)} of "
                  f"{len(checks) + len(more)}", file=sys.stderr)
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
