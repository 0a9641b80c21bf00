"""Calibration rigs as people build them and the logs they write, with the truth."""
