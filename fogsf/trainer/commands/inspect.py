"""fogsf inspect: a chamber log's summary and its SF-error metrics block.

The first thing to run on a new chamber log. The log is read with every check of the
format (a bad file is refused with its file, line and rule), then summarised: samples,
duration, board-temperature range, table rates, and the SF error about the SF at 20 C
(board thermometer) in windows of --window-s: max|e|, peak-to-peak, RMS (about the 20 C
reference) and STD (about the mean), beside the noise floor (what the gyro's own noise
leaves in one window).

Example:
  fogsf simulate --scenario paper --ramp-rate 1.0 --out run10.csv && fogsf inspect run10.csv
"""

from __future__ import annotations

import argparse
import json

from fogsf.trainer.commands import add_log_options, add_metric_options, positive_float, read_logs
from fogsf.trainer.commands.axes import run_all, wants_all
from fogsf.trainer.logs.chamber_log import ChamberLog, rate_text
from fogsf.trainer.logs.metrics import (
    log_metrics,
    noise_floor_ppm,
    plateaus,
    reference_sf,
    sf_error_ppm,
    sf_windows,
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", help="chamber log CSV (format: docs/logs.md)")
    parser.add_argument("--json", action="store_true",
                        help="print the summary as JSON (samples, duration_s, sample_rate_hz, "
                             "temp_range_c, table_rates_dps, metrics)")
    add_metric_options(parser)
    add_log_options(parser)
    parser.add_argument("--ref-sf", type=positive_float, default=None,
                        help="reference SF ratio (vs nominal) instead of the log's own at 20 C "
                             "(needed when the log never passes 20 C: take ref_sf_ratio from "
                             "`fogsf inspect --json` of a run of the same gyro that does)")
    parser.add_argument("--plot", metavar="PNG", default=None,
                        help="write a plot of the SF error vs board temperature and time")


def summary(log: ChamberLog, window_s: float, latitude_deg: float | None,
            ref: float | None) -> dict:
    rates = sorted({round(float(log.table_rate_dps[a]), 9)
                    for a, _ in plateaus(log.table_rate_dps, log.measures)})
    if ref is None:
        ref = reference_sf(sf_windows(log, window_s, latitude_deg))
    return {
        "samples": len(log),
        "duration_s": log.duration_s,
        "sample_rate_hz": log.sample_rate_hz,
        "temp_range_c": [float(log.temp_c.min()), float(log.temp_c.max())],
        "table_rates_dps": rates,
        "metrics": log_metrics(log, window_s, ref=ref, latitude_deg=latitude_deg),
        "ref_sf_ratio": ref,
    }


def run(args: argparse.Namespace) -> int:
    if wants_all(args):  # --plot NAME_A.png per axis, then one summary
        return run_all(args, run, "inspect")
    log = read_logs(args, [args.log])[0]
    s = summary(log, args.window_s, args.latitude_deg, args.ref_sf)
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        m = s["metrics"]
        lo, hi = s["temp_range_c"]
        rates = ", ".join(f"{r:+g}" for r in s["table_rates_dps"][:8])
        more = " ..." if len(s["table_rates_dps"]) > 8 else ""
        print(f"{log.path}: {s['samples']} samples, {s['duration_s']:.1f} s "
              f"({s['duration_s'] / 3600:.2f} h) at {rate_text(log.sample_dt_s)}")
        print(f"  board temperature {lo:.2f} .. {hi:.2f} C; table rates {rates}{more} deg/s")
        extra = [k for k in log.extra]
        if extra:
            print(f"  extra columns: {', '.join(extra)}")
        ref = "the given reference" if args.ref_sf is not None else "the SF at 20 C"
        print(f"  SF error about {ref}, {m['window_s']:g} s windows:")
        print(f"    max|e| {m['max_abs_ppm']:.2f} ppm   p-p {m['pp_ppm']:.2f} ppm   "
              f"RMS {m['rms_ppm']:.2f} ppm   STD {m['std_ppm']:.2f} ppm")
        print(f"    noise floor {m['noise_floor_ppm']:.2f} ppm (1 sigma of one window)")
        print(f"  reference SF ratio {s['ref_sf_ratio']:.9f} (vs nominal; --ref-sf)")
    if args.plot:
        plot(log, args.window_s, args.latitude_deg, args.ref_sf, args.plot)
        if not args.json:
            print(f"  plot: {args.plot}")
    args.axis_result = s  # the summary row of --axis all
    return 0


def plot(log: ChamberLog, window_s: float, latitude_deg: float | None, ref: float | None,
         path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w = sf_windows(log, window_s, latitude_deg)
    e = sf_error_ppm(w, ref if ref is not None else reference_sf(w))
    floor = noise_floor_ppm(w)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    a1.plot(w.temp_c, e, ".-", ms=3, lw=0.8)
    a1.set_xlabel("board temperature (C)")
    a1.set_ylabel("SF error (ppm)")
    a1.set_title(f"{log.path}: SF error vs temperature")
    a2.plot(w.t_s / 60.0, e, ".-", ms=3, lw=0.8)
    a2.fill_between(w.t_s / 60.0, -floor, floor, color="0.85", label=f"noise floor {floor:.1f}")
    a2.set_xlabel("time since power-on (min)")
    a2.set_ylabel("SF error (ppm)")
    a2.legend(loc="best")
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
