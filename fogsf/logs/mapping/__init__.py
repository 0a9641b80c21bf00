"""The column map: our columns from a log's own (renames, expressions, joins of several
files)."""
