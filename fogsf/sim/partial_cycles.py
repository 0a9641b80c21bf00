"""Partial-cycle chamber programs: temperature reversals that do not go end to end.

Rate-independent hysteresis (a play operator of the coil temperature, the simulator's
`hysteresis` effect) shows where the temperature turns back inside the range and where it
holds (a soak keeps the play's value): a ramp from end to end, or a full cycle, visits each
temperature from one side per direction only. These programs turn back at inner points with
a soak at every turn, so a model can learn (training) and be tested on (testing) minor
loops. The two use different turning points, rates and soaks, so a test on `PARTIAL_TEST`
after training on `PARTIAL_TRAIN` is a test on loops the training log does not hold. Both
span -40..50 C, so the static law is covered end to end.
"""

from __future__ import annotations

from dataclasses import dataclass

from fogsf.sim.config import ProfileConfig


@dataclass(frozen=True)
class PartialCycle:
    """A program: start at turns_c[0] and soak, then ramp to each turn, soaking there; the
    legs take the rates of `rates_c_per_min` in turn."""

    name: str
    turns_c: tuple[float, ...]
    rates_c_per_min: tuple[float, ...]
    soak_s: float
    first_soak_s: float = 1800.0

    def points(self) -> list[list[float]]:
        pts = [[0.0, self.turns_c[0]], [self.first_soak_s, self.turns_c[0]]]
        for i, temp in enumerate(self.turns_c[1:]):
            rate = self.rates_c_per_min[i % len(self.rates_c_per_min)]
            t = pts[-1][0] + abs(temp - pts[-1][1]) / rate * 60.0
            pts.append([t, temp])
            pts.append([t + self.soak_s, temp])
        return pts

    def profile(self) -> ProfileConfig:
        return ProfileConfig(kind="program", points=self.points())

    @property
    def hours(self) -> float:
        return self.points()[-1][0] / 3600.0


# training: legs at 2 and 0.75 C/min in turn (two rates pin the thermal lags), 15 min soaks
# at each turn (6.3 h)
PARTIAL_TRAIN = PartialCycle("partial_train", (-40.0, 15.0, -10.0, 50.0, 5.0, 30.0, -40.0),
                             (2.0, 0.75), 900.0)
# testing: 1 C/min, 20 min soaks, other turns (5.8 h)
PARTIAL_TEST = PartialCycle("partial_test", (-30.0, 25.0, -5.0, 45.0, 10.0, -40.0),
                            (1.0,), 1200.0)
PROGRAMS = {p.name: p for p in (PARTIAL_TRAIN, PARTIAL_TEST)}
