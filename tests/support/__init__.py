"""Helpers shared by several test files (``tests/`` is on pytest's ``pythonpath``: import them
as ``support.<module>``)."""
