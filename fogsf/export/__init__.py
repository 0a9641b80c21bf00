"""Export a streaming model artifact to ONNX (the step) and to the generated C model."""

from __future__ import annotations

from pathlib import Path

from fogsf.export.header import check_even_time, check_name, write_model
from fogsf.models.stream import StreamModel

ONNX_NAME = "model.onnx"


def export_model(model: StreamModel, out_dir: str | Path, name: str = "gyro_model",
                 even_time: bool = False) -> dict[str, Path]:
    """Write out_dir/model.onnx, out_dir/NAME.h and out_dir/NAME.c; returns
    {'onnx': p, 'header': p, 'source': p}. even_time: the C model for the kernel built with
    FOGSF_EVEN_TIME, refused (ValueError) when D < L*H + 3 (header.check_even_time)."""
    # onnx: the C header's users (`bindings.kernel`, `fogsf replay`) import this package
    # without it
    from fogsf.export.onnx_step import build_step_onnx

    check_name(name)
    if even_time:
        check_even_time(model)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    onnx_path = out / ONNX_NAME
    onnx_path.write_bytes(build_step_onnx(model).SerializeToString())
    header, source = write_model(model, out, name, even_time)
    return {"onnx": onnx_path, "header": header, "source": source}
