"""Shared set-up of the kernel tests: compiled kernels cached per session in a temp folder."""

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
