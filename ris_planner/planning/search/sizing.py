"""The sizing question: the smallest RIS size × count that reaches a target
(docs/concepts/diagnosis.md, "Sizing").

Every search method answers it in one shape (plan.json ``sizing``, :func:`sizing_json`): per
RIS size of ``sizing.ris_sizes`` (and the document's own), in ascending element count, a
:class:`SizeRow` – the smallest count found to reach the goal, the certified lower bound on the
count of any layout that reaches it where the method certifies one, the layout and its
objective – and the answer, the reaching row with the fewest elements in total
(rows · cols · count; ties to fewer RISs). The goal is the target as an objective value: for a
coverage objective a share of the servable pairs (docs/concepts/scoring.md, "One
denominator"), so a size is judged against the same pairs whatever it can cover.

The enumerating searches run the plan once per size in target mode
(:func:`enumerating_size_rows`, over the pipeline's run); the district search walks its greedy
path per size and solves its relaxation's lower bound
(:func:`ris_planner.planning.district_plan.district_size_rows`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ris_planner.core.io_json import finite_or_none
from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import Target
from ris_planner.model.search_methods import MethodChoice


@dataclass(frozen=True)
class SizeRow:
    """One RIS size of the sizing question."""

    ris_size: tuple[int, int]
    count: int | None
    """The smallest count found to reach the goal (``None``: none found)."""
    lower_bound: int | None
    """No layout of this size with fewer RISs reaches the goal (certified; ``None``: the
    method certifies none, or the goal is out of reach with every candidate)."""
    objective: float | None = None
    """The objective of the layout found."""
    sites: tuple[int, ...] | None = None
    note: str | None = None
    """Why no count is given, when none is; else how the count was found, where it is not the
    search's first answer (a district's swaps, the profile colours it was held to)."""
    counts: tuple[dict[str, Any], ...] = field(default_factory=tuple)
    """Each count tried: ``{"count", "objective", "reaches", "objective_bound"}`` (a district's
    also ``found_by``: its greedy path's layout, then each count the swaps tried below it)."""
    coverable: float | None = None
    """The weight every candidate of this size together brings within the objective's level
    (the coverable pairs depend on the RIS size; the servable ones do not)."""

    @property
    def elements(self) -> int | None:
        r, c = self.ris_size
        return None if self.count is None else r * c * self.count


def answer_row(rows: Sequence[SizeRow]) -> SizeRow | None:
    """The reaching row with the fewest elements in total; ties → fewer RISs, then the smaller
    grid."""
    reaching = [r for r in rows if r.count is not None]
    if not reaching:
        return None
    return min(reaching, key=lambda r: (r.elements, r.count, r.ris_size))


def interval_text(lower: int | None, count: int, size: tuple[int, int], goal: str) -> str:
    """The answer in plain words: ``between 131 and 168 RISs of 64×64 reach …`` (``lower`` the
    certified count, ``count`` the one found)."""
    r, c = size
    if lower is None:
        return f"{count} RISs of {r}×{c} reach {goal} (no certified lower count)"
    if lower >= count:
        return f"exactly {count} RISs of {r}×{c} reach {goal} (certified: no fewer can)"
    return f"between {lower} and {count} RISs of {r}×{c} reach {goal}"


def goal_words(kind: str, target: Target, servable_weight: float | None) -> str:
    """The target in words, with its denominator: ``90 % of the servable pairs`` (coverage),
    ``quantile ≤ 0.5 m``."""
    spec = objective_kind(kind)
    if spec.share_of_servable and target.min is not None:
        return f"{100 * target.min:.3g} % of the servable pairs"
    level = target.min if target.min is not None else target.max
    side = "≥" if target.min is not None else "≤"
    return f"{kind} {side} {level:g}{' ' + spec.unit if spec.unit else ''}"


def sizing_json(
    rows: Sequence[SizeRow],
    kind: str,
    target: Target,
    goal: Target,
    servable_weight: float | None,
    choice: MethodChoice,
) -> dict[str, Any]:
    """``plan.json["sizing"]`` (one shape for every search method): the target and its goal as
    an objective value, each size's row, the answer (``None`` when no size reaches the goal)
    with its certified interval, the search that answered and why, and a message."""
    best = answer_row(rows)
    words = goal_words(kind, target, servable_weight)
    out: dict[str, Any] = {
        "target": target.model_dump(exclude_none=True),
        "of": "servable pairs" if objective_kind(kind).share_of_servable else None,
        "goal": goal.model_dump(exclude_none=True),
        "servable_weight": servable_weight,
        "sizes": [_row_json(r, servable_weight) for r in rows],
        "search_method": choice.to_json(),
    }
    if best is None:
        out["answer"] = None
        out["message"] = (
            f"no RIS size of the ladder reaches {words} (each size's reason in 'sizes'):"
            " try larger RISs, more RISs, more power or other sites"
        )
        return out
    assert best.count is not None
    gap = None if best.lower_bound is None else best.count - best.lower_bound
    out["answer"] = {
        "ris_size": list(best.ris_size),
        "count": best.count,
        "lower_bound": best.lower_bound,
        "gap": gap,
        "gap_share": None if gap is None else gap / best.count,
        "elements": best.elements,
        "objective": finite_or_none(best.objective),
        "sites": None if best.sites is None else list(best.sites),
    }
    out["message"] = interval_text(best.lower_bound, best.count, best.ris_size, words)
    return out


def _row_json(row: SizeRow, servable_weight: float | None) -> dict[str, Any]:
    share = None
    if row.coverable is not None and servable_weight:
        share = min(1.0, row.coverable / servable_weight)
    return {
        "ris_size": list(row.ris_size),
        "count": row.count,
        "lower_bound": row.lower_bound,
        "coverable_share": share,
        "objective": finite_or_none(row.objective),
        "sites": None if row.sites is None else list(row.sites),
        "note": row.note,
        "counts": list(row.counts),
    }


RunCounts = Callable[
    [tuple[int, int], Callable[[float, str], None]], tuple[list[dict[str, Any]], float | None]
]
"""Runs the plan at one RIS size in target mode: the rows of
:meth:`~ris_planner.planning.outputs.result.PlanResult.summary_rows` (each count's objective,
whether it meets the goal and its certified bound) and the size's coverable weight."""


def enumerating_size_rows(
    sizes: Sequence[tuple[int, int]],
    goal: Target,
    first_count: int,
    run_counts: RunCounts,
    progress: Callable[[float, str], None],
) -> list[SizeRow]:
    """The enumerating searches' rows: each size's plan in target mode (``run_counts``); the
    count found is the first that meets the goal, the lower bound the first count whose
    certificate does not rule the goal out (every smaller count's certified bound misses it;
    exhaustive counts are exact). A size whose smallest count (``first_count``) already needs
    more elements than the answer so far is skipped."""
    rows: list[SizeRow] = []
    for i, (r, c) in enumerate(sizes):
        best = answer_row(rows)
        if best is not None and best.elements is not None and r * c * first_count >= best.elements:
            rows.append(SizeRow((r, c), None, None, note="skipped: more elements than the answer"))
            continue

        def sub(f: float, m: str, i: int = i, r: int = r, c: int = c) -> None:
            progress((i + f) / len(sizes), f"sizing {r}×{c}: {m}")

        tried, coverable = run_counts((r, c), sub)
        hit = next((t for t in tried if t["target_met"]), None)
        lower: int | None = None
        for t in tried:
            bound = t.get("objective_bound")
            if bound is None or goal.met(bound):
                lower = int(t["ris_count"])
                break
        else:
            lower = None if hit is None else int(hit["ris_count"])
        counts = tuple(
            {
                "count": t["ris_count"],
                "objective": t["objective"],
                "reaches": bool(t["target_met"]),
                "objective_bound": t.get("objective_bound"),
            }
            for t in tried
        )
        if hit is None:
            note = "no searched count reaches it"
            rows.append(SizeRow((r, c), None, None, note=note, counts=counts, coverable=coverable))
            continue
        rows.append(
            SizeRow(
                (r, c),
                int(hit["ris_count"]),
                lower,
                hit["objective"],
                tuple(hit["sites"]),
                counts=counts,
                coverable=coverable,
            )
        )
    progress(1.0, "sizing done")
    return rows
