"""From ranked layouts to a decision: ties within a tolerance, the target answer (the smallest
RIS count that meets ``objective.target``), and the cost-versus-objective Pareto set."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ris_planner.core.io_json import finite_or_none
from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import Objective, Target
from ris_planner.planning.certify.relaxation import Certificate
from ris_planner.planning.scoring.scorer import objective_from_loss
from ris_planner.planning.search.layouts import Layout, SearchOutcome

MAX_TIES_LISTED = 50
"""Tied layouts listed per count in plan.json (the count of all ties is always reported)."""


def tie_tolerance(best_loss: float, rtol: float) -> float:
    """Largest loss difference to the best that counts as a tie: rtol·|best| (0 for inf)."""
    return rtol * abs(best_loss) if math.isfinite(best_loss) else 0.0


def ties(outcome: SearchOutcome, rtol: float) -> tuple[int, list[tuple[Layout, float]]]:
    """(number of evaluated layouts tied with the best, the first :data:`MAX_TIES_LISTED` of
    them ranked); a tie is a loss within :func:`tie_tolerance` of the best (an infinite best:
    every infinite loss)."""
    if outcome.evaluated == 0:
        return 0, []
    best = float(outcome.losses.min())
    tol = tie_tolerance(best, rtol)
    n = int(np.sum(outcome.losses <= best + tol)) if math.isfinite(best) else outcome.losses.size
    return n, outcome.ranked(min(n, MAX_TIES_LISTED))


@dataclass(frozen=True)
class CountAnswer:
    """One searched count as the decision sees it."""

    ris_count: int
    best_loss: float | None  # None: no feasible layout
    layout: Layout | None
    cost: float
    certificate: Certificate | None


def target_status(obj: Objective, target: Target, ans: CountAnswer) -> str:
    """``met``; ``unreachable`` (no feasible layout, or the certificate proves the target out
    of reach); ``not_found`` (the search's best misses it, without proof that all layouts
    do)."""
    if ans.best_loss is None:
        return "unreachable"
    if target.met(objective_from_loss(obj, ans.best_loss)):
        return "met"
    cert = ans.certificate
    if cert is not None and (
        cert.exact or not target.met(objective_from_loss(obj, cert.loss_bound))
    ):
        return "unreachable"
    return "not_found"


def decision_json(
    obj: Objective,
    answers: list[CountAnswer],
    max_count: int,
    target_mode: bool,
    goal: Target,
    share: Callable[[float], float | None],
) -> dict[str, Any]:
    """The ``decision`` block of plan.json (docs/concepts/decisions.md): ``target`` as written,
    ``goal`` the objective value it asks for (a coverage target is a share of the servable
    pairs: ``share`` maps an objective value to that share)."""
    target = obj.target
    assert target is not None
    denominator = objective_kind(obj.kind).share_of_servable

    def said(value: float) -> str:
        pct = share(value) if denominator else None
        extra = "" if pct is None else f" = {100 * pct:.3g} % of the servable pairs"
        return f"{obj.kind} {value:.3g}{extra}"

    rows = []
    answer: CountAnswer | None = None
    proven = True  # every smaller count searched is certified unreachable
    for a in answers:
        status = target_status(obj, goal, a)
        rows.append(
            {
                "ris_count": a.ris_count,
                "status": status,
                "objective": None
                if a.best_loss is None
                else finite_or_none(objective_from_loss(obj, a.best_loss)),
            }
        )
        if status == "met" and answer is None:
            answer = a
            break
        proven &= status == "unreachable"
    counted = [a.ris_count for a in answers]
    if answer is not None:
        smaller_missing = [c for c in range(1, answer.ris_count) if c not in counted]
        value = objective_from_loss(obj, answer.best_loss or 0.0)
        minimal = proven and not smaller_missing
        msg = (
            f"{answer.ris_count} RIS{'s' if answer.ris_count > 1 else ''} meet the target"
            f" ({said(value)}); "
            + (
                "no smaller count can (certified)"
                if minimal
                else "a smaller count is not proven impossible"
            )
        )
        return {
            "target": target.model_dump(exclude_none=True),
            "goal": goal.model_dump(exclude_none=True),
            "of": "servable pairs" if denominator else None,
            "mode": "target" if target_mode else "compare",
            "met": True,
            "ris_count": answer.ris_count,
            "sites": [int(s) for s in (answer.layout or ())],
            "objective": finite_or_none(value),
            "cost": answer.cost,
            "minimal_proven": bool(minimal),
            "counts": rows,
            "message": msg,
        }
    finite = [a for a in answers if a.best_loss is not None]
    best = min(finite, key=lambda a: (a.best_loss, a.ris_count)) if finite else None
    best_val = (
        None if best is None else finite_or_none(objective_from_loss(obj, best.best_loss or 0.0))
    )
    proven_all = all(r["status"] == "unreachable" for r in rows)
    msg = f"not reachable with ≤ {max_count} RISs from these candidates" + (
        " (certified)" if proven_all else " (not found by the search; not proven impossible)"
    )
    if best is not None:
        shown = "inf" if best_val is None else f"{best_val:.3g}"  # full precision in "objective"
        shown = shown if best_val is None else said(best_val)
        msg += f"; best {shown} with {best.ris_count} RISs"
    return {
        "target": target.model_dump(exclude_none=True),
        "goal": goal.model_dump(exclude_none=True),
        "of": "servable pairs" if denominator else None,
        "mode": "target" if target_mode else "compare",
        "met": False,
        "ris_count": None,
        "sites": None if best is None else [int(s) for s in (best.layout or ())],
        "objective": best_val,
        "best_ris_count": None if best is None else best.ris_count,
        "unreachable_proven": proven_all,
        "counts": rows,
        "message": msg,
    }


def pareto(points: list[tuple[float, float, Layout]]) -> list[tuple[float, float, Layout]]:
    """The non-dominated (cost, loss, layout) points, cheapest first: a point stays when no
    other is at most as costly and strictly better, or strictly cheaper and as good."""
    out: list[tuple[float, float, Layout]] = []
    for cost, loss, lay in sorted(points, key=lambda t: (t[0], t[1], len(t[2]), t[2])):
        if not out or loss < out[-1][1]:  # sorted: an equal cost has a loss ≥ the kept one
            out.append((cost, loss, lay))
    return out
