"""The bias part of a model: its features and targets, its structure, its fit and interval,
stationary logs."""
