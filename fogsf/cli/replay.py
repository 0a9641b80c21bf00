"""Run the compiled C kernel over a chamber log, sample by sample, as the gyro firmware would.

The model directory (from `fogsf train`) is exported to its C header and the kernel in
firmware/c is compiled for it (cached in build/kernels/<model id>-..., or $FOGSF_BUILD_DIR).
Every sample of the log (board temperature, raw gyro) goes through fogsf_step; the
output CSV holds time_s, gyro_dps, gyro_corrected_dps and sf_error_ppm (the kernel's
predicted SF error vs the nominal SF, held between model steps); with a model that has a
bias head, also bias_dph (its predicted bias, deg/h, held), and the corrected rate is
(gyro - bias) / (1 + SF error); `--out X.parquet` writes it as Parquet. The kernel runs over
the log in blocks, each written as it is produced, its state carried between them (the
output of one run). The SF-error metrics of the log before and after the
correction are printed (max|e|, p-p, RMS, STD, noise floor), and the bias's (deg/h) when
the model has a bias head and the log measures the bias (+/- pairs, or a stationary log).
A log at another sample rate than the model's training logs runs the model re-rated to it
(the same model step in seconds; `fogsf export --sample-rate-hz` gives that firmware).
The kernel starts from reset at the log's first sample, its lag states at that sample's
temperature: a log that starts while the temperature moves is said so, and --skip-s S
leaves its first S seconds out of the metrics (the kernel still runs over them).
A plateau table (docs/train.md, "Plateau tables") is corrected one row a plateau.
Examples:
  fogsf replay models/m run10.csv --out corrected.csv --plot replay.png  # train --help's files
  fogsf replay models/plat rig/table.csv --out corrected.csv
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.cli.arguments import (
    add_log_options,
    add_metric_options,
    positive_float,
    progress_bar,
    rated,
    read_logs,
)
from fogsf.cli.axes import run_all, wants_all
from fogsf.cli.plateau_commands import any_plateau_table, replay_table
from fogsf.errors import UserError
from fogsf.logs.corrected_out import CorrectedWriter
from fogsf.logs.measure.bias import before_after, bias_windows
from fogsf.logs.measure.metrics import (
    log_metrics,
    metrics_block,
    noise_floor_ppm,
    sf_error_ppm,
    start_note,
)
from fogsf.logs.measure.sf_reference import reference_sf, reference_temp_c
from fogsf.logs.measure.windows import sf_windows
from fogsf.logs.read.columns import Column, Spill, is_lazy, stand_in
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_NAMES


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL_DIR", help="model directory from `fogsf train`")
    parser.add_argument("log", metavar="LOG", help="chamber log, CSV or Parquet (format: "
                                                    "docs/logs.md)")
    parser.add_argument("--out", required=True, metavar="CSV|PARQUET",
                        help="corrected log: time_s,gyro_dps,gyro_corrected_dps,sf_error_ppm "
                             "(and bias_dph with a bias head); Parquet when it ends in .parquet")
    parser.add_argument("--plot", metavar="PNG", default=None,
                        help="before/after plot of the SF error (windows vs temperature, time)")
    add_metric_options(parser, skip=True)
    add_log_options(parser)
    parser.add_argument("--json", metavar="PATH", default=None,
                        help="also write the before/after metrics and flag counts as JSON")
    parser.add_argument("--ref-sf", type=positive_float, default=None, metavar="RATIO",
                        help="reference SF ratio (vs nominal) of the before-metrics instead "
                             "of the log's SF at 20 C (needed when the log never passes 20 C)")
    parser.add_argument("--cc", default="gcc", help="C compiler for the host kernel (gcc)")
    parser.add_argument("--build-dir", metavar="DIR", default=None,
                        help="where compiled kernels are cached (default: $FOGSF_BUILD_DIR, "
                             "build/kernels in a checkout, else ~/.cache/fogsf/kernels)")


REPLAY_BLOCK = 1 << 17  # samples the kernel runs (and replay writes) at a time


def write_corrected(path: str | Path, time_s: np.ndarray, gyro: np.ndarray,
                    corrected: np.ndarray, sf_ppm: np.ndarray,
                    bias_dph: np.ndarray | None = None) -> None:
    """The replay CSV (or Parquet, for a path ending in .parquet; logs/corrected_out.py):
    every number in its shortest form that reads back the same (sf_ppm and bias_dph as
    float32, the latter only for a model with a bias head)."""
    with CorrectedWriter(path, bias=bias_dph is not None) as w:
        for a in range(0, time_s.shape[0], REPLAY_BLOCK):
            b = a + REPLAY_BLOCK
            w.write(time_s[a:b], gyro[a:b], corrected[a:b], sf_ppm[a:b],
                    None if bias_dph is None else bias_dph[a:b])


def replay_blocks(kernel, log, path: str | Path, bias_head: bool  # noqa: ANN001
                  ) -> tuple[np.ndarray, np.ndarray | None, dict[str, int]]:
    """The kernel (a `Kernel`) over the log (a `ChamberLog`) from reset, REPLAY_BLOCK samples
    at a time (its state carried from block to block: the output of one run over the whole
    log), each block written to `path` as it is produced (bias_dph too with `bias_head`):
    (sf_ppm per sample, bias_dph per sample or None without a bias head, the flag counts)."""
    n = len(log)
    on_disk = is_lazy(log.time_s)  # a log on disk: its outputs go to disk too
    spill = Spill() if on_disk else None
    sf_out = spill.file("sf_ppm", np.float32) if spill else None
    bias_out = spill.file("bias_dph", np.float32) if spill and bias_head else None
    sf = None if on_disk else np.empty(n, np.float32)
    bias = None if on_disk or not bias_head else np.empty(n, np.float32)
    counts: dict[str, int] = {}
    logged = log.extra.get("logged")  # rows filled into gaps: run, not written
    st = kernel.new_state()
    tell = progress_bar("replay", "samples") if on_disk else None
    with CorrectedWriter(path, bias=bias_head) as w:
        for a in range(0, n, REPLAY_BLOCK):
            b = min(n, a + REPLAY_BLOCK)
            gyro = np.asarray(log.gyro_dps[a:b])
            corrected, block_sf, block_bias, flags = kernel.run_bias(
                np.asarray(log.temp_c[a:b]), gyro, st)
            if sf is not None:
                sf[a:b] = block_sf
            if bias is not None:
                bias[a:b] = block_bias
            if sf_out is not None:
                sf_out.append(block_sf)
            if bias_out is not None:
                bias_out.append(block_bias)
            keep = slice(None) if logged is None else np.asarray(logged[a:b]) != 0.0
            w.write(np.asarray(log.time_s[a:b])[keep], gyro[keep], corrected[keep],
                    block_sf[keep], block_bias[keep] if bias_head else None)
            for name, c in flag_counts(flags).items():
                counts[name] = counts.get(name, 0) + c
            if tell is not None:
                tell(b, n)
    if sf_out is not None:
        return (stand_in(sf_out.column()),
                None if bias_out is None else stand_in(bias_out.column()), counts)
    assert sf is not None  # in memory
    return sf, bias, counts


def drop_treatment(log, decimation: int) -> str | None:  # noqa: ANN001 - ChamberLog
    """How the kernel treated the log's irregular rows (None for a regular log): it runs on
    the rows as logged, as firmware would, counting samples, not seconds."""
    s = log.sampling
    if s is None or not s.irregular:
        return None
    parts = []
    if s.dropped or s.jittered:
        parts.append(f"the kernel ran on the rows as logged ({s.dropped} dropped samples, "
                     f"{s.jittered} steps off the nominal {s.nominal_s:.4g} s): it counts "
                     f"rows, {decimation} a model step, so a step with a dropped sample "
                     "spans that much more time and its lag states advance as if none were "
                     "missed (firmware does the same)")
    if s.filled_rows:
        parts.append(f"{s.filled_rows} rows filled into {len(s.gaps) + len(s.resets)} gaps "
                     f"(states {'carried' if s.gap_states == 'carry' else 'restarted'}; "
                     "--gap-states) ran through the kernel too; the output holds the "
                     "log's own rows")
    return "; ".join(parts)


def flag_counts(flags: np.ndarray) -> dict[str, int]:
    return {name: int(np.count_nonzero(flags & bit)) for bit, name in FLAG_NAMES.items()}


def run(args: argparse.Namespace) -> int:
    if wants_all(args):  # MODEL_DIR/A, --out NAME_A.csv (--json, --plot) per axis
        return run_all(args, run, "replay")
    if any_plateau_table(args, [args.log]):
        return replay_table(args)
    model = StreamModel.load(args.model)
    log = read_logs(args, [args.log], on_disk=True)[0]
    note = start_note(log, args.skip_s)
    if note:
        print(f"fogsf: {note}", file=sys.stderr)
    model = rated(model, log.sample_dt_s, f"the log's {log.sample_rate_hz:.6g} Hz")
    build = build_kernel(model, root=args.build_dir, cc=args.cc)
    kernel = Kernel(model, build)
    sf, bias, counts = replay_blocks(kernel, log, args.out, model.bias_head)
    print(f"kernel {build.shared} (model {model.model_id}, {model.layers}x{model.hidden} "
          f"LSTM, D={model.decimation})")
    print(f"replayed {len(log)} samples of {log.path}; wrote {args.out}")
    how = drop_treatment(log, model.decimation)
    if how:
        print(how)
    flagged = {k: v for k, v in counts.items() if v}
    print("flags: " + (", ".join(f"{k} {v}" for k, v in flagged.items()) if flagged
                       else "none"))
    before: dict[str, float] | None
    after: dict[str, float] | None
    ref_sf, about = args.ref_sf, ""
    try:
        span = {"settle_s": args.settle_s, "skip_s": args.skip_s}
        w = sf_windows(log, args.window_s, args.latitude_deg, **span)
        if ref_sf is None:  # the log's own SF at --ref-temp-c, or the nearest it holds
            ref_sf = reference_sf(w, log.ref_temp_c)
            about = (f"the log's SF at {reference_temp_c(w, log.ref_temp_c):.2f} C, ratio "
                     f"{ref_sf:.9f} vs nominal")
        else:
            about = f"--ref-sf {ref_sf:.9f}"
        before = metrics_block(sf_error_ppm(w, ref_sf), args.window_s, noise_floor_ppm(w))
        after = log_metrics(log, args.window_s, latitude_deg=args.latitude_deg,
                            correction_ppm=sf, **span)
    except UserError as e:  # e.g. a log whose windows measure nothing
        print(f"no before/after metrics: {e}")
        before = after = None
    if before is not None and after is not None:
        skipped = f", first {args.skip_s:g} s skipped" if args.skip_s else ""
        print(f"SF error, {args.window_s:g} s windows (settle {args.settle_s:g} s{skipped}; "
              f"before: about {about}; after: measured / predicted - 1):")
        for name, m in (("before", before), ("after", after)):
            print(f"  {name:6s} max|e| {m['max_abs_ppm']:8.2f}  p-p {m['pp_ppm']:8.2f}  "
                  f"RMS {m['rms_ppm']:8.2f}  STD {m['std_ppm']:8.2f} ppm")
        print(f"  noise floor {before['noise_floor_ppm']:.2f} ppm")
    bias_block = replay_bias(model, log, bias, sf, args) if bias is not None else None
    args.axis_result = {"model_id": model.model_id, "bias_only": model.model == "bias",
                        "out": args.out, "before": before,
                        "after": after, "flags": counts, "bias": bias_block}
    if args.json:
        Path(args.json).write_text(json.dumps({"model_id": model.model_id,
                                               "rated_from": model.extra.get("rated_from"),
                                               "sample_rate_hz": log.sample_rate_hz,
                                               "decimation": model.decimation,
                                               "samples": len(log),
                                               "window_s": args.window_s,
                                               "settle_s": args.settle_s,
                                               "skip_s": args.skip_s,
                                               "before": before, "after": after,
                                               "bias": bias_block,
                                               "flags": counts}, indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.plot and before is not None:
        plot(log, sf, args.window_s, args.latitude_deg, args.plot, model.model_id,
             args.ref_sf, args.settle_s, args.skip_s)
        print(f"plot: {args.plot}")
    return 0


def replay_bias(model, log, bias: np.ndarray, sf: Column,  # noqa: ANN001 - StreamModel, ChamberLog
                args: argparse.Namespace) -> dict | None:
    """The bias before/after (deg/h) over the log's bias windows (the replayed SF taken off
    the pairs' plateaus, as `train` measures them), printed; None when the log measures no
    bias."""
    w = bias_windows(log, args.window_s, args.latitude_deg, args.settle_s, args.skip_s,
                     sf_ppm=sf)
    if w is None:
        print("bias: the log measures no bias (no +/- pairs, the table turning)")
        return None
    b = before_after(w, bias.astype(np.float64))
    print(f"bias, {len(w)} windows ({w.source}; before: the measured bias; after: measured - "
          "predicted):")
    for name in ("before", "after"):
        m = b[name]
        print(f"  {name:6s} max|e| {m['max_abs_dph']:8.4f}  p-p {m['pp_dph']:8.4f}  "
              f"RMS {m['rms_dph']:8.4f}  STD {m['std_dph']:8.4f} deg/h")
    print(f"  noise floor {w.noise_floor_dph:.4f} deg/h")
    return b


def plot(log, sf: np.ndarray, window_s: float, latitude_deg: float | None,  # noqa: ANN001
         path: str, model_id: str, ref: float | None = None, settle_s: float = 2.0,
         skip_s: float = 0.0) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sf = np.asarray(sf)  # the plot draws every sample (a log on disk is read whole here)
    w = sf_windows(log, window_s, latitude_deg, settle_s=settle_s, skip_s=skip_s)
    ref = ref if ref is not None else reference_sf(w, log.ref_temp_c)
    before = sf_error_ppm(w, ref)
    after = sf_error_ppm(sf_windows(log, window_s, latitude_deg, sf.astype(np.float64),
                                    settle_s, skip_s), 1.0)
    predicted = ((1.0 + sf.astype(np.float64) * 1e-6) / ref - 1.0) * 1e6
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7.5))
    ax1.plot(w.temp_c, before, ".", ms=4, label="measured SF error (before)")
    ax1.plot(np.asarray(log.temp_c), predicted, "-", lw=0.8,
             label="C kernel prediction (every sample)")
    ax1.plot(w.temp_c, after, ".", ms=4, label="residual after correction")
    ax1.set_xlabel("board temperature [C]")
    ax1.set_ylabel("SF error [ppm] (about the SF at 20 C)")
    ax1.legend(loc="best", fontsize=8)
    ax1.grid(alpha=0.3)
    hours = w.t_s / 3600.0
    ax2.plot(hours, before, ".-", ms=3, lw=0.6, label="before")
    ax2.plot(hours, after, ".-", ms=3, lw=0.6, label="after (C kernel)")
    ax2.set_xlabel("time [h]")
    ax2.set_ylabel(f"SF error per {window_s:g} s window [ppm]")
    ax2.legend(loc="best", fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle(f"fogsf replay: {Path(log.path).name}, model {model_id}; RMS "
                 f"{np.sqrt(np.mean(before**2)):.1f} -> {np.sqrt(np.mean(after**2)):.1f} ppm")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
