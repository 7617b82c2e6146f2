"""Diagnostics of the machine behind measured figures (not asv benchmarks): README.md."""
