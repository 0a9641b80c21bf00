"""Chamber programs and rate-table schedules."""

from __future__ import annotations

import numpy as np
import pytest

from fogsf.errors import UserError
from fogsf.logs.measure.plateaus import plateaus
from fogsf.sim.config import ProfileConfig, TableConfig
from fogsf.sim.profiles import breakpoints, chamber_series, read_program, table_series


def test_soak() -> None:
    t, c = chamber_series(ProfileConfig(kind="soak", start_c=15.0, duration_s=600.0), 0.1)
    assert t[-1] == pytest.approx(600.0) and len(t) == 6001
    assert np.all(c == 15.0)


@pytest.mark.parametrize("a,b,rate", [(-40.0, 50.0, 1.0), (50.0, -40.0, 0.5), (0.0, 3.0, 7.5)])
def test_ramp_up_or_down_at_any_rate_with_soaks(a: float, b: float, rate: float) -> None:
    p = ProfileConfig(kind="ramp", start_c=a, stop_c=b, rate_c_per_min=rate,
                      soak_before_s=120.0, soak_after_s=300.0)
    t, c = chamber_series(p, 0.1)
    ramp_s = abs(b - a) / rate * 60.0
    assert t[-1] == pytest.approx(120.0 + ramp_s + 300.0, abs=0.1)
    assert np.all(c[t <= 120.0] == a) and np.all(c[t >= 120.0 + ramp_s + 1e-6] == b)
    mid = (t > 130.0) & (t < 110.0 + ramp_s)
    slope = np.diff(c[mid]) / 0.1 * 60.0
    np.testing.assert_allclose(slope, np.sign(b - a) * rate, rtol=1e-6)


def test_total_length_cuts_or_holds_a_program() -> None:
    p = ProfileConfig(kind="ramp", start_c=0.0, stop_c=10.0, rate_c_per_min=1.0,
                      total_s=300.0)
    t, c = chamber_series(p, 0.1)
    assert t[-1] == pytest.approx(300.0) and c[-1] == pytest.approx(5.0)
    p.total_s = 1200.0
    t, c = chamber_series(p, 0.1)
    assert t[-1] == pytest.approx(1200.0) and np.all(c[t >= 600.0] == 10.0)


def test_up_down_cycle() -> None:
    p = ProfileConfig(kind="cycle", start_c=-10.0, stop_c=30.0, rate_c_per_min=2.0,
                      soak_s=600.0, cycles=2)
    bp = breakpoints(p)
    temps = bp[:, 1].tolist()
    assert temps == [-10.0, 30.0, 30.0, -10.0, -10.0, 30.0, 30.0, -10.0, -10.0]
    assert bp[-1, 0] == pytest.approx(4 * (1200.0 + 600.0))


def test_steps_with_soaks() -> None:
    p = ProfileConfig(kind="steps", levels_c=[-20.0, 0.0, 25.0], rate_c_per_min=5.0,
                      soak_s=900.0)
    t, c = chamber_series(p, 0.1)
    for level in (-20.0, 0.0, 25.0):
        assert np.sum(c == level) * 0.1 == pytest.approx(900.0, abs=0.3)
    assert t[-1] == pytest.approx(3 * 900.0 + (20.0 + 25.0) / 5.0 * 60.0, abs=0.1)


def test_program_from_csv(tmp_path) -> None:
    path = tmp_path / "chamber.csv"
    path.write_text("time_s,temp_c\n0,20\n600,20\n1800,-10\n2400,-10\n")
    p = ProfileConfig(kind="program", points=read_program(path))
    t, c = chamber_series(p, 0.1)
    assert t[-1] == pytest.approx(2400.0)
    assert c[np.searchsorted(t, 1200.0)] == pytest.approx(5.0)
    assert c[-1] == -10.0


def test_program_refusals(tmp_path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,temp_c\n0,20\n10,abc\n")
    with pytest.raises(UserError, match="line 3"):
        read_program(bad)
    bad.write_text("0,20\n")
    with pytest.raises(UserError, match="at least two"):
        read_program(bad)
    with pytest.raises(UserError, match="increasing"):
        breakpoints(ProfileConfig(kind="program", points=[[0, 1], [0, 2]]))
    with pytest.raises(UserError, match="-60..100"):
        chamber_series(ProfileConfig(kind="program", points=[[0, 20], [100, 120]]), 0.1)
    with pytest.raises(UserError, match="rate"):
        breakpoints(ProfileConfig(kind="ramp", rate_c_per_min=0.0))


def test_table_schedules() -> None:
    t = np.arange(6000) * 0.1
    assert np.all(table_series(TableConfig(kind="constant", rate_dps=-5.0), t) == -5.0)
    alt = table_series(TableConfig(kind="alternating", rate_dps=10.0, dwell_s=100.0), t)
    pl = plateaus(alt)
    assert [b - a for a, b in pl] == [1000] * 6
    assert [alt[a] for a, _ in pl] == [10.0, -10.0] * 3
    lv = table_series(TableConfig(kind="levels", rates_dps=[10.0, 50.0, -100.0],
                                  dwell_s=200.0), t)
    assert [lv[a] for a, _ in plateaus(lv)] == [10.0, 50.0, -100.0]
    with pytest.raises(UserError, match="non-zero"):
        table_series(TableConfig(kind="levels", rates_dps=[10.0, 0.0]), t)
    with pytest.raises(UserError, match="rates_dps"):
        table_series(TableConfig(kind="levels", rates_dps=[]), t)
