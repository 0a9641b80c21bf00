"""The bias model on evaluation gyros of the population: trained on one chamber loop, scored
on another (another path, another noise seed) against the simulator's true bias.

For each gyro: its own bias law from the population (offset, slope), on its coil's
temperature, with a quadratic and, in the "shupe" case, a Shupe term (deg/h per C/min of the
coil's temperature change) added. Three protocols on the same chamber loops: +/-100 deg/s
reversals every 60 s (the bias from the pairs) and a stationary soak-and-ramp (the table
stopped: the bias is the output minus the earth rate); and the reversals again from a
training loop that ramps down at 2 C/min, faster than the test's 1.5 ("reversals-fast").
Scored per test window (a pair, or 100 s): std(predicted - true) beside std(true) and a
PX4-style cubic in board temperature fitted to the same training windows.

  python -m benchmarks.bias_eval --gyros 20000:20032 --out out/bench-bias.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from fogsf.logs.logio import read_log, with_mapping_beside
from fogsf.logs.measure.bias import before_after, bias_windows
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.config import BiasConfig
from fogsf.sim.population import gyro_for_seed
from fogsf.sim.rigs import chambers, rig_logs
from fogsf.sim.rigs import protocols as rigs
from fogsf.training.bias.features import bank_feature_map
from fogsf.training.bias.fit import fit_bias
from fogsf.training.bias.interval import bias_interval
from fogsf.training.bias.structure import CANDIDATES

TRAIN_LOOP = (-10.0, 50.0, 1.0, 0.7, 1200.0)  # lo, hi C, up, down C/min, soak s
# reversals-fast: the same reversals from a loop that ramps down faster than the test
FAST_TRAIN_LOOP = (-10.0, 50.0, 1.0, 2.0, 1200.0)
KINDS = ("reversals", "reversals-fast", "stationary")
TEST_LOOP = (0.0, 40.0, 0.5, 1.5, 900.0)
SHUPE = {"no-shupe": 0.0, "shupe": 2.0}  # deg/h per C/min
# the population's own thermal bias (`population.with_thermal_bias`): Shupe, quadratic, cubic
POPULATION = "population"
CASES = (*SHUPE, POPULATION)


def bias_law(gyro: int, shupe: float | None) -> BiasConfig:
    """The gyro's own bias (offset, slope) with a quadratic and the Shupe term, on its coil
    (the first node named coil*, else the population's bias node); shupe None: the
    population's thermal bias drawn for the gyro."""
    if shupe is None:
        return gyro_for_seed(gyro, thermal_bias=True).bias
    cfg = gyro_for_seed(gyro)
    coils = [n.name for n in cfg.thermal.nodes if n.name.startswith("coil")]
    return BiasConfig(**{**asdict(cfg.bias), "quad_dph_per_c2": 0.001,
                         "node": coils[0] if coils else cfg.bias.node,
                         "shupe_dph_per_c_per_min": shupe})


def protocol(kind: str, loop: tuple, bias: BiasConfig) -> rigs.RigProtocol:
    chamber = chambers.loop(*loop)
    if kind.startswith("reversals"):
        return rigs.reversal_protocol(100.0, 60.0, chamber=chamber, bias=bias)
    return rigs.stationary_protocol(chamber, bias=bias)


def one(gyro: int, kind: str, shupe: float | None, work: Path,
        candidates: tuple[str, ...] | None = None) -> dict:
    bias = bias_law(gyro, shupe)
    logs, truth = [], []
    train_loop = FAST_TRAIN_LOOP if kind == "reversals-fast" else TRAIN_LOOP
    for name, loop, seed in (("train", train_loop, 1), ("test", TEST_LOOP, 2)):
        rl = rig_logs.rig_log("plain", work / f"{gyro}-{kind}-{name}" / "log.csv",
                          protocol(kind, loop, replace(bias)), (gyro,), seed=seed)
        logs.append(read_log(rl.path, with_mapping_beside(rl.path, Dialect())))
        truth.append(rl.truth[""].bias_dph)
    # reversals: the bias head on the SF model's z (the lag bank's, for a loop); stationary:
    # a bias-only model with its own front end
    turning = kind.startswith("reversals")
    fm = bank_feature_map([logs[0]], 5.0) if turning else None
    model = fit_bias(fm, [logs[0]], candidates=candidates)
    wt, ws = bias_windows(logs[0], 100.0), bias_windows(logs[1], 100.0)
    assert model is not None and wt is not None and ws is not None

    true = ws.mean_of(truth[1])
    per_sample = model.predict(logs[1])
    pred = ws.mean_of(per_sample)
    iv = bias_interval(model.family, logs[1], per_sample)
    assert iv is not None
    lo_iv, hi_iv = iv["rms_interval_dph"]
    after_rms = before_after(ws, per_sample)["after"]["rms_dph"]
    cubic = np.polyval(np.polyfit(wt.temp_c, wt.bias_dph, 3), ws.temp_c)
    err, err_cubic = float(np.std(pred - true)), float(np.std(cubic - true))
    rel = 0.05 if turning else 0.10
    floor = 0.1 if turning else 0.2
    return {"gyro": gyro, "protocol": kind,
            "shupe_dph_per_c_per_min": bias.shupe_dph_per_c_per_min,
            "bias_node": bias.node, "windows": len(ws),
            "structure": model.choice.as_dict() if model.choice is not None else None,
            "true_std_dph": float(np.std(true)),
            "err_std_dph": err, "px4_cubic_err_std_dph": err_cubic,
            "measured_noise_floor_dph": ws.noise_floor_dph,
            "target_dph": max(floor, rel * float(np.std(true))),
            "meets_target": err <= max(floor, rel * float(np.std(true))),
            "beats_cubic_2x": err_cubic >= 2.0 * err,
            "after_rms_dph": after_rms, "interval_dph": [lo_iv, hi_iv],
            "interval_covers": bool(lo_iv <= after_rms <= hi_iv), "interval": iv}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bias_eval", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gyros", default="20000:20032", help="population seeds LO:HI")
    p.add_argument("--out", type=Path, default=Path("out/bench-bias.json"))
    p.add_argument("--candidates", default=None,
                   help="bias structures to choose among, comma-separated (default: all)")
    args = p.parse_args(argv)
    lo, hi = (int(x) for x in args.gyros.split(":"))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for gyro in range(lo, hi):
            for kind in KINDS:
                for case in CASES:
                    shupe = SHUPE.get(case)
                    cands = tuple(args.candidates.split(",")) if args.candidates else None
                    r = one(gyro, kind, shupe, Path(tmp), cands)
                    r["case"] = case
                    rows.append(r)
                    print(f"gyro {gyro} {kind:14s} {case:8s} true std {r['true_std_dph']:6.3f}"
                          f"  err {r['err_std_dph']:6.3f}  cubic {r['px4_cubic_err_std_dph']:6.3f}"
                          f"  floor {r['measured_noise_floor_dph']:6.3f}  target "
                          f"{r['target_dph']:5.3f} {'ok' if r['meets_target'] else 'MISS'}"
                          f"  after RMS {r['after_rms_dph']:.3f} in [{r['interval_dph'][0]:.3f}, "
                          f"{r['interval_dph'][1]:.3f}]"
                          f"  {r['structure']['chosen']} " + " ".join(
                              f"{k}={v:.3f}" for k, v in
                              r['structure']['heldout_rms_dph'].items()),
                          flush=True)
    summary = {}
    for kind in KINDS:
        for case in CASES:
            sel = [r for r in rows if r["protocol"] == kind and r["case"] == case]
            e = np.array([r["err_std_dph"] for r in sel])
            c = np.array([r["px4_cubic_err_std_dph"] for r in sel])
            summary[f"{kind}/{case}"] = {
                "gyros": len(sel), "err_median_dph": float(np.median(e)),
                "err_max_dph": float(e.max()), "cubic_median_dph": float(np.median(c)),
                "meets_target": int(sum(r["meets_target"] for r in sel)),
                "beats_cubic_2x": int(sum(r["beats_cubic_2x"] for r in sel)),
                "interval_covers": int(sum(r["interval_covers"] for r in sel)),
                "structures": {c: sum(r["structure"]["chosen"] == c for r in sel)
                               for c in CANDIDATES if any(r["structure"]["chosen"] == c
                                                          for r in sel)}}
    for k, v in summary.items():
        print(f"{k:29s} median err {v['err_median_dph']:.3f} (max {v['err_max_dph']:.3f}) "
              f"deg/h, PX4 cubic {v['cubic_median_dph']:.3f}; target met {v['meets_target']}/"
              f"{v['gyros']}, cubic beaten 2x {v['beats_cubic_2x']}/{v['gyros']}, interval "
              f"covers {v['interval_covers']}/{v['gyros']}; chosen "
              + ", ".join(f"{c} {n}" for c, n in v["structures"].items()))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"gyros": [lo, hi], "train_loop": TRAIN_LOOP,
                                    "fast_train_loop": FAST_TRAIN_LOOP,
                                    "test_loop": TEST_LOOP, "rows": rows,
                                    "summary": summary}, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
