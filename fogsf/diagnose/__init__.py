"""fogsf diagnose: confront a physics model of the gyro with measured chamber logs.

Stages (one small module each):

- `runs`: chamber logs -> per-window observations (apparent SF, noise, temperatures, rate).
- `driver`: the housing temperature that drives the internal thermal nodes, identified from
  the chamber air and the board thermometer (first-order lags, profiled on a grid).
- `design`: the columns of the base model and of each catalogue effect, per window.
- `effects.catalogue`: the candidate effects (the simulator's seven), their columns, grids, units.
- `profile_ls`: weighted linear least squares, profiled over grids of time constants.
- `crossval`: held-out residuals by leaving out contiguous blocks (or whole runs).
- `stats`: whiteness (Ljung-Box), the structured share of a residual, paired sign-flip
  tests, correlations, intervals.
- `fits`: a fitted model with its held-out residuals, and the records of a diagnosis.
- `intervals`: profiled parameters of a candidate: refinement, intervals, reported values.
- `selection`: score each candidate against the base on held-out blocks, and choose among
  them (significance, third node, nesting, ambiguity, forward selection).
- `verdict`: fit, score every candidate on held-out data, name the cause or none (entry
  point `diagnose`).
- `extend`: the fitted, extended model as a simulator configuration, and its distance
  to the measured logs.
- `report`: the JSON of docs/diagnose.md and a Markdown report with plots.
- `effects.hysteresis_form`: the play (backlash) form of a coil temperature.
- `cases`: planted-effect cases (simulated) for the tests and `benchmarks.diagnose_rate`;
  `cases.programs` their chamber programs and tables, `cases.kinds` the coil bias on a log
  pair and the source mode hop, `cases.judge` whether a diagnosis got a case right.
"""
