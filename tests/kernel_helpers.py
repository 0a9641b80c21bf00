"""Shared set-up of the kernel tests: compiled kernels cached per session in a temp folder."""

from __future__ import annotations

from pathlib import Path

from fogsf.bindings.kernel import Kernel, build_kernel
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
