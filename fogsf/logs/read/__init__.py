"""Reading a log file: its dialect, formats (CSV, Parquet, the field's), cells, sampling,
columns on disk."""
