"""The FOG-in-a-chamber physics simulator.

Stages, each a pure numpy function that works on whole arrays (so `diagnose` can fit them):

- `profiles`: the chamber program and the rate-table schedule -> time series.
- `thermal`: chamber air -> housing -> board, preamp, coil inner/outer, source (first-order
  lags, exact discretisation, self-heating, warm start or power-on).
- `scale_factor`: K = 2*pi*L*D / (Km*K_DA*lambda*c) from the node temperatures, in ppm.
- `effects`: optional named effects (`--effect NAME=STRENGTH`), each adding its own term.
- `gyro`: bias, angle random walk, output pulse quantization, thermometers; `simulate()`.
- `config`: the dataclass configuration that round-trips through JSON.
- `scenarios`: named configurations, e.g. the paper's protocol.
- `rigs`: calibration rigs' protocols (reversals, staircases, slewing and stalling tables,
  bang-bang set points, skew-mounted IMUs) written in their log conventions, with the truth.
"""

from fogsf.sim.config import SimConfig
from fogsf.sim.gyro import SimResult, simulate

__all__ = ["SimConfig", "SimResult", "simulate"]
