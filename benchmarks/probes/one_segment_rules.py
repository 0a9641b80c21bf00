"""What the one-ramp structure rule could gain: protocol (a) of `benchmarks.population`
(trained on one 0.5 C/min ramp, tested at 1 C/min) on development gyros.

For each gyro it prints the held-out scores `structure_choice.choose` computes on the
training log (one ramp in three parts) and the test RMS, as a multiple of the test log's
noise floor, of each candidate fitted by least squares (`candidate_compensation`: no LSTM).
Then the median / p90 / worst over the gyros of: each candidate always; the rule (first in
an order within a tolerance of the best score) for both orders and several tolerances; and
the oracle, the candidate best on the test log (what perfect selection would reach).

    python -m benchmarks.probes.one_segment_rules --gyros 1:49
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from benchmarks.population import protocol_logs
from fogsf.logs.measure.metrics import log_metrics
from fogsf.sim.population import gyro_for_seed
from fogsf.training.structure.choice import CANDIDATES, choose
from fogsf.training.structure.heldout import candidate_compensation

TOLERANCES = (0.0, 0.1, 0.2, 0.3, 0.5)


def gyro_row(seed: int) -> dict:
    train, test = protocol_logs(gyro_for_seed(seed), seed, "a")
    choice = choose(train)
    ratios = {}
    for c in CANDIDATES:
        m = log_metrics(test, 100.0, correction_ppm=candidate_compensation(c, train)(test))
        ratios[c] = m["rms_ppm"] / m["noise_floor_ppm"]
    return {"gyro": seed, "scores": choice.scores, "chosen": choice.name, "ratios": ratios}


def by_rule(rows: list[dict], order: tuple[str, ...], tol: float) -> np.ndarray:
    """Each gyro's test ratio under the one-ramp rule (order, tolerance)."""
    out = []
    for r in rows:
        s = r["scores"]
        best = min(s.values())
        out.append(r["ratios"][next(c for c in order if s[c] <= (1.0 + tol) * best)])
    return np.asarray(out)


def _line(label: str, a: np.ndarray) -> str:
    return f"{label:28s} {np.median(a):6.2f} {np.percentile(a, 90):6.2f} {a.max():6.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="example: python -m benchmarks.probes.one_segment_rules "
                                        "--gyros 1:9")
    ap.add_argument("--gyros", default="1:49", help="development seeds LO:HI")
    ap.add_argument("--out", type=Path, default=Path("out/one-segment-rules.json"))
    args = ap.parse_args(argv)
    lo, hi = (int(v) for v in args.gyros.split(":"))
    rows = []
    for seed in range(lo, hi):
        r = gyro_row(seed)
        rows.append(r)
        print(seed, r["chosen"], {k: round(v, 1) for k, v in r["scores"].items()},
              {k: round(v, 2) for k, v in r["ratios"].items()}, flush=True)
    print(f"{'test RMS / noise floor':28s} {'median':>6s} {'p90':>6s} {'worst':>6s}")
    for c in CANDIDATES:
        print(_line(f"always {c}", np.array([r["ratios"][c] for r in rows])))
    bank_first = ("bank", *(c for c in CANDIDATES if c != "bank"))
    for order in (CANDIDATES, bank_first):
        for tol in TOLERANCES:
            print(_line(f"{order[0]} first, within {tol:.0%}", by_rule(rows, order, tol)))
    print(_line("oracle (best on the test)", np.array([min(r["ratios"].values())
                                                        for r in rows])))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
