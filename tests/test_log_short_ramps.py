"""A training log whose ramp is too short to count as one (training.interval.transfer
`ramp_segments`: 15 min) is said so on one line naming the minimum, not silently ignored."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from fogsf.cli.arguments import read_logs
from fogsf.logs.chamber_log import ChamberLog
from fogsf.training.interval.transfer import ramp_segments, short_ramps


def _log(ramp_min: float) -> ChamberLog:
    """1 Hz: a 10 min soak at 20 C, a ramp of `ramp_min` minutes at 1 C/min, a soak."""
    t = np.arange(0.0, 3600.0)
    temp = 20.0 + np.clip(t - 600.0, 0.0, ramp_min * 60.0) / 60.0
    one = np.full(t.size, 10.0)
    return ChamberLog(t, temp, one, one * 1.0001, nominal_dt_s=1.0)


def test_a_6_min_ramp_is_said_to_be_too_short() -> None:
    """6 min at 1 C/min: its 5-minute windows move for 13 min, under the 15 a ramp needs."""
    lg = _log(6.0)
    assert ramp_segments(lg) == []  # what training counts: no ramp
    found = short_ramps(lg)
    assert len(found) == 1, found
    text = found[0].text()
    assert "shorter than the 15 min a ramp needs" in text and "20.0 -> 26.0 C" in text, text
    assert 6.0 < found[0].minutes < 15.0 and found[0].rate_c_per_min == 1.0


def test_a_ramp_that_counts_and_a_soak_say_nothing() -> None:
    assert len(ramp_segments(_log(30.0))) == 1 and short_ramps(_log(30.0)) == []
    assert short_ramps(_log(1.0)) == []  # 1 C: a bend, not a ramp


def test_train_says_it_once_on_stderr(tmp_path: Path, capsys) -> None:
    lg = _log(6.0)
    p = tmp_path / "short.csv"
    rows = [f"{lg.time_s[i]:.1f},{lg.temp_c[i]:.4f},10,10.001,0.00234" for i in range(len(lg))]
    p.write_text("time_s,temp_c,table_rate_dps,gyro_dps,earth_rate_dps\n"
                 + "\n".join(rows) + "\n")
    read_logs(argparse.Namespace(train=[str(p)]), [str(p)], training=True)
    err = [ln for ln in capsys.readouterr().err.splitlines() if "a ramp needs" in ln]
    assert len(err) == 1 and err[0].startswith(f"fogsf: note: {p}: "), err
    read_logs(argparse.Namespace(log=str(p)), [str(p)])  # not training: not said
    assert "a ramp needs" not in capsys.readouterr().err
