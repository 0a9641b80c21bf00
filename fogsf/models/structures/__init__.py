"""Compensation structures: physics nodes, chain nodes, the lag bank, least squares,
hysteresis."""
