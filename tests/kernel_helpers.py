"""Shared set-up of the kernel tests: compiled kernels cached per session in a temp folder,
the C model's table layout and a writable copy of its tables."""

from __future__ import annotations

import re
from pathlib import Path

from fogsf.bindings.kernel import C_DIR, Kernel, build_kernel
from fogsf.models.stream import StreamModel

_KERNELS: dict[tuple[str, str], Kernel] = {}


def kernel_for(model: StreamModel, root: Path, cc: str = "gcc") -> Kernel:
    key = (model.model_id, cc)
    if key not in _KERNELS:
        _KERNELS[key] = Kernel(model, build_kernel(model, root=root, cc=cc))
    return _KERNELS[key]


def seal(lib, m, **fields: int):  # noqa: ANN001, ANN201 - cffi objects
    """Set the given fields of the cffi fogsf_model `m`, then its two CRCs as `fogsf export`
    would write them for the result (fogsf_model_crc32); returns m. Only for changes that do
    not lengthen a table: the CRC reads the tables at the sizes the fields give."""
    for name, value in fields.items():
        setattr(m, name, value)
    m.crc32_sizes = lib.fogsf_model_crc32(m, 1)
    m.crc32 = lib.fogsf_model_crc32(m, 0)
    return m


def header_flags() -> dict[str, int]:
    """The kernel's FOGSF_FLAG_* values as fogsf.h defines them (the flags this session's
    kernel added are not yet in fogsf.models.stream_flags)."""
    text = (C_DIR / "fogsf.h").read_text()
    return {m[1]: int(m[2]) for m in re.finditer(r"#define FOGSF_FLAG_(\w+) (\d+)u", text)}


FLAGS = header_flags()


def init(kernel, m, st) -> int:  # noqa: ANN001 - cffi objects
    """fogsf_init(m, st, sizeof(fogsf_state)) of the kernel's own layout."""
    return kernel.lib.fogsf_init(m, st, kernel.ffi.sizeof("fogsf_state"))


# the power-on rule of the kernel (fogsf.h): a first temperature primes the filters only when
# within [-55, 125] C (float32) and not a DS18B20's power-on 85 C


def table_floats(model) -> list[tuple[str, int]]:  # noqa: ANN001
    """(C field path, floats) of every table of the C model, in the CRC's order: what the
    integrity and guard tests flip, copy and count."""
    k, f, h, p = model.n_filters, model.n_features, model.hidden, model.n_plays
    out = [("filter_alpha", k), ("feat_w", f if model.feat_diag else f * (1 + k + p)),
           ("feat_b", f)]
    for layer in range(model.layers):
        n_in = model.n_lstm_inputs if layer == 0 else h
        out += [(f"lstm_w.{layer}", 4 * h * n_in), (f"lstm_r.{layer}", 4 * h * h),
                (f"lstm_b.{layer}", 8 * h)]
    out += [("head_w", h), ("skip_w", f)]
    if model.poly_head:
        out += [("quad_w", f if model.quad_diag else f * f), ("cube_w", f)]
    if model.bias_head:
        out += [("bias.w", f), ("bias.quad_w", f), ("bias.cube_w", f)]
    if p:
        out += [("plays.half_c", p), ("plays.source_w", p * (1 + k))]
    return [(name, n) for name, n in out if n > 0]


def writable_copy(kernel, keep: list):  # noqa: ANN001, ANN202
    """The bound model with every table (and the bias head, the plays) copied into writable
    memory: (model, {field path: float array})."""
    ffi, model = kernel.ffi, kernel.model
    m = ffi.new("fogsf_model *", kernel.m[0])
    keep.append(m)
    for part, ctype in (("bias", "fogsf_bias_head *"), ("plays", "fogsf_plays *")):
        if getattr(kernel.m, part) != ffi.NULL:
            owned = ffi.new(ctype, getattr(kernel.m, part)[0])
            keep.append(owned)
            setattr(m, part, owned)
    for name in ("lstm_w", "lstm_r", "lstm_b"):
        arr = ffi.new("float *[]", [getattr(kernel.m, name)[i] for i in range(model.layers)])
        keep.append(arr)
        setattr(m, name, arr)
    fields = {}
    for path, n in table_floats(model):
        head, _, tail = path.partition(".")
        arr = ffi.new("float[]", n)
        if head in ("bias", "plays"):
            owner = getattr(m, head)
            ffi.memmove(arr, getattr(owner, tail), 4 * n)
            setattr(owner, tail, arr)
        elif tail:
            ffi.memmove(arr, getattr(m, head)[int(tail)], 4 * n)
            getattr(m, head)[int(tail)] = arr
        else:
            ffi.memmove(arr, getattr(m, head), 4 * n)
            setattr(m, head, arr)
        keep.append(arr)
        fields[path] = arr
    return m, fields
