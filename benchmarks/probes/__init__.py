"""One-off probes: each reproduces the evidence behind one default (docs/decisions.md)."""
