"""``ris-planner power FILE.json``: uniform vs γ_P vs SDP power allocation (JSON on stdout)."""

from __future__ import annotations

import argparse

from ris_planner.cli.app import add_document_arguments, print_json, read_document
from ris_planner.model.power import OBJECTIVES, SOLVERS
from ris_planner.runtime.progress import ProgressBar


def _cmd_power(args: argparse.Namespace) -> int:
    from ris_planner.io.frames import to_local
    from ris_planner.power.report import run_power  # loads cvxpy: only when the command runs

    result = run_power(
        to_local(read_document(args))[0],  # a geographic frame → local metres
        progress=ProgressBar("power") if args.progress else lambda f, m: None,
        objective=args.objective,
        solver=args.solver,
    )
    print_json(result.to_json())
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``power`` subcommand."""
    p = sub.add_parser(
        "power",
        help="beam power allocation: uniform, best γ_P (DIR+DER) and the SDP of the appendix",
    )
    add_document_arguments(p)
    p.add_argument(
        "--objective",
        choices=OBJECTIVES,
        default="rx",
        help="minimise mean PEB_R² (rx), PEB_T² (tx) or their sum",
    )
    p.add_argument("--solver", choices=SOLVERS, default="CLARABEL", help="SDP solver")
    p.add_argument("--progress", action="store_true", help="progress bar on stderr")
    p.set_defaults(func=_cmd_power)
