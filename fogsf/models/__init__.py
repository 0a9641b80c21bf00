"""Compensation models: the streaming artifact and its numpy reference, features, the
lag bank, least squares, torch networks."""
