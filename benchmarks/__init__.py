"""Benchmarks: each reports wall time beside an error measure, measured in the same run."""
