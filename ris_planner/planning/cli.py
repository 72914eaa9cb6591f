"""``ris-planner plan FILE.json [--out DIR] [--scheduler ADDRESS]`` (or ``--preset NAME``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ris_planner.errors import RisPlannerError


def _cmd_plan(args: argparse.Namespace) -> int:
    from ris_planner.planning.executor import DaskExecutor, Executor, LocalExecutor
    from ris_planner.planning.plan import run_plan
    from ris_planner.planning.presets import load_plan_file, plan_preset
    from ris_planner.planning.report import write_figures, write_plan_json
    from ris_planner.progress import ProgressBar

    if (args.file is None) == (args.preset is None):
        raise RisPlannerError("give exactly one of FILE or --preset NAME")
    doc = plan_preset(args.preset) if args.preset is not None else load_plan_file(args.file)
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    with executor:
        result = run_plan(doc, ProgressBar("plan"), executor)
    out = Path(args.out)
    plan = result.to_json()
    plan_path = write_plan_json(plan, out)
    figures = write_figures(result, out)
    print(f"wrote {plan_path}", file=sys.stderr)
    for p in figures.values():
        print(f"wrote {p}", file=sys.stderr)
    for entry in plan["by_count"]:
        print(
            f"{entry['ris_count']} RIS: sites {entry['sites']} objective {entry['objective']}"
            f" ({entry['method']}, {entry['layouts_evaluated']}/{entry['layouts_total']} layouts)"
        )
    if "decision" in plan:
        print(f"decision: {plan['decision']['message']}")
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``plan`` subcommand."""
    from ris_planner.planning.presets import PLAN_PRESET_NAMES

    p = sub.add_parser("plan", help="search RIS placements and compare RIS counts")
    p.add_argument("file", nargs="?", help="plan JSON document ('-' for stdin)")
    p.add_argument("--preset", choices=PLAN_PRESET_NAMES, help="use a shipped plan instead")
    p.add_argument("--out", default="plan-out", help="output folder (plan.json, PNGs)")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes")
    p.set_defaults(func=_cmd_plan)
