"""The block loader (firmware/c/fogsf_block.c) through cffi, beside the generated C model of
the same artifact, and its host driver for the sanitizer builds.

`BlockKernel(model, build_block_lib(model, out))` loads a shared library of the kernel, the
loader and the model's generated C (`bound_model`), its state sized for the model; `load`
reads a block's bytes into a fogsf_block_model, `run` steps either model through
fogsf_run_bias.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np

from fogsf.bindings.kernel import (
    BOUND_NAME,
    C_DIR,
    SANITIZE,
    SOURCES,
    STRICT,
    cdef,
    max_defines,
    state_sizes,
)
from fogsf.errors import UserError
from fogsf.export.header import render_model
from fogsf.models.stream import StreamModel

BLOCK_SOURCES = ("fogsf_block.c",)
BLOCK_HEADER = "fogsf_block.h"


def block_cdef(model: StreamModel) -> str:
    """cdef() of fogsf.h plus fogsf_block.h's declarations for the model's sizes."""
    text = (C_DIR / BLOCK_HEADER).read_text()
    body = text.split('extern "C" {\n#endif\n', 1)[1].split("#ifdef __cplusplus\n}", 1)[0]
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.DOTALL)
    body = "\n".join(line for line in body.splitlines() if not line.lstrip().startswith("#"))
    sizes = state_sizes(model)
    body = re.sub(r"\bFOGSF_MAX_[A-Z_]+\b", lambda m: str(sizes[m.group(0)]), body)
    return cdef(model) + body


def _compile(cmd: list[str], what: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"{what} failed: {' '.join(cmd)}\n{proc.stdout}{proc.stderr}")


def write_bound(model: StreamModel, out: Path) -> Path:
    """The model's generated C as `bound_model` in out (created); returns its .c."""
    out.mkdir(parents=True, exist_ok=True)
    for name, text in render_model(model, BOUND_NAME).items():
        (out / name).write_text(text)
    return out / f"{BOUND_NAME}.c"


def build_block_lib(model: StreamModel, out: Path, cc: str = "gcc",
                    extra: tuple[str, ...] = ()) -> Path:
    """libfogsf_block.so: the kernel, the loader and the model's generated C, the state
    sized for the model (`extra`: more flags, e.g. other FOGSF_MAX_*)."""
    bound = write_bound(model, out)
    lib = out / "libfogsf_block.so"
    srcs = [*(C_DIR / n for n in (*SOURCES, *BLOCK_SOURCES)), bound]
    _compile([cc, *STRICT, "-O2", "-fPIC", "-shared", *max_defines(model), *extra,
              "-I", str(out), "-I", str(C_DIR), *map(str, srcs), "-o", str(lib)],
             "building the block library")
    return lib


def build_block_driver(model: StreamModel, out: Path, cc: str = "gcc",
                       sanitize: bool = True) -> Path:
    """firmware/c/test/block_main.c with the kernel and the loader (ASan + UBSan)."""
    out.mkdir(parents=True, exist_ok=True)
    exe = out / ("block_main_san" if sanitize else "block_main")
    srcs = [*(C_DIR / n for n in (*SOURCES, *BLOCK_SOURCES)), C_DIR / "test" / "block_main.c"]
    _compile([cc, *STRICT, "-O1", *max_defines(model), *(SANITIZE if sanitize else ()),
              "-I", str(C_DIR), *map(str, srcs), "-o", str(exe)], "building block_main")
    return exe


class BlockKernel:
    """The loader and the kernel of one model's sizes, loaded with cffi."""

    def __init__(self, model: StreamModel, lib: Path) -> None:
        import cffi

        self.model = model
        self.ffi = cffi.FFI()
        self.ffi.cdef(block_cdef(model))
        self.lib = self.ffi.dlopen(str(lib))
        self.generated = self.ffi.addressof(self.lib, BOUND_NAME)
        self._keep: list[object] = []

    def load(self, data: bytes, shift: int = 0) -> tuple[int, object]:
        """(status, the fogsf_block_model): data copied `shift` bytes past a 4-aligned start,
        the copy kept alive as long as this kernel (the model points into it)."""
        words = np.zeros((len(data) + shift) // 4 + 1, np.uint32)
        buf = words.view(np.uint8)[shift:shift + len(data)]
        buf[:] = np.frombuffer(data, np.uint8)
        bm = self.ffi.new("fogsf_block_model *")
        self._keep += [words, bm]
        status = self.lib.fogsf_model_from_block(self.ffi.from_buffer("uint8_t[]", buf),
                                                 len(data), bm)
        return int(status), bm

    def run(self, m: object, temp_c: np.ndarray, gyro_dps: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """fogsf_run_bias from fogsf_init with model pointer m: corrected, sf, bias, flags
        (float32 / uint32) and what init returned."""
        t = np.ascontiguousarray(temp_c, np.float32)
        g = np.ascontiguousarray(gyro_dps, np.float32)
        n = t.shape[0]
        out = [np.empty(n, np.float32) for _ in range(3)]
        flags = np.empty(n, np.uint32)
        st = self.ffi.new("fogsf_state *")
        init = self.lib.fogsf_init(m, st, self.ffi.sizeof("fogsf_state"))
        fb = self.ffi.from_buffer
        self.lib.fogsf_run_bias(m, st, fb("float[]", t), fb("float[]", g), n,
                                *(fb("float[]", a) for a in out), fb("uint32_t[]", flags))
        return out[0], out[1], out[2], flags, int(init)
