"""Power-on faults (issue 49, item 3): a first temperature that is not plausible (NaN/Inf, a
DS18B20's 85 C power-on value, beyond the sensor range) primes nothing; the flag
TEMP_UNPRIMED stays up on every sample until a plausible one, the gyro passes as it is (sf 0,
bias 0), and from that sample on the outputs are bit for bit those of a clean start there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import FLAGS, kernel_for

from fogsf.bindings.kernel import Kernel, build_kernel
from fogsf.models import reference, samples
from fogsf.models import stream_flags as sf

UNPRIMED, INVALID = FLAGS["TEMP_UNPRIMED"], FLAGS["TEMP_INVALID"]
NAN = float("nan")


@pytest.fixture(scope="module")
def kroot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("power-on-kernels")


def model_with_heads():  # noqa: ANN201
    return samples.random_model(2, 4, 1, 8, decimation=5, seed=71, stuck_samples=20,
                                poly_head=True, bias_head=True, plays=(((0.5, 0.3, 0.2), 1.5),))


def log(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    temp = np.linspace(18.0, 30.0, n) + rng.normal(0, 0.02, n)
    gyro = 10.0 + rng.normal(0, 0.01, n)
    return temp.astype(np.float32), gyro.astype(np.float32)


STARTS = {  # what a board thermometer gives before its first conversion, and after
    "ds18b20-85C": [85.0] * 7,
    "nan": [NAN] * 4,
    "mixed": [NAN, 85.0, float("inf"), -127.0, 1e30, -float("inf"), 125.5, 85.0, -55.5],
}


@pytest.mark.parametrize("even_time", [False, True], ids=["default", "even-time"])
@pytest.mark.parametrize("start", list(STARTS), ids=list(STARTS))
def test_an_implausible_start_waits_for_a_plausible_temperature(start, even_time, kroot) -> None:
    model = model_with_heads()
    kernel = Kernel(model, build_kernel(model, root=kroot, even_time=even_time))
    head = np.array(STARTS[start], np.float32)
    temp, gyro = log(400, 3)
    temp = np.concatenate([head, temp])
    gyro = np.concatenate([np.full(head.size, 7.5, np.float32), gyro])
    i0 = head.size
    assert reference.first_plausible(temp) == i0
    corrected, sf, bias, flags = kernel.run_bias(temp, gyro)
    # before it: the flag on every sample (with TEMP_INVALID where not finite), no correction
    want_head = np.where(np.isfinite(head), UNPRIMED, UNPRIMED | INVALID)
    assert flags[:i0].tolist() == want_head.tolist()
    assert corrected[:i0].tolist() == [7.5] * i0 and not sf[:i0].any() and not bias[:i0].any()
    # from it: a clean start there, bit for bit, and the flag gone
    clean = kernel.run_bias(temp[i0:], gyro[i0:])
    for got, want in zip((corrected, sf, bias, flags), clean, strict=True):
        assert got[i0:].tobytes() == want.tobytes()
    assert not (flags[i0:] & UNPRIMED).any()
    ref = reference.replay(model, temp, gyro, even_time=even_time)
    assert corrected.tobytes() == ref.corrected_dps.tobytes()
    assert sf.tobytes() == ref.sf_ppm.tobytes() and bias.tobytes() == ref.bias_dph.tobytes()
    assert np.array_equal(flags, ref.flags)


def test_the_error_after_85c_is_that_of_a_clean_start_not_a_primed_85(kroot) -> None:
    """The issue's case: priming every lag at 85 C (clamped to t_max) left -275 ppm at 1 min.
    With the rule the SF after the first plausible sample is the clean start's exactly; a
    kernel primed at the clamped 85 C (what the old kernel did, rebuilt here through the
    reference on the clamped log) is far from it for minutes."""
    model = samples.random_model(3, 4, 1, 16, decimation=10, seed=2026, stuck_samples=0)
    kernel = kernel_for(model, kroot)
    temp, gyro = log(6000, 5)  # 10 min at 10 Hz
    temp85 = np.concatenate([np.float32([85.0]), temp])
    gyro85 = np.concatenate([np.float32([10.0]), gyro])
    _, sf, flags = kernel.run(temp85, gyro85)
    _, sf_clean, _ = kernel.run(temp, gyro)
    assert flags[0] == UNPRIMED and sf[1:].tobytes() == sf_clean.tobytes()
    old = reference.replay_primed(model, temp85, gyro85)  # the filters primed at t_max
    assert old.flags[0] & FLAGS["TEMP_CLAMPED"] and not (old.flags[1:] & UNPRIMED).any()
    assert np.max(np.abs(old.sf_ppm[1:] - sf_clean)) > 1.0  # the prime's error it removes


def test_only_the_first_temperature_is_judged_and_a_reset_judges_again(kroot) -> None:
    """85 C or NaN later in a log is an ordinary sample (clamped, or the last good value
    held); a reset starts the power-on rule over; a stuck 85 C at power-on is not counted as
    a stuck thermometer (the run starts at the first plausible sample)."""
    model = model_with_heads()
    kernel = kernel_for(model, kroot)
    ffi, lib = kernel.ffi, kernel.lib
    temp, gyro = log(200, 9)
    temp[50], temp[60] = 85.0, np.nan
    _, _, flags = kernel.run(temp, gyro)
    assert flags[50] == FLAGS["TEMP_CLAMPED"] and flags[60] == INVALID
    assert not (flags & UNPRIMED).any()
    st = kernel.new_state()
    kernel.run(temp[:30], gyro[:30], st=st)
    assert lib.fogsf_reset(kernel.m, st, ffi.sizeof("fogsf_state")) == 0
    stuck = np.full(model.stuck_samples + 30, 85.0, np.float32)
    _, _, f2 = kernel.run(np.concatenate([stuck, temp]), np.concatenate([stuck, gyro]), st=st)
    assert f2[:stuck.size].tolist() == [UNPRIMED] * stuck.size
    assert not (f2[stuck.size:] & (UNPRIMED | FLAGS["TEMP_STUCK"])).any()


def test_no_plausible_temperature_at_all_keeps_the_flag_and_finite_outputs(kroot) -> None:
    model = model_with_heads()
    kernel = kernel_for(model, kroot)
    temp = np.array([NAN, 85.0, 130.0, -60.0, float("inf")] * 20, np.float32)
    gyro = np.array([1.0, float("nan"), -3.0, float("inf"), 0.0] * 20, np.float32)
    corrected, sf, bias, flags = kernel.run_bias(temp, gyro)
    assert (flags & UNPRIMED).all() and not sf.any() and not bias.any()
    assert np.isfinite(corrected).all()
    bad_gyro = ~np.isfinite(gyro)
    assert (flags[bad_gyro] & FLAGS["GYRO_INVALID"]).all() and not corrected[bad_gyro].any()
    assert corrected[~bad_gyro].tolist() == gyro[~bad_gyro].tolist()


def test_the_reference_holds_the_kernels_flags_and_rule() -> None:
    """stream_flags' values and the power-on rule's constants are the header's."""
    for value, name in sf.FLAG_NAMES.items():
        assert FLAGS[name] == value, name
    header = (Path(__file__).resolve().parents[1] / "firmware" / "c" / "fogsf.h").read_text()
    assert "FOGSF_TEMP_PLAUSIBLE_MIN_C (-55.0f)" in header and sf.PLAUSIBLE_C == (-55.0, 125.0)
    assert "FOGSF_TEMP_PLAUSIBLE_MAX_C 125.0f" in header
    assert "FOGSF_TEMP_POWER_ON_C 85.0f" in header and sf.POWER_ON_C == 85.0
