"""``ris-planner warmup``: compile and cache every numba kernel once, after installing
(:mod:`ris_planner.planning.warmup`; docs/getting-started.md, "Compiled kernels")."""

from __future__ import annotations

import argparse
import json
import sys

from ris_planner.core.errors import RisPlannerError
from ris_planner.planning.warmup import WarmupError, warm_up


def _cmd_warmup(args: argparse.Namespace) -> int:
    def say(message: str) -> None:
        if not args.quiet:
            print(message, file=sys.stderr)

    try:
        report = warm_up(say)
    except WarmupError as exc:
        raise RisPlannerError(str(exc)) from exc
    if args.json:
        print(json.dumps(report.to_json(), indent=1))
    else:
        total = sum(report.seconds.values())
        say(f"warm-up: {len(report.kernels)} kernels compiled and cached in {total:.1f} s")
        for module, folder in sorted(report.cache_dirs.items()):
            say(f"  {module}: {folder}")
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``warmup`` subcommand."""
    p = sub.add_parser(
        "warmup",
        help="compile and cache every numba kernel now (run once after installing: the first"
        " plan then pays no compilation)",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=_cmd_warmup)
