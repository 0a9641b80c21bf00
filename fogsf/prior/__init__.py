"""The design's prior: units of one design as a population (their fits, summaries, the prior,
the MAP and response fits)."""
