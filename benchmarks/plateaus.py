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
training plateaus (the family's oracle: its form chosen by the held-out error itself; every
form fogsf weighs but the |x| term), for the plain polynomial family's oracle (every power
of rate from x^2 to x^P, each coefficient of one degree Q in T, the rate terms' capped at
quadratic: the polynomial a person would fit, a weaker yardstick), and for the best linear SF (its
temperature degree chosen the same way).

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
from fogsf.models.rate_part import apply_rate, rate_coefficients
from fogsf.models.stream import StreamModel
from fogsf.models.stream_format import RATE_ARRAY
from fogsf.models.structures.rate_forms import (
    MAX_RATE_TEMP_DEGREE,
    TEMP_SCALE_C,
    RateForm,
    design,
    forms,
    solve,
)
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
    plain_dph: float  # the plain polynomial family's oracle
    form: str
    oracle_form: str
    f32_ppm_fs: float  # the float32 rate part against float64 arithmetic, max over x and T

    @property
    def ratio(self) -> float:
        return self.fogsf_dph / self.oracle_dph

    @property
    def ratio_plain(self) -> float:
        return self.fogsf_dph / self.plain_dph


def table_rows(gyro: int, kind: str, seed: int, noise_dph: float = 0.0
               ) -> tuple[PlateauRows, np.ndarray]:
    """(rows, each row's table rate) of one simulated run of the gyro; `noise_dph`: white
    noise of that RMS added to each plateau's mean output (a rig noisier than the sim's)."""
    cfg = gyro_for_seed(gyro, open_loop=kind == "open-loop",
                        rate_response=kind == "closed-loop")
    cfg.seed = seed
    t = plateau_table(run_plateaus(cfg, PlateauPlan()))
    c = t.columns
    gyro_dps = c["gyro_dps"] + np.random.default_rng([seed, 77]).normal(
        0.0, noise_dph / 3600.0, c["gyro_dps"].size) if noise_dph > 0 else c["gyro_dps"]
    return (PlateauRows(gyro_dps, c["table_rate_dps"] + t.earth_rate_dps, c["temp_c"]),
            c["table_rate_dps"])


def _take(rows: PlateauRows, idx: np.ndarray) -> PlateauRows:
    return PlateauRows(rows.gyro_dps[idx], rows.rate_dps[idx], rows.temp_c[idx])


def plain_form(f: RateForm) -> bool:
    """A plain polynomial: every power from x^2, each coefficient of one degree in T (the
    rate terms' capped at the family's MAX_RATE_TEMP_DEGREE), no |x| term; a linear SF of
    any degree in T among them."""
    r = min(f.temp_degree, MAX_RATE_TEMP_DEGREE) if f.has_rate_part else 0
    return not (f.odd or f.abs_term) and f.rate_temp_degree == r


def oracle(train: PlateauRows, test: PlateauRows, linear: bool, plain: bool = False
           ) -> tuple[float, RateForm]:
    """The best polynomial (or linear SF) fitted on `train`, chosen by its error on `test`:
    every candidate fogsf weighs but the |x| term (every power from x^2, or the odd ones);
    `plain`: the plain polynomials only (`plain_form`)."""
    fs = float(np.max(np.abs(train.rate_dps)))
    t_ref = float(np.mean(train.temp_c))
    best = (np.inf, RateForm(1, False, 0, 0))
    for f in forms():
        if f.abs_term or (linear and f.has_rate_part) or (plain and not plain_form(f)):
            continue
        coef = solve(design(train.gyro_dps / fs, (train.temp_c - t_ref) / TEMP_SCALE_C, f),
                     (train.rate_dps - train.gyro_dps) / fs)
        pred = test.gyro_dps + fs * (design(test.gyro_dps / fs, (test.temp_c - t_ref)
                                            / TEMP_SCALE_C, f) @ coef)
        best = min(best, (rms_dph(pred - test.rate_dps), f), key=lambda b: b[0])
    return best


def float32_error_ppm(model: StreamModel) -> float:
    """Max |out32 - (c - e64)| / FS in ppm over 2001 rates across +-FS and 21 temperatures
    across the model's range: the kernel's float32 evaluation of the rate part (its output's
    rounding included) against the same coefficients in float64 (0 without a part)."""
    if not model.has_rate_part:
        return 0.0
    fs = model.rate_fs_dps
    c = (np.linspace(-1.0, 1.0, 2001) * fs).astype(np.float32)
    w = np.asarray(model.weights[RATE_ARRAY], np.float64)
    worst = 0.0
    for s0 in np.linspace(model.t_min_c, model.t_max_c, 21) - model.t_ref_c:
        a32 = rate_coefficients(model, np.array([s0]))
        out, _ = apply_rate(model, c, np.repeat(a32, c.size, axis=0),
                            np.zeros(c.size, np.uint32))
        a = a32[0].astype(np.float64)  # the held coefficients as the kernel holds them
        x = c.astype(np.float64) / fs
        e64 = a[0] * np.abs(x) + sum(a[r] * x ** (r + 1) for r in range(1, w.shape[0]))
        worst = max(worst, float(np.max(np.abs(out - (c - e64)))) / fs * 1e6)
    return worst


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


def score_gyro(gyro: int, kind: str, noise_dph: float = 0.0) -> list[SplitScore]:
    run, _ = table_rows(gyro, kind, gyro, noise_dph)
    other, _ = table_rows(gyro, kind, gyro + OTHER_RUN, noise_dph)
    out = []
    for name, (train, test) in splits(run, other).items():
        fit = fit_plateau_model(train)
        corrected, _ = correct_rows(fit.model, test.temp_c, test.gyro_dps)
        best, best_form = oracle(train, test, linear=False)
        lin, _ = oracle(train, test, linear=True)
        plain, _ = oracle(train, test, linear=False, plain=True)
        out.append(SplitScore(gyro, kind, name, rms_dph(corrected - test.rate_dps), best, lin,
                              plain,
                              fit.form.describe(), best_form.describe(),
                              float32_error_ppm(fit.model)))
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
                "ratio_plain_median": float(np.median([s.ratio_plain for s in sel])),
                "ratio_plain_worst": float(max(s.ratio_plain for s in sel)),
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
    p.add_argument("--noise-dph", type=float, default=0.0,
                   help="white noise (deg/h RMS) added to each plateau's mean output")
    args = p.parse_args(argv)
    lo, hi = (int(x) for x in args.gyros.split(":"))
    scores: list[SplitScore] = []
    for gyro in range(lo, hi):
        for kind in KINDS:
            for s in score_gyro(gyro, kind, args.noise_dph):
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
              f"linear SF {v['linear_median_dph']:.1f} deg/h; against the plain family "
              f"{v['ratio_plain_median']:.2f} / {v['ratio_plain_worst']:.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"gyros": [lo, hi], "target_ratio": TARGET_RATIO,
                                    "summary": summ,
                                    "f32_ppm_fs_max": max(s.f32_ppm_fs for s in scores),
                                    "scores": [{**asdict(s), "ratio": s.ratio,
                                                "ratio_plain": s.ratio_plain}
                                               for s in scores]}, indent=2) + "\n")
    f32 = max(s.f32_ppm_fs for s in scores)
    print(f"  the float32 rate part against float64 arithmetic: at most {f32:.3f} ppm of full "
          "scale (its output's rounding included)")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
