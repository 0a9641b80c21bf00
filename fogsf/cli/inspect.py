"""fogsf inspect: a chamber log's summary and its SF-error metrics block.

The first thing to run on a new chamber log. The log is read with every check of the
format (a bad file is refused with its file, line and rule), then summarised: samples,
duration, board-temperature range, table rates, and the SF error about the SF at 20 C
(board thermometer) in windows of --window-s: max|e|, peak-to-peak, RMS (about the 20 C
reference) and STD (about the mean), beside the noise floor (what the gyro's own noise
leaves in one window). SF comes from plateaus of constant commanded table rate, each
after a settle margin (--settle-s); a log with +/- pairs (adjacent plateaus of opposite
sign and equal |rate|) shows the gyro's bias and its drift with temperature, a log with the
table stopped throughout (stationary, earth rate known) shows its bias (output - earth rate)
in windows of --window-s and no SF, and a
staircase (three or more |rates|) the SF per rate step, its nonlinearity and asymmetry
(IEEE Std 952). A log that starts while the temperature moves is said so (--skip-s).
A plateau table (a row per rate plateau: `layout = "plateaus"` in its column map) gives
the IEEE Std 952 figures per temperature group: SF, nonlinearity, asymmetry, bias.

Example:
  fogsf simulate --scenario paper --ramp-rate 1.0 --out run10.csv && fogsf inspect run10.csv
"""

from __future__ import annotations

import argparse
import json
import sys

from fogsf.cli.arguments import (
    add_log_options,
    add_metric_options,
    cosine_for,
    dialect_from_args,
    positive_float,
    read_logs,
)
from fogsf.cli.axes import run_all, wants_all
from fogsf.logs.chamber_log import ChamberLog, is_stationary, rate_text
from fogsf.logs.measure.bias import BiasWindows, bias_summary, bias_windows
from fogsf.logs.measure.metrics import (
    log_metrics,
    noise_floor_ppm,
    sf_error_ppm,
    start_note,
    start_ramp_c_per_min,
)
from fogsf.logs.measure.pairs import find_pairs, rate_steps
from fogsf.logs.measure.plateaus import DPS_TO_DPH, SETTLE_S, plateaus
from fogsf.logs.measure.sf_reference import reference_sf, reference_temp_c
from fogsf.logs.measure.table_figures import TEMP_GROUP_C, table_figures
from fogsf.logs.measure.windows import sf_windows
from fogsf.logs.plateau_table import PlateauTable, is_plateau_table, read_plateau_table
from fogsf.logs.read.columns import col_max, col_min


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", help="chamber log, CSV or Parquet, or a plateau table (format: "
                        "docs/logs.md)")
    parser.add_argument("--json", action="store_true",
                        help="print the summary as JSON (samples, duration_s, sample_rate_hz, "
                             "temp_range_c, table_rates_dps, metrics, settle_s, skip_s, "
                             "start_ramp_c_per_min, pairs, rate_steps, stationary, bias)")
    add_metric_options(parser, skip=True)
    add_log_options(parser)
    parser.add_argument("--ref-sf", type=positive_float, default=None,
                        help="reference SF ratio (vs nominal) instead of the log's own at 20 C "
                             "(needed when the log never passes 20 C: take ref_sf_ratio from "
                             "`fogsf inspect --json` of a run of the same gyro that does)")
    parser.add_argument("--plot", metavar="PNG", default=None,
                        help="write a plot of the SF error vs board temperature and time "
                             "(and of the bias, when the log measures it)")


def pairs_summary(log: ChamberLog, latitude_deg: float | None, settle_s: float
                  ) -> dict | None:
    """The +/- pairs' bias (deg/h), its spread and thermal drift; None without pairs."""
    pp = find_pairs(log, latitude_deg, settle_s)
    if pp is None:
        return None
    bias = pp.bias_dps * DPS_TO_DPH
    alone = sum(idx.size == 2 for idx, _ in pp.bias_weights)  # no neighbour at their rate
    return {"count": len(pp), "rates_dps": sorted({round(float(r), 6) for r in pp.rate_dps}),
            "without_neighbours": int(alone),
            "bias_dph": float(bias.mean()), "bias_std_dph": float(bias.std()),
            "bias_range_dph": [float(bias.min()), float(bias.max())],
            "bias_drift_dph_per_c": pp.bias_drift_dph_per_c(),
            "sf_ppm": float((pp.sf_ratio.mean() - 1.0) * 1e6)}


def stationary_summary(log: ChamberLog, window_s: float, latitude_deg: float | None,
                       skip_s: float = 0.0) -> dict:
    """A stationary log's summary: no SF figures (null), its bias."""
    w = bias_windows(log, window_s, latitude_deg, skip_s=skip_s)
    assert w is not None  # a stationary log always has windows (or refuses)
    return {
        "samples": len(log), "duration_s": log.duration_s,
        "sample_rate_hz": log.sample_rate_hz,
        "temp_range_c": [col_min(log.temp_c), col_max(log.temp_c)],
        "table_rates_dps": [], "metrics": None, "ref_sf_ratio": None, "ref_temp_c": None,
        "settle_s": None,
        "skip_s": skip_s, "start_ramp_c_per_min": start_ramp_c_per_min(log), "pairs": None,
        "rate_steps": None, "stationary": True, "bias": bias_summary(w),
        "sampling": sampling_summary(log),
    }


def sampling_summary(log: ChamberLog) -> dict | None:
    """How the rows lie in time (logs/read/sampling.py): the nominal rate, steps off it, dropped
    samples, gaps, resets and clock steps; None for a log made in memory."""
    s = log.sampling
    if s is None:
        return None
    return {"nominal_rate_hz": 1.0 / s.nominal_s, "steps": s.steps, "jittered": s.jittered,
            "dropped": s.dropped, "worst_step_s": s.worst_step_s, "gaps": len(s.gaps),
            "longest_gap_s": max((g for _, g in s.gaps), default=0.0), "resets": len(s.resets),
            "clock_steps": len(s.clock_steps), "filled_rows": s.filled_rows,
            "max_gap_s": s.max_gap_s, "gap_states": s.gap_states}


def summary(log: ChamberLog, window_s: float, latitude_deg: float | None,
            ref: float | None, settle_s: float = SETTLE_S, skip_s: float = 0.0) -> dict:
    if is_stationary(log):
        return stationary_summary(log, window_s, latitude_deg, skip_s)
    bias = bias_windows(log, window_s, latitude_deg, settle_s, skip_s)
    rates = sorted({round(float(log.table_rate_dps[a]), 9)
                    for a, _ in plateaus(log.table_rate_dps, log.measures)})
    ref_temp = None
    if ref is None:
        w = sf_windows(log, window_s, latitude_deg, settle_s=settle_s, skip_s=skip_s)
        ref, ref_temp = reference_sf(w, log.ref_temp_c), reference_temp_c(w, log.ref_temp_c)
    steps = rate_steps(log, latitude_deg, settle_s)
    return {
        "samples": len(log),
        "duration_s": log.duration_s,
        "sample_rate_hz": log.sample_rate_hz,
        "temp_range_c": [col_min(log.temp_c), col_max(log.temp_c)],
        "table_rates_dps": rates,
        "metrics": log_metrics(log, window_s, ref=ref, latitude_deg=latitude_deg,
                               settle_s=settle_s, skip_s=skip_s),
        "ref_sf_ratio": ref,
        "ref_temp_c": ref_temp,
        "settle_s": settle_s,
        "skip_s": skip_s,
        "start_ramp_c_per_min": start_ramp_c_per_min(log),
        "pairs": pairs_summary(log, latitude_deg, settle_s),
        "rate_steps": None if steps is None else steps.as_dict(),
        "stationary": False,
        "bias": None if bias is None else bias_summary(bias),
        "sampling": sampling_summary(log),
    }


def print_plateau_figures(s: dict) -> None:
    """The pairs' bias and the staircase's figures, when the log has them."""
    p = s["pairs"]
    if p is not None:
        drift = ("" if p["bias_drift_dph_per_c"] is None
                 else f", drift {p['bias_drift_dph_per_c']:+.4f} deg/h/C")
        lo, hi = p["bias_range_dph"]
        print(f"  bias from {p['count']} +/- pairs: {p['bias_dph']:+.4f} deg/h (std "
              f"{p['bias_std_dph']:.4f}, {lo:+.4f} .. {hi:+.4f}){drift}; taken off before SF")
        if 2 * p.get("without_neighbours", 0) > p["count"]:
            print(f"    {p['without_neighbours']} of them have no neighbour at their own rate "
                  "(a staircase): the SF moving between a pair's plateaus reads as bias here; "
                  "train and replay take the SF model's prediction off first")
    st = s["rate_steps"]
    if st is not None:
        print(f"  rate steps: SF nonlinearity {st['sf_nonlinearity_ppm_fs']:.1f} ppm of full "
              f"scale, asymmetry {st['sf_asymmetry_ppm']:+.1f} ppm (IEEE Std 952); bias "
              f"{st['bias_dph']:+.4f} deg/h (a +/- pair's bias holds asymmetry x rate / 2, "
              "this one does not)")
        print(f"    SF per rate step vs nominal, at {st['temp_c']:.1f} C board temperature:")
        for r, a, b in zip(st["rates_dps"], st["sf_pos_ppm"], st["sf_neg_ppm"], strict=True):
            pos = "   -   " if a is None else f"{a:+9.1f}"
            neg = "   -   " if b is None else f"{b:+9.1f}"
            print(f"    |rate| {r:8.3f} deg/s   SF+ {pos} ppm   SF- {neg} ppm")


def print_bias(b: dict) -> None:
    """The bias block: its figures, then a few windows over the log (time, T, bias)."""
    where = ("stationary log, output - earth rate" if b["source"] == "stationary"
             else "+/- pairs")
    drift = ("" if b["drift_dph_per_c"] is None
             else f", drift {b['drift_dph_per_c']:+.4f} deg/h/C")
    lo, hi = b["range_dph"]
    print(f"  bias ({where}), {b['count']} windows of {b['window_s']:g} s: mean "
          f"{b['bias_dph']:+.4f} deg/h, std {b['std_dph']:.4f}, {lo:+.4f} .. {hi:+.4f}"
          f"{drift}; noise floor {b['noise_floor_dph']:.4f} deg/h (1 sigma of one window)")
    print("    time (min)   board T (C)   bias (deg/h)")
    for r in b["series"]:
        print(f"    {r['t_s'] / 60.0:10.1f}   {r['temp_c']:11.2f}   {r['bias_dph']:+12.4f}")


def print_stationary(log: ChamberLog, s: dict) -> None:
    lo, hi = s["temp_range_c"]
    print(f"{log.path}: {s['samples']} samples, {s['duration_s']:.1f} s "
          f"({s['duration_s'] / 3600:.2f} h) at {rate_text(log.sample_dt_s)}")
    print(f"  board temperature {lo:.2f} .. {hi:.2f} C; the table stopped throughout: "
          "the log measures the bias, not the SF")
    print_bias(s["bias"])


def run(args: argparse.Namespace) -> int:
    if wants_all(args):  # --plot NAME_A.png per axis, then one summary
        return run_all(args, run, "inspect")
    if is_plateau_table(args.log, dialect_from_args(args)):
        return run_table(args)
    log = read_logs(args, [args.log], on_disk=True)[0]
    s = summary(log, args.window_s, args.latitude_deg, args.ref_sf, args.settle_s, args.skip_s)
    note = start_note(log, args.skip_s)  # after the summary: a refused log is one line
    if note:
        print(f"fogsf: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(s, indent=2))
    elif s["stationary"]:
        print_stationary(log, s)
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
        ref = ("the given reference" if args.ref_sf is not None
               else f"the SF at {s['ref_temp_c']:.4g} C")
        print(f"  SF error about {ref}, {m['window_s']:g} s windows (settle "
              f"{s['settle_s']:g} s{f', first {args.skip_s:g} s skipped' if args.skip_s else ''}):")
        print(f"    max|e| {m['max_abs_ppm']:.2f} ppm   p-p {m['pp_ppm']:.2f} ppm   "
              f"RMS {m['rms_ppm']:.2f} ppm   STD {m['std_ppm']:.2f} ppm")
        print(f"    noise floor {m['noise_floor_ppm']:.2f} ppm (1 sigma of one window)")
        print(f"  reference SF ratio {s['ref_sf_ratio']:.9f} (vs nominal; --ref-sf)")
        print_plateau_figures(s)
        if s["bias"] is not None:
            print_bias(s["bias"])
    if args.plot:
        plot(log, args.window_s, args.latitude_deg, args.ref_sf, args.plot, args.settle_s,
             args.skip_s)
        if not args.json:
            print(f"  plot: {args.plot}")
    args.axis_result = s  # the summary row of --axis all
    return 0


def plot(log: ChamberLog, window_s: float, latitude_deg: float | None, ref: float | None,
         path: str, settle_s: float = SETTLE_S, skip_s: float = 0.0) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bias = bias_windows(log, window_s, latitude_deg, settle_s, skip_s)
    if is_stationary(log):
        fig, axes = plt.subplots(1, 2, figsize=(11, 4), squeeze=False)
        assert bias is not None
        plot_bias(axes[0], bias, log.path)
    else:
        fig, axes = plt.subplots(2 if bias is not None else 1, 2, figsize=(11, 8 if bias
                                                                           else 4),
                                 squeeze=False)
        plot_sf(axes[0], log, window_s, latitude_deg, ref, settle_s, skip_s)
        if bias is not None:
            plot_bias(axes[1], bias, log.path)
    for a in axes.ravel():
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_bias(row, w: BiasWindows, name: str) -> None:  # noqa: ANN001 - matplotlib axes
    """The bias windows vs board temperature and time, with the noise floor."""
    a1, a2 = row
    a1.plot(w.temp_c, w.bias_dph, ".-", ms=3, lw=0.8)
    a1.set_xlabel("board temperature (C)")
    a1.set_ylabel("bias (deg/h)")
    a1.set_title(f"{name}: bias vs temperature ({w.source})")
    t_min = (w.t_s - w.t0_s) / 60.0
    a2.plot(t_min, w.bias_dph, ".-", ms=3, lw=0.8)
    m, floor = float(w.bias_dph.mean()), w.noise_floor_dph
    if floor == floor:  # not NaN
        a2.fill_between(t_min, m - floor, m + floor, color="0.85",
                        label=f"mean +/- noise floor {floor:.3f}")
        a2.legend(loc="best")
    a2.set_xlabel("time since the log's first sample (min)")
    a2.set_ylabel("bias (deg/h)")


def plot_sf(row, log: ChamberLog, window_s: float,  # noqa: ANN001 - matplotlib axes
            latitude_deg: float | None, ref: float | None, settle_s: float,
            skip_s: float) -> None:
    w = sf_windows(log, window_s, latitude_deg, settle_s=settle_s, skip_s=skip_s)
    e = sf_error_ppm(w, ref if ref is not None else reference_sf(w, log.ref_temp_c))
    floor = noise_floor_ppm(w)
    a1, a2 = row
    a1.plot(w.temp_c, e, ".-", ms=3, lw=0.8)
    a1.set_xlabel("board temperature (C)")
    a1.set_ylabel("SF error (ppm)")
    a1.set_title(f"{log.path}: SF error vs temperature")
    t_min = (w.t_s - log.time_s[0]) / 60.0  # an epoch time base reads from the log's start
    a2.plot(t_min, e, ".-", ms=3, lw=0.8)
    a2.fill_between(t_min, -floor, floor, color="0.85", label=f"noise floor {floor:.1f}")
    a2.set_xlabel("time since the log's first sample (min)")
    a2.set_ylabel("SF error (ppm)")
    a2.legend(loc="best")


def table_summary(table: PlateauTable, latitude_deg: float | None, cosine: float) -> dict:
    """A plateau table's summary: its rows and times, and its IEEE Std 952 figures."""
    keep = table.measures
    m = (table.gyro_dps - table.earth(latitude_deg, cosine))[keep]
    r, temp = table.table_rate_dps[keep], table.temp_c[keep]
    return {"plateau_table": True, "plateaus": len(table), "measuring": int(keep.sum()),
            "bias_plateaus": int((r == 0.0).sum()),
            "duration_s": float(table.time_s[-1] + table.duration_s[-1] - table.time_s[0]),
            "time_from": table.time_from,
            "temp_range_c": [float(temp.min()), float(temp.max())],
            "figures": table_figures(r, m, temp).as_dict()}


def _ppm(x: float | None, fmt: str) -> str:
    return f"{'-':>{len(format(0.0, fmt))}}" if x is None else format(x, fmt)


def print_table(table: PlateauTable, s: dict) -> None:
    """The table's rows, then the figures: the whole table's fit, a row per group."""
    lo, hi = s["temp_range_c"]
    f = s["figures"]
    rates = f["rates_dps"]
    print(f"{table.path}: plateau table, {s['plateaus']} plateaus ({s['bias_plateaus']} at "
          f"0 deg/s), {s['duration_s']:.1f} s ({s['duration_s'] / 3600:.2f} h; times from "
          f"{s['time_from']})")
    print(f"  board temperature {lo:.2f} .. {hi:.2f} C in {len(f['groups'])} groups (rows "
          f"within {TEMP_GROUP_C:g} C); table rates {rates[0]:+g} .. {rates[-1]:+g} deg/s, "
          f"{len(rates)} rates")
    o = f["overall"]
    if o is not None:
        print(f"  all plateaus (SF and bias as polynomials of temperature): SF "
              f"{o['sf_ppm']:+.1f} ppm vs nominal at {o['temp_c']:.1f} C, nonlinearity "
              f"{o['sf_nonlinearity_ppm_fs']:.1f} ppm of full scale, asymmetry "
              f"{o['sf_asymmetry_ppm']:+.1f} ppm, bias {o['bias_dph']:+.4f} deg/h")
    print("  per temperature group (IEEE Std 952; SF vs nominal):")
    print("      T (C)   plateaus     SF (ppm)   nonlin (ppm FS)   asym (ppm)   bias (deg/h)")
    for g in f["groups"]:
        print(f"    {g['temp_c']:7.2f}   {g['plateaus']:8d}   {_ppm(g['sf_ppm'], '+10.1f')}"
              f"   {_ppm(g['sf_nonlinearity_ppm_fs'], '15.1f')}"
              f"   {_ppm(g['sf_asymmetry_ppm'], '+10.1f')}   {_ppm(g['bias_dph'], '+12.4f')}")
    drift = [f"SF {f['sf_drift_ppm_per_c']:+.3f} ppm/C" if f["sf_drift_ppm_per_c"] is not None
             else "", f"bias {f['bias_drift_dph_per_c']:+.4f} deg/h/C"
             if f["bias_drift_dph_per_c"] is not None else ""]
    if any(drift):
        print(f"  drift with temperature (a line through the groups): "
              f"{', '.join(d for d in drift if d)}")


def run_table(args: argparse.Namespace) -> int:
    """`fogsf inspect` on a plateau table: its figures; the sample log's options that have
    no meaning for one (--plot, --ref-sf) are said unused on stderr."""
    table = read_plateau_table(args.log, dialect_from_args(args))
    if table.read_notes:
        print(f"fogsf: read {table.path}: {'; '.join(table.read_notes)}", file=sys.stderr)
    unused = [o for o, v in (("--plot", args.plot), ("--ref-sf", args.ref_sf)) if v]
    if unused:
        print(f"fogsf: {' and '.join(unused)} not used: a plateau table", file=sys.stderr)
    s = table_summary(table, args.latitude_deg,
                      cosine_for(getattr(args, "axis_cosine", None), args.axis))
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        print_table(table, s)
    args.axis_result = s
    return 0
