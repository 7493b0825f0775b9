"""Tools for the project's own upkeep, above the command line they read: `python -m
edgedog.tools.cli_reference` writes docs/CLI.md from the parsers (`make docs`)."""
