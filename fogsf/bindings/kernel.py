"""Compile the C kernel for one model and drive it from Python through cffi (ABI mode).

`build_kernel(model)` exports the model as C (`bound_model.h/.c`, symbol `bound_model`) and
compiles firmware/c with the state sized for exactly this model (FOGSF_MAX_* = its sizes) into
a folder keyed by the model id and a hash of the kernel sources and flags (so an edit rebuilds,
a rerun does not): `libfogsf.so` for cffi and `libfogsf.a` for firmware builds. `Kernel` loads
the shared library and offers the per-sample step, the whole-log function and the building blocks.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import fogsf
from fogsf.errors import UserError
from fogsf.export.header import render_model
from fogsf.models.stream import StreamModel
from fogsf.models.stream_format import RATE_ARRAY

C_DIR = Path(fogsf.cmake_dir)
"""The kernel's C sources: firmware/c in a checkout, fogsf/firmware/c in an installed wheel."""
ROOT = Path(fogsf.firmware_dir).parent  # the checkout's root when fogsf.in_checkout
SOURCES = ("fogsf.c", "fogsf_cell.c", "fogsf_selftest.c")
HEADERS = ("fogsf.h", "fogsf_fp.h")
# The flags of the issue: strict C99, warnings are errors, no contraction into FMA (bit-exact
# float32 order on every target).
STRICT = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-ffp-contract=off")
SANITIZE = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all",
            "-fno-omit-frame-pointer")


def user_cache_dir() -> Path:
    """fogsf's folder in the user's cache: $XDG_CACHE_HOME/fogsf (~/.cache/fogsf) on Linux,
    ~/Library/Caches/fogsf on macOS, %LOCALAPPDATA%\\fogsf\\Cache on Windows."""
    home = Path.home()
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA")
        return (Path(base) if base else home / "AppData" / "Local") / "fogsf" / "Cache"
    if sys.platform == "darwin":
        return home / "Library" / "Caches" / "fogsf"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg and Path(xdg).is_absolute() else home / ".cache") / "fogsf"


def default_build_root() -> Path:
    """$FOGSF_BUILD_DIR, else build/kernels of a checkout run from inside it, else the
    user's cache directory (`user_cache_dir()`/kernels): never inside an installed package,
    nor in a source tree the user is not working in."""
    env = os.environ.get("FOGSF_BUILD_DIR")
    if env:
        return Path(env)
    try:
        inside = Path.cwd().resolve().is_relative_to(ROOT.resolve())
    except OSError:  # the working folder was deleted: not inside the checkout
        inside = False
    if fogsf.in_checkout and inside:
        return ROOT / "build" / "kernels"
    return user_cache_dir() / "kernels"


@dataclass(frozen=True)
class KernelBuild:
    directory: Path
    shared: Path
    static: Path
    model_id: str
    defines: tuple[str, ...] = ()  # the FOGSF_MAX_* flags the state was sized with


BOUND_NAME = "bound_model"  # the C name of the model in a bindings build


def max_defines(model: StreamModel) -> tuple[str, ...]:
    """-D flags sizing fogsf_state for exactly this model."""
    sizes = state_sizes(model)
    return tuple(f"-D{k}={v}" for k, v in sizes.items())


def state_sizes(model: StreamModel) -> dict[str, int]:
    return {"FOGSF_MAX_LAYERS": model.layers, "FOGSF_MAX_HIDDEN": model.hidden,
            "FOGSF_MAX_FEATURES": model.n_features,
            "FOGSF_MAX_FILTERS": max(model.n_filters, 1),
            "FOGSF_MAX_PLAYS": max(model.n_plays, 1),
            "FOGSF_MAX_RATE_ROWS": rate_rows(model)}  # 0: the kernel without the part


def rate_rows(model: StreamModel) -> int:
    """R, the rate part's terms (0 without one)."""
    return model.weights[RATE_ARRAY].shape[0] if model.has_rate_part else 0


def _source_hash(header: str, extra: tuple[str, ...]) -> str:
    """Kernel sources, the generated model (so a template change rebuilds) and the flags."""
    h = hashlib.sha256(header.encode())
    for name in SOURCES + HEADERS:
        h.update((C_DIR / name).read_bytes())
    h.update(" ".join(extra).encode())
    return h.hexdigest()[:8]


def _run(cmd: list[str], where: Path) -> None:
    proc = subprocess.run(cmd, cwd=where, capture_output=True, text=True)
    if proc.returncode != 0:
        raise UserError(f"compiling the C kernel failed: {' '.join(cmd)}\n"
                        f"{proc.stdout}{proc.stderr}")


EVEN_TIME = "-DFOGSF_EVEN_TIME=1"  # the kernel's bounded, even-time build (fogsf.h)


def build_kernel(model: StreamModel, root: str | Path | None = None, cc: str = "gcc",
                 opt: str = "-O2", sanitize: bool = False, even_time: bool = False,
                 extra: tuple[str, ...] = ()) -> KernelBuild:
    """Export the model as C and compile the kernel (cached by model id + sources + flags);
    `even_time`: with FOGSF_EVEN_TIME (the step spread over D samples, branch-free
    activations; `reference.replay(..., even_time=True)` gives its outputs); `extra`: flags
    after the strict ones (a later -std or -ffp-contract overrides theirs), for the tests of
    what a caller's flags do to the kernel."""
    if shutil.which(cc) is None:
        raise UserError(f"C compiler '{cc}' not found: install gcc (or pass another cc)")
    defines = (*max_defines(model), *((EVEN_TIME,) if even_time else ()))
    flags = (*STRICT, opt, "-fPIC", *defines, *(SANITIZE if sanitize else ()), *extra)
    files = render_model(model, BOUND_NAME)
    header = "".join(files.values())
    # the compiler by its name and a hash of how it was given (a path has slashes)
    cc_tag = Path(cc).name + ("" if cc == Path(cc).name
                              else "-" + hashlib.sha256(cc.encode()).hexdigest()[:6])
    key = (f"{model.model_id}-{cc_tag}-{_source_hash(header, flags)}"
           + ("-san" if sanitize else ""))
    out = Path(root) if root is not None else default_build_root()
    out = (out / key).resolve()
    shared, static = out / "libfogsf.so", out / "libfogsf.a"
    if shared.is_file() and static.is_file():
        return KernelBuild(out, shared, static, model.model_id, defines)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=out.parent))
    except OSError as e:
        raise UserError(f"cannot create a kernel build folder in {out.parent}: "
                        f"{e.strerror or e}; give --build-dir DIR (or set FOGSF_BUILD_DIR)"
                        ) from None
    try:
        # built in a private folder and renamed into place: concurrent runs of one model
        # (the user cache is shared) never compile into the same files, and a reader finds
        # the whole folder or none of it
        for file_name, text in files.items():
            (work / file_name).write_text(text)
        objs = []
        for src in [C_DIR / name for name in SOURCES] + [work / f"{BOUND_NAME}.c"]:
            obj = work / (src.stem + ".o")
            _run([cc, *flags, "-I", str(work), "-I", str(C_DIR), "-c", str(src),
                  "-o", str(obj)], work)
            objs.append(str(obj))
        _run([cc, "-shared", *(SANITIZE if sanitize else ()), "-o", str(work / shared.name),
              *objs], work)
        _run(["ar", "rcs", str(work / static.name), *objs], work)
        if shared.is_file() and static.is_file():  # another process finished first
            return KernelBuild(out, shared, static, model.model_id, defines)
        if out.is_dir():  # an incomplete folder (a file deleted by hand): replaced
            shutil.rmtree(out, ignore_errors=True)
        try:
            work.rename(out)
        except OSError:  # another process renamed its complete folder first: keep that one
            if not (shared.is_file() and static.is_file()):
                raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return KernelBuild(out, shared, static, model.model_id, defines)


def cdef(model: StreamModel, even_time: bool = False) -> str:
    """The cffi declarations of fogsf.h for this model's sizes: the header's declarations
    (between its extern "C" guards) without comments and preprocessor lines, with the
    state's size macros replaced by this model's sizes and its `#if FOGSF_EVEN_TIME` members
    kept for that build only (the `#if FOGSF_MAX_RATE_ROWS > 0` ones for a model with a rate
    part only), so there is one statement of the API; plus the bound model's
    symbol."""
    text = (C_DIR / "fogsf.h").read_text()
    body = text.split('extern "C" {\n#endif\n', 1)[1].split("#ifdef __cplusplus\n}", 1)[0]
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.DOTALL)
    body = re.sub(r"^#if FOGSF_EVEN_TIME\n(.*?)^#endif\n", lambda m: m[1] if even_time else "",
                  body, flags=re.DOTALL | re.MULTILINE)
    body = re.sub(r"^#if FOGSF_MAX_RATE_ROWS > 0\n(.*?)^#endif\n",
                  lambda m: m[1] if rate_rows(model) > 0 else "", body,
                  flags=re.DOTALL | re.MULTILINE)
    body = "\n".join(line for line in body.splitlines() if not line.lstrip().startswith("#"))
    sizes = state_sizes(model)
    unknown = set(re.findall(r"\bFOGSF_[A-Z_0-9]+\b", body)) - set(sizes)
    if unknown:
        raise RuntimeError(f"fogsf.h declarations use macros cdef() does not know: {unknown}")
    body = re.sub(r"\bFOGSF_[A-Z_0-9]+\b", lambda m: str(sizes[m.group(0)]), body)
    return body + f"\nextern fogsf_model {BOUND_NAME};\n"  # cffi: a const is a constant


class Kernel:
    """The compiled kernel of one model, loaded with cffi."""

    def __init__(self, model: StreamModel, build: KernelBuild | None = None) -> None:
        import cffi

        self.model = model
        self.build = build or build_kernel(model)
        self.ffi = cffi.FFI()
        self.ffi.cdef(cdef(model, EVEN_TIME in self.build.defines))
        self.lib = self.ffi.dlopen(str(self.build.shared))
        self.m = self.ffi.addressof(self.lib, BOUND_NAME)
        got = self.ffi.string(self.m.model_id).decode()
        if got != model.model_id:
            raise UserError(f"{self.build.shared}: kernel of model {got}, expected "
                            f"{model.model_id}: delete {self.build.directory} and rerun")
        if self.ffi.sizeof("fogsf_state") != self.lib.fogsf_state_size():
            raise UserError(f"{self.build.shared}: state layout differs from the bindings")

    def new_state(self):  # noqa: ANN201 - a cffi cdata pointer
        st = self.ffi.new("fogsf_state *")
        if self.lib.fogsf_init(self.m, st, self.ffi.sizeof("fogsf_state")) != 0:
            raise UserError(f"{self.build.shared}: the model does not fit the kernel's state")
        return st

    def step(self, st, temp_c: float, gyro_dps: float) -> tuple[float, float, int]:  # noqa: ANN001
        """One sample: (corrected_dps, sf_ppm, flags); temp_c and gyro_dps are cast to
        float32 first (as C's cast)."""
        out = self.ffi.new("fogsf_output *")
        with np.errstate(over="ignore"):
            t, g = float(np.float32(temp_c)), float(np.float32(gyro_dps))
        self.lib.fogsf_step(self.m, st, t, g, out)
        return out.corrected_dps, out.sf_ppm, out.flags

    def _inputs(self, temp_c: np.ndarray, gyro_dps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(over="ignore", invalid="ignore"):
            t = np.ascontiguousarray(temp_c, dtype=np.float32)
            g = np.ascontiguousarray(np.asarray(gyro_dps, dtype=np.float64), dtype=np.float32)
        if t.shape != g.shape or t.ndim != 1:
            raise UserError(f"temperature {t.shape} and gyro {g.shape} must be 1-D, same length")
        return t, g

    def run(self, temp_c: np.ndarray, gyro_dps: np.ndarray, st=None  # noqa: ANN001
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The whole-log function fogsf_run from reset (or from `st`): corrected, sf, flags."""
        t, g = self._inputs(temp_c, gyro_dps)
        n = t.shape[0]
        corrected, sf, flags = _outputs(n)
        st = st if st is not None else self.new_state()
        fb = self.ffi.from_buffer
        self.lib.fogsf_run(self.m, st, fb("float[]", t), fb("float[]", g), n,
                           fb("float[]", corrected), fb("float[]", sf), fb("uint32_t[]", flags))
        return corrected.astype(np.float64), sf, flags

    def run_bias(self, temp_c: np.ndarray, gyro_dps: np.ndarray, st=None  # noqa: ANN001
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """fogsf_run_bias from reset (or from `st`): corrected, sf, bias_dph, flags."""
        t, g = self._inputs(temp_c, gyro_dps)
        n = t.shape[0]
        corrected, sf, flags = _outputs(n)
        bias = np.empty(n, np.float32)
        fb = self.ffi.from_buffer
        st = st if st is not None else self.new_state()
        self.lib.fogsf_run_bias(self.m, st, fb("float[]", t), fb("float[]", g),
                                n, fb("float[]", corrected), fb("float[]", sf),
                                fb("float[]", bias), fb("uint32_t[]", flags))
        return corrected.astype(np.float64), sf, bias, flags

    def stream(self, temp_c: np.ndarray, gyro_dps: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One fogsf_step call per sample from Python (what firmware does), from reset."""
        t, g = self._inputs(temp_c, gyro_dps)
        n = t.shape[0]
        corrected, sf, flags = _outputs(n)
        st = self.new_state()
        out = self.ffi.new("fogsf_output *")
        step, m = self.lib.fogsf_step, self.m
        for i, (ti, gi) in enumerate(zip(t.tolist(), g.tolist(), strict=True)):
            step(m, st, ti, gi, out)
            corrected[i], sf[i], flags[i] = out.corrected_dps, out.sf_ppm, out.flags
        return corrected.astype(np.float64), sf, flags

    def lstm_cell(self, w: np.ndarray, r: np.ndarray, b: np.ndarray | None,
                  p: np.ndarray | None, x: np.ndarray, h: np.ndarray, c: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The generic cell (runtime sizes) on copies of h and c: (h_new, c_new)."""
        hid = r.shape[-1]
        arrs = [np.ascontiguousarray(a, np.float32) for a in (w, r, x)]
        h2 = np.array(h, np.float32).ravel()
        c2 = np.array(c, np.float32).ravel()
        scratch = np.empty(hid, np.float32)
        fb = self.ffi.from_buffer

        def opt(a: np.ndarray | None):  # noqa: ANN202
            return self.ffi.NULL if a is None else fb("float[]",
                                                       np.ascontiguousarray(a, np.float32))
        self.lib.fogsf_lstm_cell(arrs[2].size, hid, fb("float[]", arrs[0]), fb("float[]", arrs[1]),
                                 opt(b), opt(p), fb("float[]", arrs[2]), fb("float[]", h2),
                                 fb("float[]", c2), fb("float[]", scratch))
        return h2, c2

    def activation(self, name: str, x: np.ndarray) -> np.ndarray:
        """fogsf_expf / fogsf_sigmoidf / fogsf_tanhf elementwise."""
        fn = getattr(self.lib, f"fogsf_{name}f")
        return np.array([fn(v) for v in np.asarray(x, np.float32).tolist()], np.float32)


def trace_steps(kernel: Kernel, temp_c: np.ndarray, gyro_dps: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step the kernel sample by sample and read its state after every model step (samples
    0, D, 2D, ...): (z [n_steps, F], last layer's h [n_steps, H], sf_ppm [n_steps]). The
    default build keeps z on the stack of a step, so z is read from the even-time build of
    the same model (gcc), whose front runs on the step's sample with the same code."""
    t, g = kernel._inputs(temp_c, gyro_dps)
    model, ffi, lib = kernel.model, kernel.ffi, kernel.lib
    even = kernel if EVEN_TIME in kernel.build.defines else Kernel(model, build_kernel(
        model, root=kernel.build.directory.parent, even_time=True))
    st, st_even = kernel.new_state(), even.new_state()
    out, out_even = ffi.new("fogsf_output *"), even.ffi.new("fogsf_output *")
    steps = range(0, t.shape[0], model.decimation)
    z = np.empty((len(steps), model.n_features), np.float32)
    h = np.empty((len(steps), model.hidden), np.float32)
    sf = np.empty(len(steps), np.float32)
    zbuf = np.frombuffer(even.ffi.buffer(st_even.z), np.float32)
    hbuf = np.frombuffer(ffi.buffer(st.h[model.layers - 1]), np.float32)
    m = 0
    for i, (ti, gi) in enumerate(zip(t.tolist(), g.tolist(), strict=True)):
        lib.fogsf_step(kernel.m, st, ti, gi, out)
        if even is not kernel:
            even.lib.fogsf_step(even.m, st_even, ti, gi, out_even)
        if i % model.decimation == 0:
            z[m], h[m], sf[m] = zbuf, hbuf, out.sf_ppm
            m += 1
    return z, h, sf


def _outputs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample output arrays: corrected rate, sf_ppm (float32; the corrected rate is
    returned as float64 holding its float32 values exactly), flags (uint32)."""
    return np.empty(n, np.float32), np.empty(n, np.float32), np.empty(n, np.uint32)
