"""``ris-planner plan FILE.json [--out DIR] [--scheduler ADDRESS]`` (or ``--preset NAME``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ris_planner.cli import int_in
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
    if args.beams and doc.get("beams") is None:
        doc = {**doc, "beams": {}}  # the default beam settings (PlanDocument.beams)
    local, frame = _local_document(doc)
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    with executor:
        result = run_plan(local, ProgressBar("plan"), executor)
    out = Path(args.out)
    plan = result.to_json()
    if frame is not None:
        plan["frame"] = {"origin": list(frame.origin), "local_crs": frame.proj4}
    plan_path = write_plan_json(plan, out)
    figures = write_figures(result, out)
    figures.update(_gis_files(result, plan, doc, out))
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


def _local_document(doc: dict[str, Any]) -> tuple[dict[str, Any], Any]:
    """The document in local metres and its frame (``ris_planner.io.frames``; only a document
    with a ``frame`` needs the GIS extra)."""
    if "frame" not in doc:
        return doc, None
    from ris_planner.io.frames import to_local

    return to_local(doc)


def _gis_files(
    result: Any, plan: dict[str, Any], doc: dict[str, Any], out: Path
) -> dict[str, Path]:
    """plan.geojson, heatmap.tif, points.csv (``ris_planner.io.export``); skipped with a note
    when the GIS extra is not installed."""
    from ris_planner.io import MissingExtraError

    try:
        from ris_planner.io.export import plan_outputs

        return plan_outputs(result, plan, doc, out)
    except MissingExtraError as exc:
        print(f"note: GIS files skipped: {exc}", file=sys.stderr)
        return {}


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``plan`` subcommand."""
    from ris_planner.planning.presets import PLAN_PRESET_NAMES

    p = sub.add_parser("plan", help="search RIS placements and compare RIS counts")
    p.add_argument("file", nargs="?", help="plan JSON document ('-' for stdin)")
    p.add_argument("--preset", choices=PLAN_PRESET_NAMES, help="use a shipped plan instead")
    p.add_argument(
        "--out",
        default="plan-out",
        help="output folder (plan.json, PNGs, plan.geojson, heatmap.tif, points.csv)",
    )
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786)")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="local worker processes (1–256)"
    )
    p.add_argument(
        "--beams",
        action="store_true",
        help="design DIR/DIR+DER beams from the UE maps and allocate power (γ_P, SDP) for the"
        " best layout of each count (the document's 'beams' settings, default ones if absent)",
    )
    p.set_defaults(func=_cmd_plan)
