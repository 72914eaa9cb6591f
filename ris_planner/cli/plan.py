"""``ris-planner plan FILE.json [--out DIR] [--scheduler ADDRESS]`` (or ``--preset NAME``).

A plan whose diagnosis is not ``ok`` prints a WARNING block on stderr and still exits 0;
with ``--fail-on-useless`` a ``useless`` plan exits :data:`EXIT_USELESS` (3) after writing
its files (docs/concepts/diagnosis.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ris_planner.cli.app import int_in, launched_as_process
from ris_planner.core.errors import RisPlannerError

if TYPE_CHECKING:
    from ris_planner.planning.figure_process import FigureProcess

EXIT_USELESS = 3
"""Exit status of ``ris-planner plan --fail-on-useless`` for a plan diagnosed ``useless``."""


def rounded(value: float | None, digits: int = 3) -> str:
    """A human-readable number: ``digits`` significant digits (``0.116``, not
    ``0.11600000000000002``); ``None`` (an infinite value in plan.json) is ``inf``."""
    return "inf" if value is None else f"{value:.{digits}g}"


def _searched(entry: dict[str, Any]) -> str:
    """The objective of one count's entry and how it was searched: the layouts scored, or the
    district search's certified upper bound and gap."""
    value = rounded(entry["objective"])
    if entry["method"] == "district":
        return (
            f"objective {value} (district, certified ≤ {rounded(entry['upper_bound'])},"
            f" gap {rounded(entry['gap'])})"
        )
    return (
        f"objective {value} ({entry['method']},"
        f" {entry['layouts_evaluated']}/{entry['layouts_total']} layouts)"
    )


def listed_lines(diagnosis: dict[str, Any], plan_path: Path) -> list[str]:
    """Where the candidates a cause counts are listed (the ``blocked`` cause of a plan with
    hundreds of them): one line per such cause naming plan.json's member, never the names –
    the cause's message counts them and gives a few examples."""
    if diagnosis["verdict"] == "ok":
        return []
    return [
        f"    the {len(c['candidates'])} candidates of '{c['kind']}', each with why:"
        f" {plan_path} → diagnosis.causes[{k}].candidates"
        for k, c in enumerate(diagnosis["causes"])
        if c.get("candidates")
    ]


def _cmd_plan(args: argparse.Namespace) -> int:
    if (args.file is None) == (args.preset is None):
        raise RisPlannerError("give exactly one of FILE or --preset NAME")
    from ris_planner.planning.figure_process import FigureProcess

    # started first: it imports matplotlib while this process reads the document and searches
    with FigureProcess() as figures:
        return _plan(args, figures)


def _plan(args: argparse.Namespace, figures: FigureProcess) -> int:
    from ris_planner.io.estimates import document_estimate, plan_measured
    from ris_planner.planning.inputs.presets import load_plan_file, plan_preset
    from ris_planner.planning.outputs.diagnosis import summary_lines
    from ris_planner.planning.outputs.report import write_plan_json
    from ris_planner.runtime.executor import DaskExecutor, Executor, LocalExecutor
    from ris_planner.runtime.process import process_age_s
    from ris_planner.runtime.progress import ProgressBar

    doc = plan_preset(args.preset) if args.preset is not None else load_plan_file(args.file)
    if args.nested:
        doc = {**doc, "rollout": "nested"}
    if args.beams and doc.get("beams") is None:
        doc = {**doc, "beams": {}}  # the default beam settings (PlanDocument.beams)
    if args.validate is not None:  # the document's validation settings, N pairs
        doc = {**doc, "validation": {**(doc.get("validation") or {}), "pairs": args.validate}}
    if args.sizing and doc.get("sizing") is None:
        doc = {**doc, "sizing": {}}  # the default ladder and target (PlanDocument.sizing)
    out = Path(args.out)
    # the interpreter's start, the imports and reading the document, before the first stage
    startup = process_age_s() if launched_as_process() else None
    # before any work: the refusal (exit 2) or the estimate (plan.json keeps it, "resources")
    estimate = document_estimate(doc)
    print(f"estimate: {estimate.describe()}", file=sys.stderr, flush=True)
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    done = plan_measured(executor, doc, out, ProgressBar("plan"), figures, estimate)
    plan = done.plan
    if startup is not None:
        plan["timing_s"] = {"startup": startup, **plan["timing_s"]}
    plan_path = write_plan_json(plan, out)
    if done.note is not None:
        print(f"note: GIS files skipped: {done.note}", file=sys.stderr)
    if figures.note is not None:
        print(f"note: figures drawn in this process: {figures.note}", file=sys.stderr)
    print(f"wrote {plan_path}", file=sys.stderr)
    for p in done.files.values():
        print(f"wrote {p}", file=sys.stderr)
    for entry in plan["by_count"]:
        print(f"{entry['ris_count']} RIS: sites {entry['sites']} {_searched(entry)}")
    if "decision" in plan:
        print(f"decision: {plan['decision']['message']}")
    if "sizing" in plan:
        print(f"sizing: {plan['sizing']['message']}")
    if "validation" in plan:
        from ris_planner.planning.outputs.estimator_check import summary_lines as validation_lines

        for line in validation_lines(plan["validation"]):
            print(line)
    diagnosis = plan.get("diagnosis")
    if diagnosis is not None:
        for line in summary_lines(diagnosis):
            print(line, file=sys.stderr)
        for line in listed_lines(diagnosis, plan_path):
            print(line, file=sys.stderr)
        if args.fail_on_useless and diagnosis["verdict"] == "useless":
            return EXIT_USELESS
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``plan`` subcommand."""
    from ris_planner.planning.inputs.presets import PLAN_PRESET_NAMES

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
    p.add_argument(
        "--sizing",
        action="store_true",
        help="also answer the smallest RIS size × count that reaches the target (the"
        " document's 'sizing' settings, the default ladder 10×10 … 100×100 if absent)",
    )
    p.add_argument(
        "--validate",
        type=int_in(1, 1000),
        default=None,
        metavar="N",
        help="check each recommended layout with the two-stage estimator at N pairs sampled"
        " from the maps (the document's 'validation' settings otherwise: draws, seed,"
        " reflections; plan.json 'validation', validation.png)",
    )
    p.add_argument(
        "--fail-on-useless",
        action="store_true",
        help=f"exit with status {EXIT_USELESS} when the plan is diagnosed useless (the files are"
        " still written; default: a WARNING on stderr and status 0)",
    )
    p.add_argument(
        "--nested",
        action="store_true",
        help="phased roll-out: each count's layout contains the previous count's (the"
        " document's rollout = 'nested'; plan.json rollout gives the price of nesting)",
    )
    p.set_defaults(func=_cmd_plan)
