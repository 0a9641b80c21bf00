"""The default's structure chosen by the training logs: physics nodes or the lag bank, a
hysteresis term."""
