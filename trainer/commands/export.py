"""Export a trained streaming model to ONNX and to the generated C model.

Reads MODEL_DIR (stream.json + stream_weights.npz, written by `fogsf train`) and writes
  OUT/model.onnx   the streaming step: z, (h, c) per layer -> sf_ppm, new (h, c)
  OUT/NAME.h       `extern const fogsf_model NAME;` and NAME_* size macros (firmware/c)
  OUT/NAME.c       the weights as static const float32 data and the model struct
Models exported under different names link into one image (docs/firmware.md).
The same model and name always give the same bytes.

Example:
  fogsf export models/m --out build/m --name imu_x
"""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL_DIR", help="model directory from `fogsf train`")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output folder (created): model.onnx, NAME.h and NAME.c")
    parser.add_argument("--name", default="gyro_model",
                        help="C name of the model (its symbol, file names and macro prefix); "
                             "one name per model of an image (default gyro_model)")


def run(args: argparse.Namespace) -> int:
    from export import export_model
    from export.header import check_name
    from trainer.errors import UserError
    from trainer.stream import StreamModel

    try:
        check_name(args.name)
    except ValueError as e:
        raise UserError(str(e)) from None
    model = StreamModel.load(args.model)
    paths = export_model(model, args.out, args.name)
    print(f"model {model.model_id} ({model.model}): {model.summary}")
    for kind, path in paths.items():
        print(f"wrote {path} ({path.stat().st_size} bytes, {kind})")
    return 0
