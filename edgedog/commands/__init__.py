"""Sub-commands of the `edgedog` command line.

Each module exposes `add_parser(subparsers)`, which registers the command and sets
`run(args) -> int | None` as the parser's default `run`.
"""
