"""Training: fit a model on chamber logs, score it on a test log, the rate-transfer interval."""
