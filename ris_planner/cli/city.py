"""``ris-planner city FILE.json --cell-m M [--out DIR] [--scheduler ADDRESS | --workers N]``:
a city plan document planned as one map – its pairs drawn once over the whole city, its cells
planned by the district search on the executor, one plan.json, plan.geojson, heatmap.tif and
points.csv for the city (docs/concepts/district.md, "A city")."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ris_planner.cli.app import int_in


def _cmd_city(args: argparse.Namespace) -> int:
    from ris_planner.io.cityplan import admit_city, plan_city_document
    from ris_planner.planning.city import city_summary
    from ris_planner.planning.inputs.presets import load_plan_file
    from ris_planner.runtime.executor import DaskExecutor, Executor, LocalExecutor
    from ris_planner.runtime.progress import ProgressBar

    request = admit_city(load_plan_file(args.file), args.cell_m)
    city = request.city
    print(
        f"{len(city.cells)} cells of {args.cell_m:g} m ({len(city.planned)} with candidates),"
        f" {city.pairs.size} pairs, {int(city.border.sum())} across a cell border",
        file=sys.stderr,
    )
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    done = plan_city_document(request, out, executor, ProgressBar("city"))
    path = out / "plan.json"
    path.write_text(json.dumps(done.plan, indent=1) + "\n")
    print(f"wrote {path}", file=sys.stderr)
    for name, file in done.files.items():
        print(f"wrote {name}: {file}", file=sys.stderr)
    if done.note:
        print(f"no GIS files: {done.note}", file=sys.stderr)
    print("\n".join(city_summary(done.plan)))
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``city`` subcommand."""
    p = sub.add_parser(
        "city", help="plan a city as one map: cells planned by the district search, stitched"
    )
    p.add_argument("file", help="plan JSON document of the whole city ('-' for stdin)")
    p.add_argument("--cell-m", type=float, required=True, help="cell size [m]")
    p.add_argument(
        "--out",
        default="city-out",
        help="output folder (plan.json, plan.geojson, heatmap.tif, points.csv)",
    )
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786)")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="local worker processes (1–256)"
    )
    p.set_defaults(func=_cmd_city)
