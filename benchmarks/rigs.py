"""Logs the way calibration rigs write them, end to end (`make bench-rigs`).

For each rig case of `fogsf.sim.rigs.benches.bench_cases` (a ROS-logged staircase with a
slewing, stalling table; +/-100 deg/s reversals in a plain rad/s log with an epoch time base;
a skew-mounted 3-axis IMU; quantised thermometers; ...) and each gyro drawn from the
population, the case's training and held-out test logs are written with their column map
beside them, `fogsf train --axis all` (or one axis) runs on the training log through that
map as a user would run it, and the trained model (numpy reference, bit-exact with the
kernel) predicts the test log's SF error. Scored against the generator's truth, per axis:

  sf_std_ppm    std over the test log's measuring samples of (predicted - true SF error)
  sf_target_ppm max(3 ppm, 2 % of the true SF error's std there): the issue's target
  bias_err_dph  per +/- pair of the test log (`pairs.find_pairs`): measured bias minus the
                true bias at the pair's centre; median |err| and the largest |err|
  bias_model    the trained bias head per test pair: std(predicted - true) against
                max(0.1 deg/h, 5 % of the true bias' std), beside a PX4-style cubic in board
                temperature fitted to the training log's pairs (a stationary log: per 100 s
                window, against max(0.2 deg/h, 10 %))

Every gyro has its own thermal bias from the population (a Shupe term, a quadratic and a
cubic on its coil).

Gyros: evaluation seeds 20000-29999 by default (`--seeds dev` for 0-9999, to tune on).

Raw logger output (issue 39; `RAW_CASES`, written by `raw_loggers.write_loggers`,
`write_px4`, `write_bursts` and `rig_logs.write_ros`): loggers (an IMU at 100 Hz on a 32-bit us boot
clock, thermometers at 1 Hz with ISO stamps and a dropout, the table's commands as events),
px4-rates (a jittered export with dropped samples, trained at 50 and 100 Hz, tested at 200 Hz
as logged), units (a deg/s log under a rad/s map; a rad/s and a deg/s log trained together:
both must be refused naming the units), burst-tvac (5 s bursts every 5 min of a stationary
gyro cooling 8 C over 2 h: the bias per burst against a cubic's in-sample residual, within
1.2 x), heated-ros (the ROS rig held at 38-62 C by its heater).

    python -m benchmarks.rigs --n 2 --out out/bench-rigs.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SEED_BASE = {"dev": 0, "eval": 20000}
SF_FLOOR_PPM = 3.0
SF_SHARE = 0.02
BIAS_TARGET_DPH = 0.1
BIAS_SHARE = 0.05
STILL_TARGET = (0.2, 0.10)  # a stationary log's bias: max(0.2 deg/h, 10 % of its std)


def score_bias(train_log, log, bias_dph: np.ndarray, truth,  # noqa: ANN001
               sf_train: np.ndarray | None = None, sf_test: np.ndarray | None = None) -> dict:
    """The bias head on the test log: per test window (a +/- pair), std(predicted - true)
    against max(0.1 deg/h, 5 % of the true bias' std), beside a PX4-style cubic in board
    temperature fitted to the training log's windows (the pairs measured as `train` measures
    them: the SF model's prediction `sf_train`, `sf_test` taken off their plateaus)."""
    from fogsf.logs.measure.bias import bias_windows

    wt, ws = bias_windows(train_log, sf_ppm=sf_train), bias_windows(log, sf_ppm=sf_test)
    if wt is None or ws is None:
        return {}
    true = ws.mean_of(truth.bias_dph)
    err = float(np.std(ws.mean_of(bias_dph) - true))
    cubic = np.polyval(np.polyfit(wt.temp_c, wt.bias_dph, 3), ws.temp_c)
    floor, share = STILL_TARGET if ws.source == "stationary" else (BIAS_TARGET_DPH, BIAS_SHARE)
    target = max(floor, share * float(np.std(true)))
    return {"bias_model_err_std_dph": err, "bias_true_std_dph": float(np.std(true)),
            "bias_model_target_dph": target, "bias_model_meets": bool(err <= target),
            "bias_px4_cubic_err_std_dph": float(np.std(cubic - true))}


def score_axis(model_dir: Path, train_path: Path, test_path: Path, axis: str, truth,  # noqa: ANN001 - rigs.Truth
               model: str) -> dict:
    """The trained model of one axis on its test log, against the truth."""
    from fogsf.logs.logio import read_log
    from fogsf.logs.measure.pairs import find_pairs
    from fogsf.logs.read.dialect import Dialect
    from fogsf.models.reference import replay
    from fogsf.models.stream import StreamModel

    log = read_log(test_path, Dialect(axis=axis or None))
    sm = StreamModel.load(model_dir).at_rate(log.sample_dt_s)
    out_steps = replay(sm, log.temp_c, log.gyro_dps)
    pred = out_steps.sf_ppm.astype(np.float64)
    m = truth.measures & log.measures
    out: dict = {"axis": axis or "-", "model": model}
    if m.any():  # a stationary log measures no SF (its model is the bias alone)
        true_std = float(np.std(truth.sf_ppm[m]))
        out.update(sf_std_ppm=float(np.std(pred[m] - truth.sf_ppm[m])),
                   true_sf_std_ppm=true_std,
                   sf_target_ppm=max(SF_FLOOR_PPM, SF_SHARE * true_std))
    pairs = find_pairs(log)
    if pairs is not None:
        true_bias = np.interp(pairs.t_s, truth.time_s, truth.bias_dph)
        err = pairs.bias_dps * 3600.0 - true_bias
        out.update(pairs=len(pairs), bias_err_median_dph=float(np.median(np.abs(err))),
                   bias_err_max_dph=float(np.max(np.abs(err))),
                   bias_within_target=float(np.mean(np.abs(err) <= BIAS_TARGET_DPH)))
    if sm.bias_head and out_steps.bias_dph is not None:
        train_log = read_log(train_path, Dialect(axis=axis or None))
        sf_train = replay(sm, train_log.temp_c, train_log.gyro_dps).sf_ppm.astype(np.float64)
        out.update(score_bias(train_log, log, out_steps.bias_dph.astype(np.float64), truth,
                              sf_train, pred))
    return out


def run_case(name: str, gyro: int, seed: int, model: str | None, work: Path) -> list[dict]:
    """Write the case's logs for one gyro (three for an IMU), train, score every axis."""
    from fogsf.sim.rigs import benches

    case = benches.bench_cases()[name]
    seeds = (gyro, gyro + 1, gyro + 2) if case.kind == "imu3" else (gyro,)
    folder = work / f"{name}-{gyro}"
    train, test = benches.write_case(folder, case, seeds, seed)
    axes = [a for a in train.truth if a]
    out_dir = folder / "model"
    cmd = [sys.executable, "-m", "fogsf", "train", "--train", str(train.path),
           "--out", str(out_dir), "--seed", str(seed)]
    if axes:
        cmd += ["--axis", "all"]
    if model:
        cmd += ["--model", model]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{name} gyro {gyro}: fogsf train failed: {r.stderr.strip()[-400:]}")
    took = time.perf_counter() - t0
    rows = []
    for a in axes or [""]:
        row = score_axis(out_dir / a if a else out_dir, train.path, test.path, a, test.truth[a],
                         model or "default")
        row.update(case=name, gyro=gyro, train_s=took)
        rows.append(row)
    return rows


# --- raw logger output (issue 39): several files, jitter and drops, units, bursts, heat ---

RAW_CASES = ("loggers", "px4-rates", "units", "burst-tvac", "heated-ros")


def _train(cmd_logs: list[str], out_dir: Path, seed: int, extra: tuple[str, ...] = ()
           ) -> float:
    cmd = [sys.executable, "-m", "fogsf", "train", *sum((["--train", p] for p in cmd_logs),
                                                        []), "--out", str(out_dir),
           "--seed", str(seed), *extra]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"fogsf train failed: {r.stderr.strip()[-400:]}")
    return time.perf_counter() - t0


def _sf_row(model_dir: Path, log_path: Path, truth, name: str, gyro: int,  # noqa: ANN001
            took: float) -> dict:
    """std(predicted - true SF error) on the test log as read through its map (the model
    re-rated to its rate, run on its rows as logged), against max(3 ppm, 2 % of truth)."""
    from fogsf.logs.logio import read_log
    from fogsf.models.reference import replay
    from fogsf.models.stream import StreamModel

    log = read_log(log_path)
    sm = StreamModel.load(model_dir).at_rate(log.sample_dt_s)
    pred = replay(sm, log.temp_c, log.gyro_dps).sf_ppm.astype(np.float64)
    m = truth.measures & log.measures
    true_std = float(np.std(truth.sf_ppm[m]))
    return {"case": name, "gyro": gyro, "axis": "-", "model": "default", "train_s": took,
            "sf_std_ppm": float(np.std(pred[m] - truth.sf_ppm[m])),
            "true_sf_std_ppm": true_std,
            "sf_target_ppm": max(SF_FLOOR_PPM, SF_SHARE * true_std),
            "rate_hz": log.sample_rate_hz,
            "sampling": None if log.sampling is None else log.sampling.text()}


def _loop_protocol(rate_hz: float, lo: float, hi: float, up: float, down: float, **kw):  # noqa: ANN202
    from fogsf.sim.rigs import chambers
    from fogsf.sim.rigs import protocols as rigs

    return rigs.reversal_protocol(100.0, 60.0,
                                  chamber=chambers.loop(lo, hi, up, down, soak_s=600.0),
                                  rate_hz=rate_hz, bias=None, thermal_bias=True, **kw)


def run_raw(name: str, gyro: int, seed: int, work: Path) -> list[dict]:
    """One raw-logger case for one gyro: its logs written as the loggers write them, read
    through the map beside them (no user script), trained and scored against the truth."""
    from fogsf.sim.rigs import chambers, raw_loggers, rig_logs
    from fogsf.sim.rigs import protocols as rigs

    folder = work / f"{name}-{gyro}"
    if name == "loggers":  # IMU at 100 Hz on its boot clock, thermometers at 1 Hz, table
        train_run = rigs.run_rig(_loop_protocol(100.0, -10.0, 40.0, 1.0, 0.7), gyro, seed)
        test_run = rigs.run_rig(_loop_protocol(100.0, -10.0, 40.0, 0.8, 0.9), gyro, seed + 1)
        tr = raw_loggers.write_loggers(folder / "train" / "imu.csv", train_run, seed=seed)
        te = raw_loggers.write_loggers(folder / "test" / "imu.csv", test_run, seed=seed + 1)
        took = _train([str(tr.path)], folder / "model", seed)
        return [_sf_row(folder / "model", te.path, te.truth[""], name, gyro, took)]
    if name == "px4-rates":  # jittered, dropped samples; trained at 50 and 100 Hz, test 200
        logs = []
        for k, (rate, up, down) in enumerate(((50.0, 1.5, 1.0), (100.0, 1.0, 1.5),
                                              (200.0, 1.2, 1.3))):
            run = rigs.run_rig(_loop_protocol(rate, -10.0, 40.0, up, down), gyro, seed + k)
            logs.append(raw_loggers.write_px4(folder / f"r{k}" / "gyro.csv", run, seed=seed + k))
        took = _train([str(logs[0].path), str(logs[1].path)], folder / "model", seed)
        return [_sf_row(folder / "model", logs[2].path, logs[2].truth[""], name, gyro, took)]
    if name == "units":  # a deg/s log under a rad/s map; a rad/s and a deg/s log together
        run = rigs.run_rig(_loop_protocol(10.0, 5.0, 35.0, 3.0, 3.0), gyro, seed)
        deg = rig_logs.write_plain(folder / "deg" / "plain.csv", run, gyro_unit="deg/s")
        rig_logs.write_mapping(deg.path.parent, {"gyro_dps": "gyro_dps * 57.29577951308232"})
        ok = rig_logs.write_plain(folder / "deg2" / "plain.csv", run, gyro_unit="deg/s")
        rad = rig_logs.write_plain(folder / "rad" / "plain.csv", run, gyro_unit="rad/s")
        rig_logs.write_mapping(rad.path.parent, {"gyro_dps": "gyro_rad_s"})  # no factor
        row: dict = {"case": name, "gyro": gyro}
        for key, cmd in (("deg_under_rad_map", ["inspect", str(deg.path)]),
                         ("rad_and_deg_together", ["train", "--train", str(ok.path),
                                                   "--train", str(rad.path), "--model", "poly",
                                                   "--out", str(folder / "m")])):
            r = subprocess.run([sys.executable, "-m", "fogsf", *cmd], capture_output=True,
                               text=True)
            err = [ln for ln in r.stderr.splitlines() if ": error: " in ln]
            row[key] = {"exit": r.returncode, "error": err[-1] if err else "",
                        "refused": r.returncode == 2 and len(err) == 1
                        and "rad/s" in err[0] and "deg/s" in err[0]}
        return [row]
    if name == "burst-tvac":  # 5 s bursts every 5 min, 2 h, the gyro cooling 8 C at rest
        p = rigs.stationary_protocol(chamber=chambers.Chamber([[0.0, 30.0], [7200.0, 22.0]]),
                                     rate_hz=50.0, bias=None, thermal_bias=True)
        rl = raw_loggers.write_bursts(folder / "tvac.csv", rigs.run_rig(p, gyro, seed))
        took = _train([str(rl.path)], folder / "model", seed, ("--window-s", "5"))
        return [_burst_row(folder / "model", rl.path, name, gyro, took)]
    if name == "heated-ros":  # the ROS rig with its heater holding the gyro at 38-62 C
        train_run = rigs.run_rig(_loop_protocol(10.0, 38.0, 62.0, 1.0, 0.7), gyro, seed)
        test_run = rigs.run_rig(_loop_protocol(10.0, 38.0, 62.0, 0.8, 0.9), gyro, seed + 1)
        tr = rig_logs.write_ros(folder / "train" / "ros.csv", train_run)
        te = rig_logs.write_ros(folder / "test" / "ros.csv", test_run)
        took = _train([str(tr.path)], folder / "model", seed)
        return [_sf_row(folder / "model", te.path, te.truth[""], name, gyro, took)]
    raise ValueError(name)


def _burst_row(model_dir: Path, path: Path, name: str, gyro: int, took: float) -> dict:
    """A burst log's bias per burst: the trained model's residual (measured - predicted)
    RMS against a cubic in board temperature fitted to the same bursts (in-sample)."""
    from fogsf.logs.logio import read_log
    from fogsf.logs.measure.bias import bias_windows
    from fogsf.models.reference import replay
    from fogsf.models.stream import StreamModel

    log = read_log(path)
    sm = StreamModel.load(model_dir).at_rate(log.sample_dt_s)
    out = replay(sm, log.temp_c, log.gyro_dps)
    w = bias_windows(log, 5.0)
    assert w is not None
    model = float(np.sqrt(np.mean((w.bias_dph - w.mean_of(out.bias_dph.astype(np.float64)))
                                  ** 2)))
    cubic = w.bias_dph - np.polyval(np.polyfit(w.temp_c, w.bias_dph, 3), w.temp_c)
    cubic_rms = float(np.sqrt(np.mean(cubic**2)))
    return {"case": name, "gyro": gyro, "axis": "-", "train_s": took, "bursts": len(w),
            "bias_model_rms_dph": model, "cubic_in_sample_rms_dph": cubic_rms,
            "ratio": model / cubic_rms, "meets": bool(model <= 1.2 * cubic_rms),
            "noise_floor_dph": w.noise_floor_dph}


def print_raw(row: dict) -> None:
    name, gyro = row["case"], row["gyro"]
    if "sf_std_ppm" in row:
        ok = "ok" if row["sf_std_ppm"] <= row["sf_target_ppm"] else "MISS"
        print(f"{name:18s} gyro {gyro}: std(pred - true) {row['sf_std_ppm']:6.2f} ppm (target "
              f"{row['sf_target_ppm']:.2f}, {ok}) at {row['rate_hz']:.5g} Hz; train "
              f"{row['train_s']:.0f} s", flush=True)
    elif "ratio" in row:
        print(f"{name:18s} gyro {gyro}: bias per burst ({row['bursts']}) RMS "
              f"{row['bias_model_rms_dph']:.3f} deg/h, cubic in-sample "
              f"{row['cubic_in_sample_rms_dph']:.3f}: {row['ratio']:.2f} x (target 1.2, "
              f"{'ok' if row['meets'] else 'MISS'})", flush=True)
    else:
        for key in ("deg_under_rad_map", "rad_and_deg_together"):
            r = row[key]
            print(f"{name:18s} gyro {gyro}: {key}: exit {r['exit']}, "
                  f"{'refused naming the units' if r['refused'] else 'NOT REFUSED'}",
                  flush=True)


def main(argv: list[str] | None = None) -> int:
    from fogsf.sim.rigs import benches

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m benchmarks.rigs --n 1 --cases "
                                       "plain-reversals")
    p.add_argument("--seeds", choices=tuple(SEED_BASE), default="eval")
    p.add_argument("--first", type=int, default=0, help="first gyro after the range's base")
    p.add_argument("--n", type=int, default=2, help="gyros per case (IMU cases: 3 each)")
    p.add_argument("--cases", default=",".join([*benches.bench_cases(), *RAW_CASES]),
                   help="comma-separated case names (default: all; the raw loggers' "
                        f"{', '.join(RAW_CASES)} too)")
    p.add_argument("--model", default=None, help="fogsf train --model (default: its default)")
    p.add_argument("--out", default="out/bench-rigs.json")
    args = p.parse_args(argv)
    names = [c for c in args.cases.split(",") if c]
    unknown = set(names) - set(benches.bench_cases()) - set(RAW_CASES)
    if unknown:
        p.error(f"unknown case {sorted(unknown)[0]}; cases: {', '.join(benches.bench_cases())}")
    rows: list[dict] = []
    base = SEED_BASE[args.seeds] + args.first
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            for k in range(args.n):
                gyro = base + 3 * k
                if name in RAW_CASES:
                    try:
                        raw = run_raw(name, gyro, gyro, Path(tmp))
                    except RuntimeError as e:
                        print(f"{name:18s} gyro {gyro}: FAILED: {e}", flush=True)
                        rows.append({"case": name, "gyro": gyro, "failed": str(e)})
                        continue
                    for row in raw:
                        print_raw(row)
                        rows.append(row)
                    continue
                try:
                    case_rows = run_case(name, gyro, gyro, args.model, Path(tmp))
                except RuntimeError as e:  # a refusal is a result: the row says which
                    print(f"{name:18s} gyro {gyro}: FAILED: {e}", flush=True)
                    rows.append({"case": name, "gyro": gyro, "failed": str(e)})
                    continue
                for row in case_rows:
                    rows.append(row)
                    bias = (f"bias |err| median {row['bias_err_median_dph']:.3f} max "
                            f"{row['bias_err_max_dph']:.3f} deg/h ({row['pairs']} pairs)"
                            if "pairs" in row else "no pairs")
                    if "bias_model_err_std_dph" in row:
                        bias += (f"; bias model {row['bias_model_err_std_dph']:.3f} deg/h "
                                 f"(target {row['bias_model_target_dph']:.2f}, PX4 cubic "
                                 f"{row['bias_px4_cubic_err_std_dph']:.3f})")
                    sf = "no SF (table stopped)"
                    if "sf_std_ppm" in row:
                        ok = "ok" if row["sf_std_ppm"] <= row["sf_target_ppm"] else "MISS"
                        sf = (f"std(pred - true) {row['sf_std_ppm']:6.2f} ppm (target "
                              f"{row['sf_target_ppm']:.2f}, {ok})")
                    print(f"{name:18s} gyro {gyro} axis {row['axis']}: {sf}; {bias}; train "
                          f"{row['train_s']:.0f} s", flush=True)
    met = sum(r.get("sf_std_ppm", np.inf) <= r.get("sf_target_ppm", 0.0) for r in rows)
    n_sf = sum("sf_std_ppm" in r for r in rows)
    print(f"SF target met on {met} of {n_sf} axes ({args.seeds} gyros from {base}; "
          f"{sum('failed' in r for r in rows)} runs failed)")
    bursts = [r for r in rows if "ratio" in r]
    if bursts:
        print(f"burst logs: bias per burst within 1.2 x a cubic's in-sample residual on "
              f"{sum(r['meets'] for r in bursts)} of {len(bursts)}")
    units = [r for r in rows if "deg_under_rad_map" in r]
    if units:
        both = sum(r["deg_under_rad_map"]["refused"] and r["rad_and_deg_together"]["refused"]
                   for r in units)
        print(f"units: refused naming rad/s and deg/s on {both} of {len(units)}")
    scored = [r for r in rows if "bias_model_meets" in r]
    if scored:
        print(f"bias model target met on {sum(r['bias_model_meets'] for r in scored)} of "
              f"{len(scored)} axes; median std(pred - true) "
              f"{np.median([r['bias_model_err_std_dph'] for r in scored]):.3f} deg/h, PX4 "
              f"cubic {np.median([r['bias_px4_cubic_err_std_dph'] for r in scored]):.3f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"seeds": args.seeds, "first_gyro": base, "rows": rows},
                              indent=1))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
