"""``ris-planner city FILE.json --cell-m M [--out DIR] [--scheduler ADDRESS | --workers N]``:
a city plan document cut into districts on a square grid, each planned by the district search
on the executor (docs/concepts/district.md, "A city")."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ris_planner.cli.app import int_in


def _cmd_city(args: argparse.Namespace) -> int:
    from ris_planner.io.frames import to_local
    from ris_planner.planning.city import plan_city, split_city
    from ris_planner.planning.inputs.presets import load_plan_file
    from ris_planner.runtime.executor import DaskExecutor, Executor, LocalExecutor
    from ris_planner.runtime.progress import ProgressBar

    local, frame = to_local(load_plan_file(args.file))
    districts = split_city(local, args.cell_m)
    print(f"{len(districts)} districts of {args.cell_m:g} m", file=sys.stderr)
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    with executor:
        plan = plan_city(districts, executor, ProgressBar("city"))
    if frame is not None:
        plan["frame"] = frame.describe()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "plan.json"
    path.write_text(json.dumps(plan, indent=1) + "\n")
    print(f"wrote {path}", file=sys.stderr)
    for row in plan["by_count"]:
        print(
            f"{row['ris_per_district']} RIS per district ({row['ris_total']} in all): coverage"
            f" {row['coverage']:.3g}, certified ≤ {row['upper_bound']:.3g}"
        )
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``city`` subcommand."""
    p = sub.add_parser("city", help="plan a city as independent districts (district search)")
    p.add_argument("file", help="plan JSON document of the whole city ('-' for stdin)")
    p.add_argument("--cell-m", type=float, required=True, help="district cell size [m]")
    p.add_argument("--out", default="city-out", help="output folder (plan.json)")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786)")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="local worker processes (1–256)"
    )
    p.set_defaults(func=_cmd_city)
