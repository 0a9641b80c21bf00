"""The bias target's oracle: the true bias law (the gyro's own coil node, its true
temperature and rate of change: no time constant to identify) with only its linear
coefficients fitted to the same noisy training windows as `bias_eval`, scored the same way
on the test loop. What it leaves is the estimation variance of the linear coefficients
alone: a lower bound on what any structure fitted to those windows can reach.

The true regressors are the simulator's truth of the same run with one term of the bias
law at a time (bias 0, one coefficient 1): (T_coil - ref), its square and cube, and
dT_coil/dt in C/min, each averaged over the windows.

A second oracle, `board`, knows the true time constants but not the coil's temperature:
where the coil and the board sit behind the same node (the housing), the coil is
reconstructed from the logged board temperature B with the true tau_board and tau_coil
(housing = B + tau_board dB/dt, dB/dt from a 20 s lag; coil = lag(housing, tau_coil)),
and the same four regressors' linear coefficients are fitted.

  python -m benchmarks.bias_oracle --gyros 1:9
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.bias_eval import CASES, SHUPE, TEST_LOOP, TRAIN_LOOP, bias_law, protocol
from fogsf.logs.logio import read_log, with_mapping_beside
from fogsf.logs.measure.bias import bias_windows
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.config import BiasConfig
from fogsf.sim.lag import first_order_lag
from fogsf.sim.population import gyro_for_seed
from fogsf.sim.rigs import rig_logs

FAST_S = 20.0  # the board derivative's lag (board oracle)
BASIS = ("lin_dph_per_c", "quad_dph_per_c2", "cube_dph_per_c3", "shupe_dph_per_c_per_min")


def _board_regressors(log, bias: BiasConfig, gyro: int) -> np.ndarray | None:  # noqa: ANN001
    """(T_coil - ref), its square and cube, dT_coil/dt (C/min) from the logged board
    temperature and the true time constants; None where the coil is not the board's
    sibling."""
    nodes = {n.name: n for n in gyro_for_seed(gyro).thermal.nodes}
    board, coil = nodes.get("board"), nodes.get(bias.node)
    if board is None or coil is None or board.parent != coil.parent:
        return None
    b = np.asarray(log.temp_c, dtype=np.float64)
    dt = float(np.median(np.diff(log.time_s)))
    db = (b - first_order_lag(b, FAST_S, dt, float(b[0]))) / FAST_S
    h = b + board.tau_s * db
    c = first_order_lag(h, coil.tau_s, dt, float(h[0]))
    x = c - bias.ref_c
    return np.column_stack([x, x * x, x ** 3, (h - c) / coil.tau_s * 60.0])


def one(gyro: int, kind: str, shupe: float | None, work: Path) -> dict:
    bias = bias_law(gyro, shupe)
    x, y, true, xb = [], [], [], []
    for name, loop, seed in (("train", TRAIN_LOOP, 1), ("test", TEST_LOOP, 2)):
        rl = rig_logs.rig_log("plain", work / f"{gyro}-{kind}-{name}" / "log.csv",
                              protocol(kind, loop, replace(bias)), (gyro,), seed=seed)
        log = read_log(rl.path, with_mapping_beside(rl.path, Dialect()))
        ws = bias_windows(log, 100.0)
        assert ws is not None
        br = _board_regressors(log, bias, gyro)
        xb.append(None if br is None else np.column_stack([ws.mean_of(br[:, j])
                                                           for j in range(4)]))
        cols = []
        for term in BASIS:
            b = BiasConfig(**{**bias.__dict__, "bias_dph": 0.0, "lin_dph_per_c": 0.0,
                              "quad_dph_per_c2": 0.0, "cube_dph_per_c3": 0.0,
                              "shupe_dph_per_c_per_min": 0.0, term: 1.0})
            rb = rig_logs.rig_log("plain", work / f"{gyro}-{kind}-{name}-{term}" / "log.csv",
                                  protocol(kind, loop, b), (gyro,), seed=seed)
            cols.append(ws.mean_of(rb.truth[""].bias_dph))
        x.append(np.column_stack(cols))
        y.append(ws.bias_dph)
        true.append(ws.mean_of(rl.truth[""].bias_dph))
    used = [j for j, term in enumerate(BASIS) if getattr(bias, term) != 0.0]
    a = np.column_stack([np.ones(len(y[0])), x[0][:, used]])
    coef = np.linalg.lstsq(a, y[0], rcond=None)[0]
    pred = np.column_stack([np.ones(len(y[1])), x[1][:, used]]) @ coef
    err = float(np.std(pred - true[1]))
    err_board = None
    if xb[0] is not None and xb[1] is not None:
        ab = np.column_stack([np.ones(len(y[0])), xb[0][:, used]])
        cb = np.linalg.lstsq(ab, y[0], rcond=None)[0]
        pb = np.column_stack([np.ones(len(y[1])), xb[1][:, used]]) @ cb
        err_board = float(np.std(pb - true[1]))
    # the law itself reproduces the truth (a check of the basis)
    law = np.column_stack([np.ones(len(y[1])), x[1][:, used]]) @ np.array(
        [0.0, *[getattr(bias, BASIS[j]) for j in used]])
    rel, floor = (0.05, 0.1) if kind == "reversals" else (0.10, 0.2)
    target = max(floor, rel * float(np.std(true[1])))
    train_noise = float(np.std(y[0] - true[0]))
    return {"gyro": gyro, "protocol": kind, "terms": [BASIS[j] for j in used],
            "train_windows": len(y[0]), "train_noise_std_dph": train_noise,
            "law_check_std_dph": float(np.std(law - true[1])),
            "oracle_err_std_dph": err, "board_oracle_err_std_dph": err_board,
            "true_std_dph": float(np.std(true[1])),
            "target_dph": target, "oracle_meets": err <= target}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bias_oracle", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: python -m benchmarks.bias_oracle --gyros 1:17")
    p.add_argument("--gyros", default="1:9", help="population seeds LO:HI (development)")
    p.add_argument("--cases", default="shupe,population",
                   help="comma-separated, of: " + ", ".join(CASES))
    p.add_argument("--out", type=Path, default=Path("out/bias-oracle.json"))
    args = p.parse_args(argv)
    lo, hi = (int(v) for v in args.gyros.split(":"))
    bad = [c for c in args.cases.split(",") if c not in CASES]
    if bad:
        p.error(f"unknown case {bad[0]!r}; cases are {', '.join(CASES)}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for gyro in range(lo, hi):
            for kind in ("reversals", "stationary"):
                for case in args.cases.split(","):
                    r = one(gyro, kind, SHUPE.get(case) if case in SHUPE else None,
                            Path(tmp))
                    r["case"] = case
                    rows.append(r)
                    print(f"gyro {gyro} {kind:10s} {case:10s} oracle {r['oracle_err_std_dph']:.3f}"
                          f" board {r['board_oracle_err_std_dph'] or float('nan'):.3f}"
                          f" target {r['target_dph']:.3f} "
                          f"{'ok' if r['oracle_meets'] else 'MISS'}  train noise "
                          f"{r['train_noise_std_dph']:.3f} ({r['train_windows']} windows)  "
                          f"law check {r['law_check_std_dph']:.4f}", flush=True)
    for kind in ("reversals", "stationary"):
        for case in args.cases.split(","):
            sel = [r for r in rows if r["protocol"] == kind and r["case"] == case]
            e = np.array([r["oracle_err_std_dph"] for r in sel])
            eb = np.array([r["board_oracle_err_std_dph"] for r in sel
                           if r["board_oracle_err_std_dph"] is not None])
            tb = np.array([r["target_dph"] for r in sel
                           if r["board_oracle_err_std_dph"] is not None])
            if eb.size:
                print(f"{kind}/{case}: board oracle median {np.median(eb):.3f} (max "
                      f"{eb.max():.3f}) deg/h on {eb.size} gyros, meets target "
                      f"{int(np.sum(eb <= tb))}/{eb.size}")
            print(f"{kind}/{case}: oracle median {np.median(e):.3f} (max {e.max():.3f}) deg/h, "
                  f"meets target {sum(r['oracle_meets'] for r in sel)}/{len(sel)}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"gyros": [lo, hi], "rows": rows}, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
