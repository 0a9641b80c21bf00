"""Planted-effect cases for the diagnose tests and benchmark: drawn, their programs and kinds,
judged."""
