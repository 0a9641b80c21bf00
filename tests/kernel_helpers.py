"""Shared set-up of the kernel tests: compiled kernels cached per session in a temp folder."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from fogsf.bindings.kernel import C_DIR, Kernel, build_kernel
from fogsf.models import reference
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
PLAUSIBLE_C = (-55.0, 125.0)
POWER_ON_C = 85.0


def first_plausible(temp_c: np.ndarray) -> int:
    """Index of the first temperature the kernel primes with (len(temp_c) if none)."""
    with np.errstate(over="ignore", invalid="ignore"):
        t = np.asarray(temp_c, dtype=np.float32)
        ok = (t >= np.float32(PLAUSIBLE_C[0])) & (t <= np.float32(PLAUSIBLE_C[1])) & (
            t != np.float32(POWER_ON_C))
    hits = np.flatnonzero(ok)
    return int(hits[0]) if hits.size else int(t.shape[0])


def replay_from_power_on(model: StreamModel, temp_c: np.ndarray, gyro_dps: np.ndarray,
                         even_time: bool = False) -> reference.ReplayOut:
    """The reference with the power-on rule (what fogsf/models/reference.py is to take on):
    before the first plausible temperature the gyro as it is (float32; non-finite: 0 and
    GYRO_INVALID), sf 0, bias 0, TEMP_UNPRIMED (and TEMP_INVALID for a non-finite one); from
    it on the reference from a clean start on the rest of the log."""
    with np.errstate(over="ignore", invalid="ignore"):
        t = np.asarray(temp_c, dtype=np.float32)
        g = np.asarray(gyro_dps, dtype=np.float64).astype(np.float32)
    i0 = first_plausible(t)
    head_corrected, gflags = reference.correct(g[:i0], np.zeros(i0, np.float32))
    head_flags = (np.uint32(FLAGS["TEMP_UNPRIMED"]) | gflags
                  | np.where(np.isfinite(t[:i0]), 0, FLAGS["TEMP_INVALID"]).astype(np.uint32))
    rest = reference.replay(model, t[i0:], g[i0:], even_time=even_time)
    zeros = np.zeros(i0, np.float32)
    return reference.ReplayOut(np.concatenate([head_corrected, rest.corrected_dps]),
                               np.concatenate([zeros, rest.sf_ppm]),
                               np.concatenate([head_flags, rest.flags]).astype(np.uint32),
                               np.concatenate([zeros, rest.bias_dph]))
