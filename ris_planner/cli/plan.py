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


def objective_words(plan: dict[str, Any]) -> str:
    """The objective as plan.json states it: kind, metric, level, unit and direction – ``coverage
    of PEB_R ≤ 1 m (a fraction of the pairs, higher is better)``."""
    obj = plan["objective"]
    metric = {"rx": "PEB_R", "tx": "PEB_T", "max": "max(PEB_T, PEB_R)"}[obj["metric"]]
    level = next((obj[k] for k in ("threshold_m", "cap_m") if obj.get(k) is not None), None)
    unit = plan.get("objective_unit") or ""
    what = "a fraction of the pairs" if unit == "" else f"in {unit}"
    at = "" if level is None else f" ≤ {level:g} m"
    return f"{obj['kind']} of {metric}{at} ({what}, {plan['objective_better']} is better)"


def count_line(entry: dict[str, Any], plan: dict[str, Any]) -> str:
    """One count's summary line: its sites by name (and index), the objective with its share
    of the servable pairs where it is a coverage, how it was found, the certified interval."""
    names = entry.get("site_names") or [str(s) for s in entry["sites"]]
    sites = ", ".join(f"{n} [{i}]" for n, i in zip(names, entry["sites"], strict=True))
    value = rounded(entry["objective"])
    share = entry.get("share_of_servable")
    shown = value if share is None else f"{value} = {100 * share:.3g} % of the servable pairs"
    cert = entry.get("certificate")
    how = entry.get("found_by") or entry["method"]
    if entry["method"] != "district":
        how += f", {entry['layouts_evaluated']}/{entry['layouts_total']} layouts"
    text = f"{entry['ris_count']} RIS: {shown} ({how})"
    if cert is not None and not cert["exact"]:
        bound = rounded(cert["objective_bound"])
        side = "≤" if cert["bound_side"] == "upper" else "≥"
        text += f", certified {side} {bound} (gap {rounded(cert['gap'])}"
        if cert.get("relative_gap") is not None:
            text += f", {100 * cert['relative_gap']:.3g} % of the bound"
        text += ")"
        servable = (plan.get("pairs_summary") or {}).get("servable_weight")
        if cert["bound_side"] == "upper" and share is not None and servable:
            top = cert["objective_bound"] / servable
            text += (
                f": the best layout of {entry['ris_count']} RISs covers between"
                f" {100 * share:.3g} % and {100 * min(1.0, top):.3g} % of the servable pairs"
            )
    elif cert is not None:
        text += ", optimal (certified)"
    return f"{text}; sites {sites}"


def pairs_words(summary: dict[str, Any]) -> str:
    """plan.json ``pairs_summary`` in words: the servable pairs (every share's denominator)
    and the coverable ones at this RIS size."""
    text = (
        f"{summary['pairs']} pairs; servable (some layout of the candidates locates them):"
        f" {100 * summary['servable_weight']:.3g} % of the weight – the denominator of every"
        " share below"
    )
    share = summary.get("coverable_share")
    if share is not None:
        text += f"; coverable at this RIS size: {100 * share:.3g} % of the servable pairs"
    return text


def search_lines(choice: Any, sizing: Any) -> list[str]:
    """What the plan (and its sizing question) search with and why, when ``auto`` chose the
    district search or the sizing runs another search than the plan: one line each."""
    out = []
    if choice.requested != choice.used:
        out.append(f"search: {choice.used} ({choice.why})")
    if sizing is not None and sizing.used != choice.used:
        out.append(f"sizing search: {sizing.used} ({sizing.why})")
    return out


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
    from ris_planner.io.estimates import plan_measured
    from ris_planner.io.plan_request import admit_request
    from ris_planner.model.search_methods import sparse_search
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
    # before any work, once: the refusal (exit 2) or the estimate (plan.json keeps it)
    request = admit_request(doc)
    if sparse_search(request.admitted.document) and (args.scheduler or args.workers):
        flag = "--scheduler" if args.scheduler else "--workers"
        raise RisPlannerError(
            f"{flag}: the district search runs in this process (its relaxations on a thread"
            " beside it); worker processes and a Dask cluster score the enumerating searches'"
            " layouts"
        )
    print(f"estimate: {request.estimate.describe()}", file=sys.stderr, flush=True)
    for line in search_lines(request.admitted.choice, request.admitted.sizing_choice):
        print(line, file=sys.stderr, flush=True)
    executor: Executor = (
        DaskExecutor(args.scheduler) if args.scheduler else LocalExecutor(args.workers)
    )
    done = plan_measured(executor, request, out, ProgressBar("plan"), figures)
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
    print(f"objective: {objective_words(plan)}")
    summary = plan.get("pairs_summary")
    if summary is not None:
        print(f"pairs: {pairs_words(summary)}")
    for entry in plan["by_count"]:
        print(count_line(entry, plan))
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
