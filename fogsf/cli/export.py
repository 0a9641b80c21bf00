"""Export a trained streaming model to ONNX and to the generated C model.

Reads MODEL_DIR (stream.json + stream_weights.npz, written by `fogsf train`) and writes
  OUT/model.onnx   the streaming step: z, (h, c) per layer -> sf_ppm, new (h, c)
  OUT/NAME.h       `extern const fogsf_model NAME;` and NAME_* size macros (firmware/c)
  OUT/NAME.c       the weights as static const float32 data and the model struct
  --blob FILE      the calibration block: the model as data for one firmware image that
                   serves every unit (firmware/c/fogsf_block.h)
Models exported under different names link into one image (docs/firmware.md).
The same model and name always give the same bytes. `--sample-rate-hz` exports the model
for firmware that runs at another rate than the training logs': the model step in seconds
is kept, so D = step * rate (docs/stream-contract.md, "Sample rate"). `--even-time` exports
for the kernel built with FOGSF_EVEN_TIME and refuses a model whose step D is below that
build's bound, L*H + 3 samples (docs/firmware.md, "Bounded, even time").

Examples:
  fogsf export models/m --out build/m --name imu_x  # models/m: train --help's first example
  fogsf export models/m --out build/m1k --name imu_x --sample-rate-hz 1000
  fogsf export models/m --blob build/unit.bin
  fogsf export models/m --out build/m --name imu_x --even-time
"""

from __future__ import annotations

import argparse

from fogsf.cli.arguments import positive_float, rated
from fogsf.cli.axes import run_all, wants_all
from fogsf.errors import UserError
from fogsf.export import export_model
from fogsf.export.block import describe, write_block
from fogsf.export.header import check_even_time, check_name
from fogsf.logs.chamber_log import check_rate_hz
from fogsf.models.stream import StreamModel


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL_DIR", help="model directory from `fogsf train`")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="output folder (created): model.onnx, NAME.h and NAME.c")
    parser.add_argument("--blob", default=None, metavar="FILE",
                        help="write the calibration block (the model as data in flash: "
                             "docs/firmware.md, \"Calibration block\") to FILE")
    parser.add_argument("--name", default="gyro_model",
                        help="C name of the model (its symbol, file names and macro prefix); "
                             "one name per model of an image (default gyro_model)")
    parser.add_argument("--sample-rate-hz", type=positive_float, default=None, metavar="HZ",
                        help="the firmware's sample rate (default: the training logs'); "
                             "the model step must be a whole number of samples at it")
    parser.add_argument("--even-time", action="store_true",
                        help="the C model is for the kernel built with FOGSF_EVEN_TIME: "
                             "refused when the step's D < L*H + 3 (the per-sample bound "
                             "needs each step's parts to end before the next step)")
    parser.add_argument("--axis", choices=("all",), default=None,
                        help="all: MODEL_DIR holds one model folder per axis (A/, as `fogsf "
                             "train --axis all` writes): each is exported into OUT/A as "
                             "NAME_A (--name imu: imu_x, imu_y, imu_z)")


def run(args: argparse.Namespace) -> int:
    if wants_all(args):
        return run_all(args, run, "export")
    try:
        check_name(args.name)
    except ValueError as e:
        raise UserError(str(e)) from None
    if args.out is None and args.blob is None:
        raise UserError("nothing to write: give --out DIR (ONNX and C) and/or --blob FILE "
                        "(the calibration block)")
    model = StreamModel.load(args.model)
    if args.sample_rate_hz is not None:
        model = rated(model, 1.0 / check_rate_hz(args.sample_rate_hz),
                      f"{args.sample_rate_hz:g} Hz")
    if args.even_time:
        try:
            check_even_time(model)
        except ValueError as e:
            raise UserError(str(e)) from None
    paths = (export_model(model, args.out, args.name, args.even_time)
             if args.out is not None else {})
    if args.blob is not None:
        paths["block"] = write_block(model, args.blob)
    args.axis_result = {"name": args.name, "model_id": model.model_id,
                        "out": args.out or args.blob,
                        "sample_rate_hz": 1.0 / model.sample_dt_s,
                        "decimation": model.decimation}
    print(f"model {model.model_id} ({model.model}): {model.summary}")
    for kind, path in paths.items():
        print(f"wrote {path} ({path.stat().st_size} bytes, {kind})")
    if "block" in paths:
        print(describe(paths["block"].read_bytes()))
    return 0
