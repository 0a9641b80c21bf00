"""Compensation models: the streaming artifact and its numpy reference, features, torch
networks; the structures (`structures`: physics nodes, the lag bank, least squares,
hysteresis)."""
