"""How far one ramp rate takes a compensation model (`make bench-transfer`).

The paper's protocol trains on a 0.5 C/min ramp and tests on 1 C/min. Over several seeds of
the simulated paper scenario this prints, per seed, the test RMS as a multiple of the test
log's noise floor for
- the default model (lag-lstm, its structure chosen by the training logs: "chosen" names
  it, p1-p3 physics nodes, b the bank) trained on the 0.5 C/min run (the paper's protocol),
- the same with a 2 C/min run added to the training logs (two ramp rates), lag-lstm on the
  lag bank (`--structure bank`, the previous default, "bank 1r" / "bank 2r"), with one
  effective node (`--structure node`, "node 1r" / "node 2r") and with two (`--structure
  node --nodes 2`, "2 nodes"),
- the oracle: least squares on the simulator's TRUE node temperatures with the simulator's
  own SF structure (source, coil mean and its square, inner coil, board), fitted on the
  0.5 C/min run: no model built on the board thermometer can know more,
and the rate-transfer spread of `training.interval.transfer` for both training sets: how much lag
models that fit the training data equally well disagree on the test log.

    python -m benchmarks.rate_transfer --out out/bench-transfer.json --seeds 8
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fogsf.logs.measure.metrics import log_metrics
from fogsf.models.features import step_targets
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.scenarios import paper
from fogsf.training.options import TrainOptions
from fogsf.training.train import run_training


def true_structure(r: SimResult) -> np.ndarray:
    """The simulator's SF structure on its true node temperatures (a linear design)."""
    n = r.nodes
    coil = 0.5 * (n["coil_inner"] + n["coil_outer"])
    cols = [n["source"], coil, coil * coil / 50.0, n["coil_inner"], n["board"]]
    return np.column_stack([np.ones_like(coil)] + [(c - 20.0) / 50.0 for c in cols])


def oracle_ratio(train: SimResult, test: SimResult) -> float:
    x = true_structure(train)
    coef, *_ = np.linalg.lstsq(x, step_targets(train.log, 1), rcond=None)
    m = log_metrics(test.log, correction_ppm=true_structure(test) @ coef)
    return m["rms_ppm"] / m["noise_floor_ppm"]


def lag_lstm(train_logs: list, test_log, seed: int, out: Path, nodes: int = 1,
             structure: str = "auto") -> dict:
    opts = TrainOptions(model="lag-lstm", seed=seed, nodes=nodes, progress=False,
                        structure="node" if nodes > 1 else structure)
    m, _ = run_training(opts, train_logs, test_log, out)
    after = m["test"]["after"]
    return {"ratio": after["rms_ppm"] / m["noise_floor_ppm"], "rms_ppm": after["rms_ppm"],
            "spread_median_ppm": m["rate_transfer"]["spread_median_ppm"],
            "spread_max_ppm": m["rate_transfer"]["spread_max_ppm"],
            "consistent": m["rate_transfer"]["consistent"],
            "chosen": m.get("structure_choice", {}).get("chosen", structure)}


def _short(structure: str) -> str:
    """physics2 -> p2, bank -> b: the chosen structure in three characters."""
    tail = structure[-1] if structure.startswith("physics") else ""
    return f"{structure[0] + tail:>3}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/bench-transfer.json")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=0)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    head = (f"{'seed':>4} {'floor':>6} | {'1 rate':>6} {'spread':>8} | {'2 rates':>7} "
            f"{'spread':>7} | {'chosen':>7} | {'bank 1r':>7} {'bank 2r':>7} | "
            f"{'node 1r':>7} {'node 2r':>7} | {'2 nodes':>7} | {'oracle':>6}")
    print("test RMS / noise floor on the 1 C/min run; spread: median ppm RMS between "
          "equally good lag models on it")
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            tr = simulate(paper(0.5, seed=1000 + seed))
            te = simulate(paper(1.0, seed=2000 + seed))
            fast = simulate(paper(2.0, seed=4000 + seed))
            one = lag_lstm([tr.log], te.log, seed, Path(tmp) / f"one{seed}")
            two = lag_lstm([tr.log, fast.log], te.log, seed, Path(tmp) / f"two{seed}")
            two2 = lag_lstm([tr.log, fast.log], te.log, seed, Path(tmp) / f"tt{seed}", nodes=2)
            n1 = lag_lstm([tr.log], te.log, seed, Path(tmp) / f"n1{seed}", structure="node")
            n2 = lag_lstm([tr.log, fast.log], te.log, seed, Path(tmp) / f"n2{seed}",
                          structure="node")
            b1 = lag_lstm([tr.log], te.log, seed, Path(tmp) / f"b1{seed}", structure="bank")
            b2 = lag_lstm([tr.log, fast.log], te.log, seed, Path(tmp) / f"b2{seed}",
                          structure="bank")
            floor = log_metrics(te.log)["noise_floor_ppm"]
            row = {"seed": seed, "noise_floor_ppm": floor, "one_rate": one, "two_rates": two,
                   "two_rates_two_nodes": two2, "one_rate_node": n1, "two_rates_node": n2,
                   "one_rate_bank": b1, "two_rates_bank": b2,
                   "oracle_one_rate_ratio": oracle_ratio(tr, te)}
            rows.append(row)
            print(f"{seed:>4} {floor:>6.2f} | {one['ratio']:>6.2f} "
                  f"{one['spread_median_ppm']:>8.1f} | {two['ratio']:>7.2f} "
                  f"{two['spread_median_ppm']:>7.1f} | {_short(one['chosen'])}/"
                  f"{_short(two['chosen'])} | {b1['ratio']:>7.2f} {b2['ratio']:>7.2f} | "
                  f"{n1['ratio']:>7.2f} {n2['ratio']:>7.2f} | "
                  f"{two2['ratio']:>7.2f} | "
                  f"{row['oracle_one_rate_ratio']:>6.2f}",
                  flush=True)
    summary = {k: {"mean": float(np.mean(v)), "max": float(np.max(v)),
                   "at_or_under_1.25": int(np.sum(np.asarray(v) <= 1.25))}
               for k, v in (("one_rate", [r["one_rate"]["ratio"] for r in rows]),
                            ("two_rates", [r["two_rates"]["ratio"] for r in rows]),
                            ("one_rate_bank", [r["one_rate_bank"]["ratio"] for r in rows]),
                            ("two_rates_bank", [r["two_rates_bank"]["ratio"] for r in rows]),
                            ("one_rate_node", [r["one_rate_node"]["ratio"] for r in rows]),
                            ("two_rates_node", [r["two_rates_node"]["ratio"] for r in rows]),
                            ("two_rates_two_nodes",
                             [r["two_rates_two_nodes"]["ratio"] for r in rows]),
                            ("oracle_one_rate", [r["oracle_one_rate_ratio"] for r in rows]))}
    for k, s in summary.items():
        print(f"{k:>20}: mean {s['mean']:.2f} x floor, worst {s['max']:.2f}, "
              f"{s['at_or_under_1.25']}/{len(rows)} seeds at or under 1.25 x")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "summary": summary,
                               "seconds": time.perf_counter() - t0}, indent=2) + "\n")
    print(f"-> {out} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
