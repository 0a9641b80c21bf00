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
