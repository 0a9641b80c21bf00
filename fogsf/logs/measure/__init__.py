"""What a log measures: SF windows and metrics, the bias, +/- pairs and plateaus, exact
statistics."""
