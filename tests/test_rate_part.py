"""The streaming model's optional rate part (docs/stream-contract.md, "Optional rate part"):
the artifact's keys and refusals, and the numpy reference against the formula in double."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.models import reference
from fogsf.models.rate_part import apply_rate, inverse_full_scale, rate_coefficients
from fogsf.models.samples import chamber_ramp, random_model
from fogsf.models.stream import StreamModel
from fogsf.models.stream_flags import FLAG_GYRO_INVALID, FLAG_RATE_CLAMPED


def _inputs(n_hours: float = 0.2, top_dps: float = 160.0) -> tuple[np.ndarray, np.ndarray]:
    """A ramp's temperatures and a gyro sweeping +-top_dps (past a 150 deg/s full scale)."""
    temp, gyro = chamber_ramp(n_hours, seed=3)
    sweep = top_dps * np.sin(np.arange(temp.size) / 400.0)
    return temp, gyro / 10.0 * sweep


@pytest.mark.parametrize("rows,coefs", [(1, 1), (2, 3), (8, 3), (9, 2)])
def test_save_and_load_keep_the_part_and_its_id(rows: int, coefs: int, tmp_path: Path) -> None:
    m = random_model(rate_part=(rows, coefs), bias_head=True)
    back = StreamModel.load(m.save(tmp_path / "m"))
    assert back.rate_fs_dps == 150.0 and back.model_id == m.model_id
    assert np.array_equal(back.weights["rate_w"], m.weights["rate_w"])
    assert "rate part" in back.summary


def test_a_model_without_the_part_writes_no_key_and_keeps_its_id() -> None:
    plain, with_part = random_model(), random_model(rate_part=(3, 2))
    assert "rate_fs_dps" not in plain.config() and not plain.has_rate_part
    assert plain.model_id != with_part.model_id
    weights = {k: v for k, v in with_part.weights.items() if k != "rate_w"}
    assert replace(with_part, weights=weights, rate_fs_dps=0.0).model_id == plain.model_id


@pytest.mark.parametrize("change,says", [
    (dict(rate_fs_dps=0.0), "holds rate_w but stream.json has no rate_fs_dps"),
    (dict(rate_fs_dps=-1.0), "must be a full scale"),
    (dict(rate_fs_dps=float("nan")), "must be a full scale"),
    (dict(rate_fs_dps=2e4), "must be a full scale"),
    (dict(rate_w=np.zeros((10, 1), np.float32)), "expected [R, Q]"),
    (dict(rate_w=np.zeros((2, 4), np.float32)), "expected [R, Q]"),
    (dict(rate_w=np.zeros(3, np.float32)), "expected [R, Q]"),
    (dict(rate_w=None), "lacks array rate_w"),
    (dict(rate_w=np.full((2, 1), np.inf, np.float32)), "NaN or Inf"),
])
def test_a_broken_part_is_refused_in_one_message(change: dict, says: str) -> None:
    m = random_model(rate_part=(2, 1))
    weights = dict(m.weights)
    if "rate_w" in change:
        if change["rate_w"] is None:
            del weights["rate_w"]
        else:
            weights["rate_w"] = change["rate_w"]
    fs = change.get("rate_fs_dps", m.rate_fs_dps)
    with pytest.raises(UserError) as e:
        replace(m, weights=weights, rate_fs_dps=fs).validate()
    assert says in str(e.value)


def test_the_reference_is_the_formula_in_double_within_float32_rounding() -> None:
    """e = a_0 |x| + sum a_r x^(r+1), a_r polynomials of s0; x clamped at full scale and
    flagged; the float32 reference within a few float32 ulps of FS of the formula."""
    m = random_model(rate_part=(6, 3), bias_head=True, decimation=7)
    plain = replace(m, weights={k: v for k, v in m.weights.items() if k != "rate_w"},
                    rate_fs_dps=0.0)
    temp, gyro = _inputs()
    got, before = reference.replay(m, temp, gyro), reference.replay(plain, temp, gyro)
    c = before.corrected_dps
    x = np.clip(c / 150.0, -1.0, 1.0)
    s0 = reference.frontend(temp, m.front_end).s[:, 0].astype(np.float64)
    w = m.weights["rate_w"].astype(np.float64)
    a = np.stack([np.polynomial.polynomial.polyval(s0, w[r]) for r in range(6)], 1)
    a = reference.expand(a, temp.size, m.decimation)
    e = a[:, 0] * np.abs(x) + sum(a[:, r] * x ** (r + 1) for r in range(1, 6))
    assert np.max(np.abs(got.corrected_dps - (c - e))) < 150.0 * 3e-7
    beyond = np.abs(c) > 150.0
    assert beyond.any() and np.array_equal((got.flags & FLAG_RATE_CLAMPED) != 0, beyond)
    assert np.array_equal(got.flags & ~np.uint32(FLAG_RATE_CLAMPED), before.flags)


def test_zero_coefficients_change_no_bit_and_bad_samples_pass_as_zero() -> None:
    m = random_model(rate_part=(4, 2))
    zero = replace(m, weights={**m.weights, "rate_w": np.zeros((4, 2), np.float32)})
    plain = replace(m, weights={k: v for k, v in m.weights.items() if k != "rate_w"},
                    rate_fs_dps=0.0)
    temp, gyro = _inputs(top_dps=140.0)
    gyro[[5, 900]] = [np.nan, np.inf]
    a, b = reference.replay(zero, temp, gyro), reference.replay(plain, temp, gyro)
    assert np.array_equal(a.corrected_dps.view(np.int64), b.corrected_dps.view(np.int64))
    got = reference.replay(m, temp, gyro)
    assert got.corrected_dps[5] == 0.0 and got.flags[900] & FLAG_GYRO_INVALID


def test_even_time_holds_no_rate_correction_before_the_first_step_publishes() -> None:
    m = random_model(rate_part=(3, 2), decimation=10)
    temp, gyro = _inputs(top_dps=100.0)
    late = reference.replay(m, temp, gyro, even_time=True)
    assert np.array_equal(late.corrected_dps[:10], gyro[:10].astype(np.float32))


def test_coefficients_are_horner_in_s0_and_one_row_is_the_abs_term_alone() -> None:
    m = random_model(rate_part=(1, 3))
    s0 = np.array([-20.0, 0.0, 15.5], np.float32)
    w = m.weights["rate_w"][0]
    want = [(w[2] * s + w[1]) * s + w[0] for s in s0]
    assert np.array_equal(rate_coefficients(m, s0)[:, 0], np.array(want, np.float32))
    c = np.array([-75.0, 0.0, 300.0], np.float32)
    a = np.ones((3, 1), np.float32)
    out, flags = apply_rate(m, c, a, np.zeros(3, np.uint32))
    x = np.clip(c * inverse_full_scale(m), -1, 1)
    assert np.array_equal(out, c - np.abs(x)) and flags.tolist() == [0, 0, FLAG_RATE_CLAMPED]
