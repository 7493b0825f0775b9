"""Benchmarks behind `edgedog bench ...`; results are recorded in docs/BENCHMARKS.md."""
