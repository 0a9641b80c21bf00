"""`benchmarks.firmware_bench`'s own checks: the image rows of `make bench` (moved from
tests/test_firmware_cmake.py: the library's tests import no bench)."""

from __future__ import annotations

import pytest

from benchmarks.firmware_bench import IMAGE_TARGET, bench_image, small_poly_models
from fogsf.bindings.firmware import arm_tools_missing


@pytest.mark.slow
@pytest.mark.skipif(arm_tools_missing() is not None, reason=f"{arm_tools_missing()}")
@pytest.mark.parametrize("filters,extras", [(1, {}), (11, {}),
                                             (11, {"bias_head": True, "own": 1}),
                                             (11, {"bias_head": True, "play": True}),
                                             (11, {"bias_head": True, "full_quad": True}),
                                             (11, {"selftest": True})],
                         ids=["one-feature", "lag-bank-default-form",
                              "default-form-lead-bias-head", "default-form-bias-head-play",
                              "default-form-full-quad-bias-head",
                              "default-form-with-fogsf_selftest"])
def test_three_small_models_in_one_image_meet_the_size_target(filters, extras,
                                                               tmp_path) -> None:
    """make bench's image rows: three 1x16 poly-head models <= 24 KB flash, <= 1.5 KB RAM,
    one-feature models, the default model's shape (the lag bank: 12 features, a diagonal
    feature map, the LSTM on z[0:BANK_LSTM_INPUTS], a diagonal quadratic), and its largest
    forms: a bias head with `lead`'s own filter (whose feature keeps the full feat_w), a
    bias head and a hysteresis play (a model with a play leaves `lead` out), or a bias head
    and the full 12 x 12 quadratic; and the default shape with the power-on self-test
    linked; the three-model image costs more than the one-model image (the figures are
    measured)."""
    selftest = bool(extras.pop("selftest", False))
    one = bench_image(small_poly_models(1, filters, **extras), tmp_path, f"k{filters}",
                      selftest=selftest)
    three = bench_image(small_poly_models(3, filters, **extras), tmp_path, f"k{filters}",
                        selftest=selftest)
    assert three["flash_bytes"] <= IMAGE_TARGET["flash_bytes"], three
    assert three["ram_bytes"] <= IMAGE_TARGET["ram_bytes"], three
    assert three["flash_bytes"] > one["flash_bytes"] and three["ram_bytes"] > one["ram_bytes"]
    assert three["instructions_per_sample_worst"] > 2 * one["instructions_per_sample_worst"]
