"""Run-time integrity (issue 49, item 2): the state records the model's crc32 and sizes at
init; fogsf_step re-reads half a float of the model's tables a sample (the head words and
the start of each table on samples that run a model step), so the whole model is compared at
least every fogsf_check_period(m) samples, and checks the sizes against init's before a model
step. A fault planted after init (a flipped bit in any table or scalar, a size changed within
FOGSF_MAX_*) raises MODEL_CHANGED within two periods (a size: at the next model step) and
holds the correction of the last verified pass; NULL pointers and a state of another size
are refused with CALL_INVALID, nothing written. The C driver test (ASan + UBSan) plants the
size changes in a model whose tables are exactly their sizes, so a read past one aborts."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import FLAGS, init, kernel_for, seal, table_floats, writable_copy

from fogsf.bindings.firmware import golden_inputs
from fogsf.bindings.kernel import C_DIR, SANITIZE, SOURCES, STRICT, build_kernel
from fogsf.models import reference, samples

CHANGED, CALL = FLAGS["MODEL_CHANGED"], FLAGS["CALL_INVALID"]
INVALID = FLAGS["MODEL_INVALID"]
HEAD_SLOTS = 21  # head words, one a sample (the 21st only with a bias head)

# (K, F, L, H, D, seed, extras): plain; the default model's form with a bias head; a play
# and two layers
SHAPES = [(3, 4, 1, 16, 10, 2026, {}),
          (11, 12, 1, 16, 50, 81, {"poly_head": True, "lstm_inputs": 1, "quad_diag": True,
                                   "feat_diag": True, "bias_head": True}),
          (2, 4, 2, 6, 3, 82, {"poly_head": True, "bias_head": True,
                               "plays": (((0.2, 0.5, 0.3), 2.0),)})]


@pytest.fixture(scope="module")
def kroot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("integrity-kernels")


def shape_model(shape):  # noqa: ANN001, ANN201
    k, f, layers, hidden, d, seed, extra = shape
    return samples.random_model(k, f, layers, hidden, decimation=d, seed=seed,
                                stuck_samples=0, **extra)


def period(model) -> int:  # noqa: ANN001
    """The most samples one pass takes: two a float (its halves), and the 21 head slots, the
    start of each of the 12 + 3L table slots and the compare each on a model step's sample,
    at most D samples after the one before (fogsf.h, fogsf_check_period)."""
    ops = HEAD_SLOTS + 12 + 3 * model.layers + 1
    return ops * model.decimation + 2 * sum(n for _, n in table_floats(model))


def stepped(kernel, m, temp, gyro, flip=None):  # noqa: ANN001, ANN201
    """fogsf_step over the log from init with model m: (outputs per sample as (corrected,
    sf, bias, flags), the samples at which a pass ended). `flip`: (sample, callable) run
    before that sample's step."""
    ffi, lib = kernel.ffi, kernel.lib
    state = ffi.new("fogsf_state *")
    assert init(kernel, m, state) == 0
    out = ffi.new("fogsf_output *")
    got, ends = [], []
    for i in range(temp.size):
        if flip is not None and i == flip[0]:
            flip[1]()
        seg = state.crc_seg
        lib.fogsf_step(m, state, float(temp[i]), float(gyro[i]), out)
        if seg > 0 and state.crc_seg == 0:
            ends.append(i)
        got.append((out.corrected_dps, out.sf_ppm, out.bias_dph, out.flags))
    return got, ends


@pytest.mark.parametrize("shape", SHAPES, ids=["plain", "default-form-bias", "play-2-layers"])
def test_check_period_and_a_healthy_model_is_never_flagged(shape, kroot) -> None:
    model = shape_model(shape)
    kernel = kernel_for(model, kroot)
    n = period(model)
    assert kernel.lib.fogsf_check_period(kernel.m) == n
    temp, gyro = golden_inputs(model, n=3 * n + 17, seed=1)
    got, ends = stepped(kernel, kernel.m, temp, gyro)
    assert len(ends) >= 3 and ends[0] < n and np.diff(ends).max() <= n  # within the bound
    assert not any(g[3] & CHANGED for g in got)  # three whole passes compared, all equal
    want = reference.replay(model, temp, gyro)
    corrected = np.array([g[0] for g in got], np.float32).astype(np.float64)
    assert corrected.tobytes() == want.corrected_dps.tobytes()
    assert np.array_equal(np.array([g[3] for g in got], np.uint32), want.flags)


@pytest.mark.parametrize("shape", SHAPES, ids=["plain", "default-form-bias", "play-2-layers"])
def test_a_bit_flipped_after_init_is_found_and_the_verified_correction_held(shape,
                                                                           kroot) -> None:
    """One bit flipped in one table (every table in turn, at a random sample of the third
    pass): MODEL_CHANGED from the end of the pass that reads the flipped word, within two
    periods of the flip, and from then on the outputs of the last verified pass held (the
    state of a clean run at that time), until a reset; the flags before it say nothing."""
    model = shape_model(shape)
    kernel = kernel_for(model, kroot)
    ffi = kernel.ffi
    n = period(model)
    temp, gyro = golden_inputs(model, n=5 * n, seed=2)
    clean, ends = stepped(kernel, kernel.m, temp, gyro)
    rng = np.random.default_rng(shape[5])
    keep: list = []
    for path, floats in table_floats(model):
        m, fields = writable_copy(kernel, keep)
        flip_at = int(rng.integers(ends[1], ends[2]))  # in the third pass
        byte, bit = int(rng.integers(0, 4 * floats)), 1 << int(rng.integers(0, 8))

        def flip(arr=fields[path], byte=byte, bit=bit) -> None:  # noqa: ANN001
            raw = ffi.buffer(arr)
            raw[byte] = bytes([raw[byte][0] ^ bit])
        got, _ = stepped(kernel, m, temp, gyro, (flip_at, flip))
        assert got[:flip_at] == clean[:flip_at], path  # nothing before the flip
        flagged = [i for i, g in enumerate(got) if g[3] & CHANGED]
        assert flagged, path
        first = flagged[0]
        assert first in ends and flip_at <= first < flip_at + 2 * n, (path, first)
        assert flagged == list(range(first, temp.size)), path  # latched
        # held: what the clean run held before the end of the pass two passes earlier (the
        # last verified pass's start; nothing verified before the third pass ends: zeros)
        k = ends.index(first)
        good = clean[ends[k - 2] - 1] if k >= 2 else (0.0, 0.0, 0.0, 0)
        sf_good, bias_good = np.float32(good[1]), np.float32(good[2])
        fl_good = good[3] & (FLAGS["SF_CLAMPED"] | FLAGS["BIAS_CLAMPED"])
        kk, b = reference.correction_terms(np.float32([sf_good]), np.float32([bias_good]))
        for i in range(first, temp.size):
            corrected, sf, bias, flags = got[i]
            with np.errstate(all="ignore"):
                d = np.float32(gyro[i]) - b[0]
                want = np.float32(d - d * kk[0])
            want_flags = CHANGED | fl_good
            if not np.isfinite(want):
                want, want_flags = np.float32(0.0), want_flags | FLAGS["GYRO_INVALID"]
            assert (np.float32(sf), np.float32(bias)) == (sf_good, bias_good), (path, i)
            assert np.float32(corrected).tobytes() == want.tobytes(), (path, i)
            assert flags == want_flags, (path, i)
        state = ffi.new("fogsf_state *")
        assert init(kernel, m, state) == INVALID  # a reset checks the whole model: refused


def test_a_scalar_changed_after_init_is_found_by_the_pass(kroot) -> None:
    """t_ref, out_scale, the bias head's b and stuck_samples are head words of the pass: a
    change (even one with the model's own CRCs resealed) is found at the pass's end."""
    model = shape_model(SHAPES[1])
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    n = period(model)
    out = ffi.new("fogsf_output *")
    for field, value, reseal in (("t_ref_c", 21.0, False), ("out_scale", 301.0, True),
                                 ("stuck_samples", 7, False), ("bias.b", 2.5, True)):
        keep: list = []
        m, _ = writable_copy(kernel, keep)
        state = ffi.new("fogsf_state *")
        assert init(kernel, m, state) == 0
        for _ in range(n + 5):
            lib.fogsf_step(m, state, 20.0, 10.0, out)
        owner, name = (m.bias, "b") if field == "bias.b" else (m, field)
        setattr(owner, name, value)
        if reseal:
            seal(lib, m)
        steps = 0
        while not out.flags & CHANGED and steps < 2 * n:
            lib.fogsf_step(m, state, 20.0, 10.0, out)
            steps += 1
        assert out.flags & CHANGED, field


@pytest.mark.parametrize("field", ["hidden", "n_features", "n_filters", "lstm_inputs"])
def test_a_size_changed_within_the_state_is_flagged_at_the_next_model_step(field,
                                                                           kroot) -> None:
    """The kernel's state sized for a larger model (FOGSF_MAX_* of 3x6x16), the model started
    with smaller sizes (the same tables, CRCs resealed), then a size raised back within
    FOGSF_MAX_*: MODEL_CHANGED at the next model step, the correction held, no step run."""
    big = samples.random_model(4, 6, 1, 16, decimation=4, seed=83)
    kernel = kernel_for(big, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    small = {"hidden": 8, "n_features": 5, "n_filters": 3, "lstm_inputs": 2}
    m = seal(lib, ffi.new("fogsf_model *", kernel.m[0]), **{field: small[field]})
    if field == "n_features":  # the first layer then reads z[0:5]
        m = seal(lib, m, lstm_inputs=5)
    state = ffi.new("fogsf_state *")
    assert init(kernel, m, state) == 0
    out = ffi.new("fogsf_output *")
    for _ in range(9):  # two model steps and a bit
        lib.fogsf_step(m, state, 20.0, 10.0, out)
        assert out.flags == 0
    held = (out.corrected_dps, out.sf_ppm)
    setattr(m, field, getattr(kernel.m, field) if field != "lstm_inputs" else 4)
    h_before = bytes(ffi.buffer(state.h))
    flags = []
    for _ in range(big.decimation):
        lib.fogsf_step(m, state, 20.0, 10.0, out)
        flags.append(out.flags)
    assert flags[-1] == CHANGED and flags.count(CHANGED) == 1  # at the model step
    assert bytes(ffi.buffer(state.h)) == h_before  # no unit ran at the changed size
    assert (out.corrected_dps, out.sf_ppm) == (10.0, 0.0) != held  # nothing verified yet


def test_null_pointers_and_a_state_of_another_size_are_refused(kroot) -> None:
    model = shape_model(SHAPES[0])
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    size = ffi.sizeof("fogsf_state")
    for wrong in (0, size - 4, size + 4, 2 * size):
        buf = ffi.new("unsigned char[]", 2 * size + 8)
        ffi.memmove(buf, b"\xa5" * len(buf), len(buf))
        st = ffi.cast("fogsf_state *", buf)
        assert lib.fogsf_init(kernel.m, st, wrong) == CALL, wrong
        assert lib.fogsf_reset(kernel.m, st, wrong) == CALL, wrong
        assert bytes(ffi.buffer(buf)) == b"\xa5" * len(buf), wrong  # nothing written
    assert lib.fogsf_init(kernel.m, ffi.NULL, size) == CALL
    assert lib.fogsf_init(ffi.NULL, ffi.new("fogsf_state *"), size) == INVALID
    st = kernel.new_state()
    out = ffi.new("fogsf_output *")
    for m, s in ((kernel.m, ffi.NULL), (ffi.NULL, st)):
        lib.fogsf_step(m, s, 20.0, 10.0, out)
        assert (out.corrected_dps, out.sf_ppm, out.flags) == (0.0, 0.0, INVALID | CALL)
    before = bytes(ffi.buffer(st))
    lib.fogsf_step(kernel.m, st, 20.0, 10.0, ffi.NULL)  # no output: nothing done
    assert bytes(ffi.buffer(st)) == before
    vals = np.full(4, 7.0, np.float32)
    outs = np.full(4, -1.0, np.float32)
    fb = ffi.from_buffer
    for t, g, s in ((ffi.NULL, fb("float[]", vals), st), (fb("float[]", vals), ffi.NULL, st),
                    (fb("float[]", vals), fb("float[]", vals), ffi.NULL)):
        assert lib.fogsf_run(kernel.m, s, t, g, 4, fb("float[]", outs), ffi.NULL,
                             ffi.NULL) == CALL
        assert (outs == -1.0).all()  # nothing written
    assert lib.fogsf_run(kernel.m, st, ffi.NULL, ffi.NULL, 0, ffi.NULL, ffi.NULL, ffi.NULL) == 0
    assert lib.fogsf_model_check(ffi.NULL) == INVALID
    assert lib.fogsf_model_crc32(ffi.NULL, 0) == 0 and lib.fogsf_check_period(ffi.NULL) == 0
    h = np.ones(4, np.float32)
    lib.fogsf_lstm_cell(1, 4, ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL,
                        fb("float[]", h), ffi.NULL, ffi.NULL)
    assert (h == 1.0).all()


FAULT_MAIN = r"""/* Planted size changes after init, under ASan + UBSan: the model's tables are
 * exactly its sizes (generated statics with redzones), the state sized above them
 * (FOGSF_MAX_*), so a loop that ran to a changed size would read past a table and abort.
 * Each change must be flagged MODEL_CHANGED within D + 1 samples (at the next model step). */
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include "fogsf.h"
#include "bound_model.h"

static int plant(const char *name, size_t offset, uint32_t value)
{
    static fogsf_state st;
    fogsf_model live = bound_model; /* a model in RAM */
    uint32_t i, seen = 0u;
    fogsf_output out;
    if (fogsf_init(&live, &st, sizeof st) != 0u) {
        printf("%s: init refused\n", name);
        return 1;
    }
    for (i = 0u; i < 2u * live.decimation + 1u; ++i) {
        fogsf_step(&live, &st, 20.0f + 0.01f * (float)i, 10.0f, &out);
    }
    memcpy((unsigned char *)&live + offset, &value, sizeof value);
    for (i = 0u; (i < live.decimation + 1u) && (seen == 0u); ++i) {
        fogsf_step(&live, &st, 20.0f, 10.0f, &out);
        seen = out.flags & FOGSF_FLAG_MODEL_CHANGED;
    }
    for (i = 0u; i < 3u * live.decimation; ++i) { /* and after it: held, nothing read */
        fogsf_step(&live, &st, 20.0f, 10.0f, &out);
    }
    printf("%s -> %u: %s\n", name, (unsigned)value, seen != 0u ? "flagged" : "NOT FLAGGED");
    return seen != 0u ? 0 : 1;
}

#define PLANT(f, v) plant(#f, offsetof(fogsf_model, f), (v))

/* a state the caller compiled smaller (another FOGSF_MAX_*): refused, nothing written (ASan
 * guards the bytes past it) */
static uint32_t small_state[(sizeof(fogsf_state) / 4u) - 2u];

static int refuse_small_state(void)
{
    fogsf_state *st = (fogsf_state *)(void *)small_state;
    const uint32_t a = fogsf_init(&bound_model, st, sizeof small_state);
    const uint32_t b = fogsf_reset(&bound_model, st, sizeof small_state);
    const uint32_t c = fogsf_selftest(st, sizeof small_state);
    const int ok = (a == FOGSF_FLAG_CALL_INVALID) && (b == FOGSF_FLAG_CALL_INVALID) &&
                   (c == FOGSF_SELFTEST_MODEL) && (small_state[0] == 0u);
    printf("small state: %s\n", ok ? "refused" : "NOT REFUSED");
    return ok ? 0 : 1;
}

int main(void)
{
    int bad = refuse_small_state();
    bad |= PLANT(hidden, bound_model.hidden + 2u);
    bad |= PLANT(n_features, bound_model.n_features + 2u);
    bad |= PLANT(n_filters, bound_model.n_filters + 2u);
    bad |= PLANT(layers, bound_model.layers + 1u);
    bad |= PLANT(lstm_inputs, 0u);
    bad |= PLANT(quad_diag, 0u);
    bad |= PLANT(feat_diag, 0u);
    printf(bad == 0 ? "PASS\n" : "FAIL\n");
    return bad;
}
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_sizes_changed_within_the_state_never_read_out_of_bounds_asan(tmp_path) -> None:
    """The default model's form (lstm_inputs 1, the diagonal quadratic and feature map, a
    bias head) in a state 2 larger in every size: every size raised within FOGSF_MAX_*
    after init (or a narrowed form widened) is flagged, and ASan sees no read past a table;
    a state smaller than the kernel's is refused by init, reset and the self-test, and
    ASan sees no write past it."""
    model = shape_model(SHAPES[1])
    build = build_kernel(model, root=tmp_path / "k")
    (tmp_path / "fault_main.c").write_text(FAULT_MAIN)
    defines = [f"-DFOGSF_MAX_{k}={v}" for k, v in (
        ("LAYERS", model.layers + 1), ("HIDDEN", model.hidden + 2),
        ("FEATURES", model.n_features + 2), ("FILTERS", model.n_filters + 2),
        ("PLAYS", max(model.n_plays, 1) + 2))]
    exe = tmp_path / "fault"
    subprocess.run(["gcc", *STRICT, "-O1", *SANITIZE, *defines, "-I", str(build.directory),
                    "-I", str(C_DIR), str(tmp_path / "fault_main.c"),
                    *(str(C_DIR / n) for n in SOURCES), str(build.directory / "bound_model.c"),
                    "-o", str(exe)], check=True, capture_output=True, text=True)
    proc = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("PASS"), \
        proc.stdout + proc.stderr
    assert "ERROR: AddressSanitizer" not in proc.stderr and "runtime error" not in proc.stderr
    assert proc.stdout.count("flagged") == 7 and "small state: refused" in proc.stdout
