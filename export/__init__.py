"""Export a streaming model artifact to ONNX (the step) and to the generated C header."""

from __future__ import annotations

from pathlib import Path

from trainer.stream import StreamModel

HEADER_NAME = "fogsf_model.h"
ONNX_NAME = "model.onnx"


def export_model(model: StreamModel, out_dir: str | Path) -> dict[str, Path]:
    """Write out_dir/model.onnx and out_dir/fogsf_model.h; returns {'onnx': p, 'header': p}."""
    from export.header import render_header
    from export.onnx_step import build_step_onnx

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    onnx_path, header_path = out / ONNX_NAME, out / HEADER_NAME
    onnx_path.write_bytes(build_step_onnx(model).SerializeToString())
    header_path.write_text(render_header(model))
    return {"onnx": onnx_path, "header": header_path}
