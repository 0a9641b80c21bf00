"""How far the reversal pairs of a training loop pin the bias's Shupe term: the lead
structure's consistent set.

`make bench-bias`'s "reversals, Shupe term" row misses its target on most gyros, and the
board oracle (`benchmarks.bias_oracle`) meets it with the coil's true time constants. This
probe asks whether the training loop's pairs hold those time constants: the `lead`
structure's least-squares profile over its grid (the coil's time constant x the lead-lag
weight, `bias_structure.LEAD_TAU_GRID_S` x `LEAD_W_GRID`) on the training loop's pairs, the
grid points whose SSE lies within the 95 % allowance of a two-parameter profile (SSE_min +
5.99 s^2, s^2 = SSE_min / (n - 5); the interval's `lead_set` takes the same allowance on the
long-run-widened noise, so its region is at least as wide), and the test loop's error
std(predicted - true bias) of the bias model trained at each of them (the same `fit_bias`
path as the bench, `lead` fixed at that point). Where the consistent points' test errors
spread across the target, the training pairs cannot tell a model that meets it from one that
misses it: no rule on those pairs can; where they all lie under it, the choice within the
set is free. Also the point nearest the true (tau_coil, w = tau_board / tau_coil), where the
coil and the board sit behind the housing, and whether it is in the set.

    python -m benchmarks.probes.bias_consistent --gyros 1:13 --loops slow,fast
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.bias_eval import FAST_TRAIN_LOOP, SHUPE, TEST_LOOP, TRAIN_LOOP, bias_law, protocol
from benchmarks.probes import finish
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.logio import read_log, with_mapping_beside
from fogsf.logs.measure.bias import BiasWindows, bias_windows
from fogsf.logs.read.dialect import Dialect
from fogsf.sim.population import gyro_for_seed
from fogsf.sim.rigs import rig_logs
from fogsf.training.bias import structure as bs
from fogsf.training.bias.features import FeatureMap, bank_feature_map
from fogsf.training.bias.fit import fit_bias

LOOPS = {"slow": TRAIN_LOOP, "fast": FAST_TRAIN_LOOP}
MAX_POINTS = 40  # consistent points refitted per gyro (evenly by SSE rank)


def true_point(gyro: int, node: str) -> tuple[float, float] | None:
    """(tau_coil, w = tau_board / tau_coil) where the coil and the board share a parent."""
    nodes = {n.name: n for n in gyro_for_seed(gyro).thermal.nodes}
    board, coil = nodes.get("board"), nodes.get(node)
    if board is None or coil is None or board.parent != coil.parent:
        return None
    return coil.tau_s, board.tau_s / coil.tau_s


def profile(fm: FeatureMap, train: ChamberLog) -> tuple[np.ndarray, int]:
    """The lead profile's SSE over the grid [tau, w] on the training pairs (the fit on all
    targets, as `_fit_lead` computes it) and the number of targets."""
    seen: dict[str, object] = {}
    orig = bs._fit_lead

    def recording(cols: bs.Columns, rows: np.ndarray, y: np.ndarray) -> bs.CandidateFit:
        if rows.size >= int(seen.get("n", 0)):  # the fit on every target, not a fold's
            seen.update(n=rows.size, sse=bs.lead_profile(cols, rows, y))
        return orig(cols, rows, y)

    bs._fit_lead = recording
    try:
        fit_bias(fm, [train], candidates=("lead",))
    finally:
        bs._fit_lead = orig
    if "sse" not in seen:
        raise SystemExit("the bias model did not fit lead on these logs")
    return seen["sse"], int(seen["n"])  # type: ignore[return-value]


def error_at(fm: FeatureMap, train: ChamberLog, test: ChamberLog, ws: BiasWindows,
             true: np.ndarray, tc: float, w: float) -> float:
    """The test loop's std(predicted - true) of the bias model with lead fixed at (tc, w)."""
    grid = bs.LEAD_TAU_GRID_S, bs.LEAD_W_GRID
    bs.LEAD_TAU_GRID_S, bs.LEAD_W_GRID = (tc,), (w,)
    try:
        model = fit_bias(fm, [train], candidates=("lead",))
    finally:
        bs.LEAD_TAU_GRID_S, bs.LEAD_W_GRID = grid
    assert model is not None
    return float(np.std(ws.mean_of(model.predict(test)) - true))


def one(gyro: int, loop: str, work: Path) -> dict:
    bias = bias_law(gyro, SHUPE["shupe"])
    logs, truth = [], []
    for name, lp, seed in (("train", LOOPS[loop], 1), ("test", TEST_LOOP, 2)):
        rl = rig_logs.rig_log("plain", work / f"{gyro}-{loop}-{name}" / "log.csv",
                              protocol("reversals", lp, replace(bias)), (gyro,), seed=seed)
        logs.append(read_log(rl.path, with_mapping_beside(rl.path, Dialect())))
        truth.append(rl.truth[""].bias_dph)
    train, test = logs
    ws = bias_windows(test, 100.0)
    assert ws is not None
    true = ws.mean_of(truth[1])
    target = max(0.1, 0.05 * float(np.std(true)))
    fm = bank_feature_map([train], 5.0)
    sse, n = profile(fm, train)
    s2 = float(sse.min()) / max(n - 5, 1)
    ok = bs.lead_allowed(sse, s2)
    pick = ok[np.unique(np.linspace(0, len(ok) - 1, min(MAX_POINTS, len(ok))).astype(int))]
    taus, ws_grid = np.asarray(bs.LEAD_TAU_GRID_S), np.asarray(bs.LEAD_W_GRID)
    errs = np.array([error_at(fm, train, test, ws, true, float(taus[i]), float(ws_grid[j]))
                     for i, j in pick])
    row = {"gyro": gyro, "loop": loop, "targets": n, "target_dph": target,
           "consistent": int(len(ok)), "refitted": int(len(pick)),
           "tau_range_s": [float(taus[ok[:, 0]].min()), float(taus[ok[:, 0]].max())],
           "w_range": [float(ws_grid[ok[:, 1]].min()), float(ws_grid[ok[:, 1]].max())],
           "err_best_dph": float(errs[0]), "err_min_dph": float(errs.min()),
           "err_median_dph": float(np.median(errs)), "err_max_dph": float(errs.max()),
           "share_meeting": float(np.mean(errs <= target))}
    tp = true_point(gyro, bias.node)
    if tp is not None:
        i = int(np.argmin(np.abs(np.log(taus / tp[0]))))
        j = int(np.argmin(np.abs(ws_grid - tp[1])))
        row.update(true_tau_s=tp[0], true_w=tp[1],
                   true_in_set=bool(np.all(ok == (i, j), axis=1).any()),
                   true_delta_sse_s2=float((sse[i, j] - sse.min()) / s2),
                   err_true_dph=error_at(fm, train, test, ws, true, float(taus[i]),
                                         float(ws_grid[j])))
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.probes.bias_consistent",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gyros", default="1:13", help="population seeds LO:HI")
    p.add_argument("--loops", default="slow,fast",
                   help="training loops: slow (1 up, 0.7 down), fast (1 up, 2 down)")
    p.add_argument("--out", default=None, help="rows as JSON")
    args = p.parse_args(argv)
    lo, hi = (int(v) for v in args.gyros.split(":"))
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for loop in args.loops.split(","):
            for gyro in range(lo, hi):
                r = one(gyro, loop, Path(tmp))
                rows.append(r)
                tru = (f" true ({r['true_tau_s']:.0f} s, w {r['true_w']:.2f}) "
                       f"{'in' if r['true_in_set'] else 'OUT'} dSSE {r['true_delta_sse_s2']:.1f}"
                       f" s^2 err {r['err_true_dph']:.3f}" if "true_tau_s" in r else "")
                print(f"{loop} gyro {gyro}: {r['consistent']} consistent (tau "
                      f"{r['tau_range_s'][0]:.0f}-{r['tau_range_s'][1]:.0f} s, w "
                      f"{r['w_range'][0]:.1f}-{r['w_range'][1]:.1f}); test err best "
                      f"{r['err_best_dph']:.3f}, set {r['err_min_dph']:.3f} / "
                      f"{r['err_median_dph']:.3f} / {r['err_max_dph']:.3f} (min / median / "
                      f"max), target {r['target_dph']:.3f}, {100 * r['share_meeting']:.0f} % "
                      f"of the set meet it{tru}", flush=True)
        for loop in args.loops.split(","):
            sel = [r for r in rows if r["loop"] == loop]
            med = [r["err_median_dph"] for r in sel]
            print(f"{loop}: {len(sel)} gyros; the set's median error {np.median(med):.3f} "
                  f"deg/h (median over gyros); best point meets the target on "
                  f"{sum(r['err_best_dph'] <= r['target_dph'] for r in sel)}, every point of "
                  f"the set on {sum(r['err_max_dph'] <= r['target_dph'] for r in sel)}, no "
                  f"point on {sum(r['err_min_dph'] > r['target_dph'] for r in sel)}; the truth "
                  f"in the set on {sum(bool(r.get('true_in_set')) for r in sel)} of "
                  f"{sum('true_in_set' in r for r in sel)}")
    return finish(rows, args.out, t0)


if __name__ == "__main__":
    raise SystemExit(main())
