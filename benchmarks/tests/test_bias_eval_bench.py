"""`benchmarks.bias_eval`'s own checks: a case's score and the interval it reports (moved
from tests/test_bias_model.py: the library's tests import no bench)."""

from __future__ import annotations

from pathlib import Path
from tempfile import TemporaryDirectory

from benchmarks.bias_eval import one


def test_the_bias_interval_is_not_the_most_flexible_fits_distance() -> None:
    """Reversals from a loop with a fast down-ramp (development gyro 1, its population bias):
    the bank fits the training pairs best and extrapolates worst; the interval's family is
    the structures as good on held-out blocks, with the chosen one, so its top stays near
    the test's actual RMS (before: the bank's distance alone, 6 x it) and still holds it."""
    with TemporaryDirectory() as tmp:
        r = one(1, "reversals-fast", None, Path(tmp))
    iv = r["interval"]
    assert r["structure"]["chosen"] in iv["consistent"]
    lo, hi = iv["rms_interval_dph"]
    assert lo <= r["after_rms_dph"] <= hi <= 2.0 * r["after_rms_dph"], (lo, r["after_rms_dph"], hi)
