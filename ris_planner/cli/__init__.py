"""The ``ris-planner`` command line, the top of the package: one module per group of
subcommands, loaded lazily (docs/reference/cli.md, docs/reference/layers.md). The engine never
imports this package."""
