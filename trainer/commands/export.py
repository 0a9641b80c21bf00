"""Export a trained streaming model to ONNX and to the generated C header.

Reads MODEL_DIR (stream.json + stream_weights.npz, written by `fogsf train`) and writes
  OUT/model.onnx      the streaming step: z, (h, c) per layer -> sf_ppm, new (h, c)
  OUT/fogsf_model.h   fixed-size float32 arrays and macros for the C kernel (firmware/c)
The same model always gives the same bytes.

Example:
  fogsf export models/m --out build/m
"""

from __future__ import annotations

import argparse


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL_DIR", help="model directory from `fogsf train`")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output folder (created): model.onnx and fogsf_model.h")


def run(args: argparse.Namespace) -> int:
    from export import export_model
    from trainer.stream import StreamModel

    model = StreamModel.load(args.model)
    paths = export_model(model, args.out)
    print(f"model {model.model_id} ({model.model}): {model.summary}")
    for kind, path in paths.items():
        print(f"wrote {path} ({path.stat().st_size} bytes, {kind})")
    return 0
