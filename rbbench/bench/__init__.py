"""Benchmarking: run matrices, the runner and executors' shared case execution, the results
row schema, results loading, reports and comparisons."""
