"""Measurements: the benchmarks behind `edgedog bench ...` (results recorded in
docs/BENCHMARKS.md), detector calibration behind `edgedog calibrate-detector` (`calibrate`), and
the studio's frame rate while it trains (`python -m edgedog.bench.studio`)."""
