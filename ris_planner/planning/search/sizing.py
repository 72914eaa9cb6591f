"""The sizing question: the smallest RIS size × count that reaches a target
(docs/concepts/diagnosis.md, "Sizing").

Each RIS size of ``document.sizing.ris_sizes`` runs the plan once more over the same candidates
and pairs – the ``sweep`` machinery over ``ris_size`` (:func:`ris_planner.planning.
sweep_rows`) – with the sizing target as ``objective.target``: with explicit counts every count
is searched (``mode: compare``); without, each size searches 1, 2, … ``max_ris`` and stops at
the first count that reaches the target (``mode: target``). The answer is the reaching row with
the fewest elements in total (rows · cols · count); ties go to fewer RISs. Sizes are tried in
ascending element count, and a size whose smallest count already needs more elements than the
answer found so far cannot win: it is skipped (and named in the message)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ris_planner.model.plan import PlanDocument, Sweep
from ris_planner.runtime.executor import Executor
from ris_planner.runtime.progress import ProgressCallback


def sizing_document(doc: PlanDocument) -> dict[str, Any]:
    """The plan document (JSON dict) each sizing run starts from: without ``sweep``,
    ``sizing`` and ``beams``, the sizing target as ``objective.target`` and the sizing counts
    (compare mode) or 1 … ``max_ris`` in target mode."""
    assert doc.sizing is not None
    target = doc.sizing_target()
    raw = {
        k: v
        for k, v in doc.model_dump(mode="json").items()
        if k not in ("sweep", "sizing", "beams")
    }
    raw["objective"] = {**raw["objective"], "target": target.model_dump(exclude_none=True)}
    counts = doc.sizing.counts if doc.sizing.counts is not None else doc.ris_count
    if counts is not None:
        raw["ris_count"], raw["mode"] = list(counts), "compare"
    else:
        raw["ris_count"], raw["mode"] = None, "target"
    return raw


def smallest(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The reaching row with the fewest elements in total (rows · cols · count); ties → fewer
    RISs, then the smaller grid."""
    reaching = [r for r in rows if r["reaches"]]
    if not reaching:
        return None
    return min(reaching, key=lambda r: (r["rows"] * r["cols"] * r["count"], r["count"], r["rows"]))


SweepRows = Callable[[dict[str, Any], Sweep, Any, ProgressCallback, Executor], list[dict[str, Any]]]
"""The pipeline's sweep runner (:func:`ris_planner.planning.pipeline.sweep_rows`): the rows
of one sweep value, each RIS count's objective and whether it meets the target."""


def run_sizing(
    doc: PlanDocument, progress: ProgressCallback, ex: Executor, sweep_rows: SweepRows
) -> dict[str, Any]:
    """``plan.json["sizing"]``: ``{"target", "answer", "table", "skipped", "message"}``.

    ``answer`` is ``{"rows", "cols", "count", "objective", "sites"}`` of :func:`smallest` or
    ``None``; ``table`` one row per (size, searched count) with ``reaches``. ``sweep_rows``
    runs the plans (the pipeline passes its own, so this stage does not import it)."""
    assert doc.sizing is not None
    sizes = doc.sizing.ris_sizes
    target = doc.sizing_target()
    raw = sizing_document(doc)
    sweep = Sweep(ris_size=sizes)
    counts = raw["ris_count"] or list(range(1, doc.max_ris + 1))
    table: list[dict[str, Any]] = []
    skipped: list[list[int]] = []
    for i, (r, c) in enumerate(sizes):
        best = smallest(table)
        if best is not None and (r * c * counts[0], counts[0]) >= (
            best["rows"] * best["cols"] * best["count"],
            best["count"],
        ):
            skipped.append([r, c])
            continue

        def sub_progress(f: float, m: str, i: int = i, r: int = r, c: int = c) -> None:
            progress((i + f) / len(sizes), f"sizing {r}×{c}: {m}")

        for row in sweep_rows(raw, sweep, [r, c], sub_progress, ex):
            table.append(
                {
                    "rows": r,
                    "cols": c,
                    "count": row["ris_count"],
                    "objective": row["objective"],
                    "reaches": bool(row["target_met"]),
                    "sites": row["sites"],
                    "cost": row["cost"],
                }
            )
    progress(1.0, "sizing done")
    best = smallest(table)
    level = target.min if target.min is not None else target.max
    side = "≥" if target.min is not None else "≤"
    goal = f"{doc.objective.kind} {side} {level:g}"
    if best is None:
        largest = sizes[-1]
        message = (
            f"no RIS size up to {largest[0]}×{largest[1]} with {counts[0]}–{counts[-1]} RISs"
            f" reaches {goal}: try larger RISs, more RISs (counts), more power or other sites"
        )
        answer = None
    else:
        obj = best["objective"]
        message = (
            f"smallest reaching {goal}: {best['count']} × {best['rows']}×{best['cols']} RIS"
            f" ({best['count'] * best['rows'] * best['cols']} elements, objective"
            f" {obj:.3g} at sites {best['sites']})"
        )
        answer = {k: best[k] for k in ("rows", "cols", "count", "objective", "sites")}
    if skipped:
        message += (
            f"; sizes {', '.join(f'{a}×{b}' for a, b in skipped)} skipped: they need more"
            " elements than the answer"
        )
    return {
        "target": {"objective": level, "better": "higher" if target.min is not None else "lower"},
        "counts": counts,
        "answer": answer,
        "table": table,
        "skipped": skipped,
        "message": message,
    }
