"""The ``ris-planner`` command line, the top of the package: :func:`main` (:func:`run`, the
entry point) and the parser in :mod:`.app`, one module per group of subcommands, loaded lazily
(docs/reference/cli.md, docs/reference/layers.md). The engine never imports this package."""

from ris_planner.cli.app import build_parser, main, run

__all__ = ["build_parser", "main", "run"]
