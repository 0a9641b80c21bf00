"""The kernel's bounded, even-time build (FOGSF_EVEN_TIME, fogsf.h): the model step spread
over the D samples after its own, its outputs held from the next step's sample on, bit for
bit the numpy reference's `replay(..., even_time=True)`; branch-free activations with the
default build's bits; the power-on self-test passes in both builds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import FLAGS

from fogsf.bindings.firmware import golden_inputs
from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.models import reference, samples

# (filters, features, layers, hidden, D, seed, extras): D below the step's parts (3 with
# 1x8: 11 parts, the pending parts run at the next step's sample) and above them
SHAPES = [
    (2, 4, 1, 8, 3, 61, {}),
    (2, 3, 1, 6, 10, 62, {"poly_head": True, "bias_head": True,
                          "plays": (((0.5, 0.3, 0.2), 1.5),)}),
    (11, 12, 1, 16, 50, 63, {"poly_head": True, "lstm_inputs": 1, "quad_diag": True,
                             "feat_diag": True, "bias_head": True}),
    (1, 2, 2, 5, 7, 64, {"poly_head": True}),
]


@pytest.fixture(scope="module")
def kroot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("even_kernels")


@pytest.mark.slow
@pytest.mark.parametrize("shape", SHAPES)
def test_even_time_kernel_is_the_reference_held_one_period_later(shape, kroot: Path) -> None:
    k, f, layers, hidden, d, seed, extra = shape
    model = samples.random_model(k, f, layers, hidden, decimation=d, seed=seed,
                                 stuck_samples=20, **extra)
    temp, gyro = golden_inputs(model, n=60 * d + 7, seed=seed)
    even = Kernel(model, build_kernel(model, root=kroot, even_time=True))
    corrected, sf, bias, flags = even.run_bias(temp, gyro)
    want = reference.replay(model, temp, gyro, even_time=True)
    assert sf.tobytes() == want.sf_ppm.tobytes(), f"seed {seed}"
    assert bias.tobytes() == want.bias_dph.tobytes(), f"seed {seed}"
    assert corrected.tobytes() == want.corrected_dps.tobytes(), f"seed {seed}"
    assert np.array_equal(flags, want.flags), f"seed {seed}"
    # the same step outputs as the default kernel, D samples later; sample by sample too
    plain = reference.replay(model, temp, gyro)
    assert sf[d:].tobytes() == plain.sf_ppm[:-d].tobytes()
    assert not sf[:d].any()
    c2, sf2, fl2 = even.stream(temp, gyro)
    assert c2.tobytes() == corrected.tobytes() and sf2.tobytes() == sf.tobytes()
    assert np.array_equal(fl2, flags)


def test_even_time_activations_and_selftest(kroot: Path) -> None:
    """tanh computes both forms and selects: the default build's bits on every kind of
    input (both sides of 0.625, the clamps, NaN, +-Inf, zeros, denormals); the self-test
    passes in both builds (its expected outputs chosen by FOGSF_EVEN_TIME)."""
    model = samples.random_model(1, 1, 1, 4, decimation=2, seed=65)
    rng = np.random.default_rng(65)
    x = np.concatenate([rng.normal(0, 3, 4000), rng.uniform(-100, 100, 2000),
                        [0.625, -0.625, 0.62500006, 10.0, -10.0, 87.9, -87.1, 0.0, -0.0,
                         1e-40, -1e-40, np.inf, -np.inf, np.nan]]).astype(np.float32)
    even = Kernel(model, build_kernel(model, root=kroot, even_time=True))
    plain = Kernel(model, build_kernel(model, root=kroot))
    for name in ("exp", "sigmoid", "tanh"):
        assert even.activation(name, x).tobytes() == plain.activation(name, x).tobytes(), name
    for k in (even, plain):
        assert k.lib.fogsf_selftest(k.ffi.new("fogsf_state *"), k.ffi.sizeof("fogsf_state")) == 0


def test_even_time_model_changed_in_ram_is_refused_at_its_next_part(kroot: Path) -> None:
    """A part runs on most samples after a step: the sizes are checked there, so a model
    changed after init is flagged at once (MODEL_CHANGED), with the verified correction
    held (none yet right after init: the gyro as it is) and no part run."""
    model = samples.random_model(2, 4, 1, 8, decimation=20, seed=66)
    even = Kernel(model, build_kernel(model, root=kroot, even_time=True))
    ffi, lib = even.ffi, even.lib
    live = ffi.new("fogsf_model *", even.m[0])
    state = ffi.new("fogsf_state *")
    out = ffi.new("fogsf_output *")
    assert lib.fogsf_init(live, state, ffi.sizeof("fogsf_state")) == 0
    lib.fogsf_step(live, state, 20.0, 10.0, out)  # the step's front; its units follow
    live.hidden = model.hidden + 100
    h_before = bytes(ffi.buffer(state.h))
    lib.fogsf_step(live, state, 20.0, 10.0, out)
    assert (out.corrected_dps, out.sf_ppm, out.flags) == (10.0, 0.0, FLAGS["MODEL_CHANGED"])
    assert bytes(ffi.buffer(state.h)) == h_before and state.part == 0  # no unit ran
