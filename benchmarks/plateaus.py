"""fogsf's plateau model on evaluation gyros of the population, as open-loop FOGs (a sine
response whose phase scale moves with temperature) and as closed-loop FOGs (an SF
nonlinearity growing as a fractional power of |rate|, and an asymmetry), each on the rig of
`fogsf simulate --plateaus`: set points 36, 43, 50, 57 C, staircases to +-150 deg/s, 18 s
plateaus, means only.

Three splits per gyro: a held-out temperature band (the third set point's plateaus), the
last 30 % of a run, and every 5th plateau of another run of the same gyro (another noise
seed). Each is scored as RMS(corrected - rate sensed) on the held-out plateaus for fogsf
(`fit_plateau_model`, corrected by the float32 reference the kernel matches bit for bit),
for the best polynomial in rate (powers to the 9th) and temperature fitted to the same
training plateaus (the family's oracle: its form chosen by the held-out error itself), and
for the best linear SF (its temperature degree chosen the same way).

  python -m benchmarks.plateaus --gyros 20000:20010 --out out/bench-plateaus.json
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from fogsf.logs.measure.table_figures import temperature_groups
from fogsf.models.structures.rate_forms import TEMP_SCALE_C, RateForm, design, forms, solve
from fogsf.sim.population import gyro_for_seed
from fogsf.sim.rigs.plateau_tables import PlateauPlan, plateau_table, run_plateaus
from fogsf.training.rate.plateau_model import PlateauRows, fit_plateau_model
from fogsf.training.rate.plateau_train import correct_rows, rms_dph

KINDS = ("open-loop", "closed-loop")
SPLITS = ("band", "last30", "every5th")
OTHER_RUN = 5000  # the other run's noise seed: the gyro's seed plus this
TARGET_RATIO = 1.1


@dataclass(frozen=True)
class SplitScore:
    gyro: int
    kind: str
    split: str
    fogsf_dph: float
    oracle_dph: float
    linear_dph: float
    form: str
    oracle_form: str

    @property
    def ratio(self) -> float:
        return self.fogsf_dph / self.oracle_dph


def table_rows(gyro: int, kind: str, seed: int) -> tuple[PlateauRows, np.ndarray]:
    """(rows, each row's table rate) of one simulated run of the gyro."""
    cfg = gyro_for_seed(gyro, open_loop=kind == "open-loop",
                        rate_response=kind == "closed-loop")
    cfg.seed = seed
    t = plateau_table(run_plateaus(cfg, PlateauPlan()))
    c = t.columns
    return (PlateauRows(c["gyro_dps"], c["table_rate_dps"] + t.earth_rate_dps, c["temp_c"]),
            c["table_rate_dps"])


def _take(rows: PlateauRows, idx: np.ndarray) -> PlateauRows:
    return PlateauRows(rows.gyro_dps[idx], rows.rate_dps[idx], rows.temp_c[idx])


def oracle(train: PlateauRows, test: PlateauRows, linear: bool) -> tuple[float, RateForm]:
    """The best polynomial (or linear SF) fitted on `train`, chosen by its error on `test`."""
    fs = float(np.max(np.abs(train.rate_dps)))
    t_ref = float(np.mean(train.temp_c))
    best = (np.inf, RateForm(1, False, 0, 0))
    for f in forms():
        if f.abs_term or (linear and f.has_rate_part):
            continue
        coef = solve(design(train.gyro_dps / fs, (train.temp_c - t_ref) / TEMP_SCALE_C, f),
                     (train.rate_dps - train.gyro_dps) / fs)
        pred = test.gyro_dps + fs * (design(test.gyro_dps / fs, (test.temp_c - t_ref)
                                            / TEMP_SCALE_C, f) @ coef)
        best = min(best, (rms_dph(pred - test.rate_dps), f), key=lambda b: b[0])
    return best


def splits(run: PlateauRows, other: PlateauRows
           ) -> dict[str, tuple[PlateauRows, PlateauRows]]:
    n = len(run)
    groups = temperature_groups(run.temp_c)
    band = np.unique(groups)[-2]
    cut = int(round(0.7 * n))
    return {"band": (_take(run, np.flatnonzero(groups != band)),
                     _take(run, np.flatnonzero(groups == band))),
            "last30": (_take(run, np.arange(cut)), _take(run, np.arange(cut, n))),
            "every5th": (run, _take(other, np.arange(0, len(other), 5)))}


def score_gyro(gyro: int, kind: str) -> list[SplitScore]:
    run, _ = table_rows(gyro, kind, gyro)
    other, _ = table_rows(gyro, kind, gyro + OTHER_RUN)
    out = []
    for name, (train, test) in splits(run, other).items():
        fit = fit_plateau_model(train)
        corrected, _ = correct_rows(fit.model, test.temp_c, test.gyro_dps)
        best, best_form = oracle(train, test, linear=False)
        lin, _ = oracle(train, test, linear=True)
        out.append(SplitScore(gyro, kind, name, rms_dph(corrected - test.rate_dps), best, lin,
                              fit.form.describe(), best_form.describe()))
    return out


def summary(scores: list[SplitScore]) -> dict:
    out: dict = {}
    for kind in KINDS:
        for split in SPLITS:
            sel = [s for s in scores if s.kind == kind and s.split == split]
            if not sel:
                continue
            r = np.array([s.ratio for s in sel])
            out[f"{kind}/{split}"] = {
                "gyros": len(sel), "ratio_median": float(np.median(r)),
                "ratio_worst": float(r.max()),
                "fogsf_median_dph": float(np.median([s.fogsf_dph for s in sel])),
                "oracle_median_dph": float(np.median([s.oracle_dph for s in sel])),
                "linear_median_dph": float(np.median([s.linear_dph for s in sel])),
                "meets_target_median": bool(np.median(r) <= TARGET_RATIO)}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.plateaus", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gyros", default="20000:20010", help="population seeds LO:HI")
    p.add_argument("--out", type=Path, default=Path("out/bench-plateaus.json"))
    args = p.parse_args(argv)
    lo, hi = (int(x) for x in args.gyros.split(":"))
    scores: list[SplitScore] = []
    for gyro in range(lo, hi):
        for kind in KINDS:
            for s in score_gyro(gyro, kind):
                scores.append(s)
                print(f"gyro {gyro} {kind:11s} {s.split:8s} fogsf {s.fogsf_dph:8.2f}  oracle "
                      f"{s.oracle_dph:8.2f}  ratio {s.ratio:5.2f}  linear {s.linear_dph:9.1f} "
                      f"deg/h  [{s.form}]", flush=True)
    summ = summary(scores)
    seeds = ("evaluation" if lo >= 20000 else "development" if hi <= 10000 else "population")
    print(f"\n{seeds} gyros {lo}..{hi - 1}: fogsf / best polynomial on held-out plateaus "
          f"(target <= {TARGET_RATIO} at the median)")
    for key, v in summ.items():
        print(f"  {key:22s} median {v['ratio_median']:.2f}  worst {v['ratio_worst']:.2f}   "
              f"fogsf {v['fogsf_median_dph']:.2f}  oracle {v['oracle_median_dph']:.2f}  "
              f"linear SF {v['linear_median_dph']:.1f} deg/h")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"gyros": [lo, hi], "target_ratio": TARGET_RATIO,
                                    "summary": summ,
                                    "scores": [{**asdict(s), "ratio": s.ratio}
                                               for s in scores]}, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
