"""The streaming model's status flags, one bit each with the values of the C kernel's
FOGSF_FLAG_*, and the limits beyond which a model's SF or bias output is broken and clamped
(docs/stream-contract.md)."""

from __future__ import annotations

# Status flags, one bit each (the C kernel's FOGSF_FLAG_* have the same values).
FLAG_TEMP_INVALID = 1  # temperature not finite: last good value (or t_ref) used
FLAG_TEMP_CLAMPED = 2  # temperature outside [t_min, t_max]: clamped
FLAG_TEMP_STUCK = 4  # raw temperature bitwise unchanged for >= stuck_samples samples
FLAG_GYRO_INVALID = 8  # gyro input (or corrected output) not finite: corrected = 0.0
FLAG_SF_CLAMPED = 16  # model output not finite or beyond +-SF_LIMIT_PPM: clamped
FLAG_BIAS_CLAMPED = 64  # bias head output not finite or beyond +-BIAS_LIMIT_DPH: clamped
FLAG_NAMES = {FLAG_TEMP_INVALID: "TEMP_INVALID", FLAG_TEMP_CLAMPED: "TEMP_CLAMPED",
              FLAG_TEMP_STUCK: "TEMP_STUCK", FLAG_GYRO_INVALID: "GYRO_INVALID",
              FLAG_SF_CLAMPED: "SF_CLAMPED", FLAG_BIAS_CLAMPED: "BIAS_CLAMPED"}
SF_LIMIT_PPM = 1.0e5  # |predicted SF error| beyond 10 % is a broken model, never a gyro
BIAS_LIMIT_DPH = 3.6e4  # |predicted bias| beyond 10 deg/s is a broken model
