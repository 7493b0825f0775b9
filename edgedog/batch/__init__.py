"""Benchmark suites: many training runs from one YAML file, executed here or on a Ray cluster,
gathered into one table (`edgedog batch`)."""
