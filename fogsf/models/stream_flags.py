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
FLAG_TEMP_UNPRIMED = 128  # no plausible temperature yet since reset: the gyro passes as it is
FLAG_MODEL_CHANGED = 256  # the kernel's run-time check found the model changed since init
FLAG_CALL_INVALID = 512  # a NULL pointer or a state of another size (C only)
FLAG_SELFTEST_FAILED = 1024  # init's self-test failed (C only, FOGSF_SELFTEST_AT_INIT)
FLAG_RATE_CLAMPED = 2048  # |corrected| beyond the rate part's full scale: its edge value used
FLAG_NAMES = {FLAG_TEMP_INVALID: "TEMP_INVALID", FLAG_TEMP_CLAMPED: "TEMP_CLAMPED",
              FLAG_TEMP_STUCK: "TEMP_STUCK", FLAG_GYRO_INVALID: "GYRO_INVALID",
              FLAG_SF_CLAMPED: "SF_CLAMPED", FLAG_BIAS_CLAMPED: "BIAS_CLAMPED",
              FLAG_TEMP_UNPRIMED: "TEMP_UNPRIMED", FLAG_MODEL_CHANGED: "MODEL_CHANGED",
              FLAG_CALL_INVALID: "CALL_INVALID", FLAG_SELFTEST_FAILED: "SELFTEST_FAILED",
              FLAG_RATE_CLAMPED: "RATE_CLAMPED"}
# The power-on rule (fogsf.h): the filters prime from the first temperature that is finite,
# within PLAUSIBLE_C and not a DS18B20's power-on value (a bad first reading primes nothing)
PLAUSIBLE_C = (-55.0, 125.0)
POWER_ON_C = 85.0
SF_LIMIT_PPM = 1.0e5  # |predicted SF error| beyond 10 % is a broken model, never a gyro
BIAS_LIMIT_DPH = 3.6e4  # |predicted bias| beyond 10 deg/s is a broken model
