"""The candidate effects diagnose scores: the catalogue and the hysteresis form."""
