"""Phased roll-out: nested layouts, where each RIS count's layout contains the previous count's
(docs/guides/rollout.md).

Deploying 2 RISs now and 2 more next year only pays if the 4-RIS layout keeps the first two.
The free search optimises every count on its own, so its layouts need not be nested. With
``rollout: "nested"`` the plan also searches the nested chain: the first count's layout is the
free one; each next count's is the best superset of the previous count's layout – every
extension (exhaustively) when there are at most ``search.max_exhaustive`` of them, else a
greedy extension (one site at a time) followed by swaps of the added sites only. The *price
of nesting* of a count is how much worse the nested layout's objective is than the free
optimum's (``≥ 0`` when the free search is exhaustive), absolute and relative to the free
objective. With ``rollout: "free"`` (the default) plan.json still says whether the free
layouts happen to be nested, and gives the price when the chain is cheap: when every count's
extension is searched exhaustively within ``search.max_exhaustive`` layouts in all and
the chain costs at most 2 million (layout, pair) evaluations or 5 % of the free search's
(:func:`chain_is_cheap`; otherwise ``price`` is ``null`` and ``price_note`` says why).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import finite_or_none
from ris_planner.model.plan import Objective, SearchSpec
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.scoring.scorer import Scorer, objective_from_loss

Layout = tuple[int, ...]

BATCH_LAYOUTS = 4096
"""Layouts scored per :meth:`Scorer.exact_loss` call."""


@dataclass(frozen=True)
class NestedStep:
    """The nested layout of one RIS count."""

    ris_count: int
    layout: Layout | None
    """Sorted site indices (``None``: no feasible superset of the previous layout)."""
    loss: float
    method: str
    """``free`` (the first count: the free optimum), ``exhaustive`` or ``greedy``."""
    evaluated: int


def _score(scorer: Scorer, layouts: list[Layout]) -> NDArray[np.float64]:
    out = np.empty(len(layouts))
    for b0 in range(0, len(layouts), BATCH_LAYOUTS):
        block = np.array(layouts[b0 : b0 + BATCH_LAYOUTS], dtype=np.int64)
        out[b0 : b0 + len(block)] = scorer.exact_loss(block)
    return out


def _best(
    scorer: Scorer, feasibility: Feasibility, layouts: list[Layout]
) -> tuple[Layout | None, float, int]:
    """(best feasible layout, its loss, layouts scored) of ``layouts`` (ties: lowest sites)."""
    if not layouts:
        return None, math.inf, 0
    ok = feasibility.ok(np.array(layouts, dtype=int))
    cand = [lay for lay, g in zip(layouts, ok, strict=True) if g]
    if not cand:
        return None, math.inf, 0
    losses = _score(scorer, cand)
    order = sorted(range(len(cand)), key=lambda i: (losses[i], cand[i]))
    return cand[order[0]], float(losses[order[0]]), len(cand)


def extension_count(n_sites: int, base: int, count: int) -> int:
    """Supersets of a ``base``-site layout with ``count`` sites among ``n_sites``."""
    return math.comb(n_sites - base, count - base) if count >= base else 0


def extend(
    scorer: Scorer,
    feasibility: Feasibility,
    base: Layout,
    count: int,
    spec: SearchSpec,
) -> NestedStep:
    """The best ``count``-site superset of ``base`` (module docstring)."""
    n = feasibility.n_sites
    rest = [s for s in range(n) if s not in base]
    k = count - len(base)
    if extension_count(n, len(base), count) <= spec.max_exhaustive:
        lays = [tuple(sorted(base + extra)) for extra in itertools.combinations(rest, k)]
        lay, loss, ev = _best(scorer, feasibility, lays)
        return NestedStep(count, lay, loss, "exhaustive", ev)
    # greedy: add the best site, one at a time; then swap added sites for outside ones
    chosen: Layout = tuple(base)
    evaluated = 0
    loss = math.inf
    for _ in range(k):
        lays = [tuple(sorted((*chosen, s))) for s in rest if s not in chosen]
        lay, loss, ev = _best(scorer, feasibility, lays)
        evaluated += ev
        if lay is None:
            return NestedStep(count, None, math.inf, "greedy", evaluated)
        chosen = lay
    for _ in range(spec.max_rounds):
        added = [s for s in chosen if s not in base]
        outside = [s for s in rest if s not in chosen]
        lays = [tuple(sorted(set(chosen) - {a} | {o})) for a in added for o in outside]
        lay, new, ev = _best(scorer, feasibility, lays)
        evaluated += ev
        if lay is None or not new < loss:
            break
        chosen, loss = lay, new
    return NestedStep(count, chosen, loss, "greedy", evaluated)


def nested_chain(
    scorer: Scorer,
    feasibility: Feasibility,
    free: list[tuple[int, Layout, float]],
    spec: SearchSpec,
) -> list[NestedStep]:
    """The nested layouts of the counts of ``free`` ((count, free best layout, its loss) in
    increasing count): the first is the free one, each next the best superset of the one
    before (:func:`extend`)."""
    steps: list[NestedStep] = []
    for i, (count, lay, loss) in enumerate(free):
        if i == 0:
            steps.append(NestedStep(count, lay, loss, "free", 0))
            continue
        prev = steps[-1].layout
        if prev is None:
            steps.append(NestedStep(count, None, math.inf, "exhaustive", 0))
            continue
        steps.append(extend(scorer, feasibility, prev, count, spec))
    return steps


FREE_CHAIN_WORK = 2_000_000
"""Free mode prices the nested chain when its (layout, pair) evaluations stay within this …"""
FREE_CHAIN_SHARE = 0.05
"""… or within this share of the free search's own (layout, pair) evaluations."""


def chain_is_cheap(
    n_sites: int, counts: list[int], max_exhaustive: int, n_pairs: int, search_work: float
) -> bool:
    """Whether the free mode searches the chain too (and so reports the price): every extension
    exhaustive within ``max_exhaustive`` layouts in all, and their (layout, pair) evaluations
    within :data:`FREE_CHAIN_WORK` or :data:`FREE_CHAIN_SHARE` of ``search_work`` (the free
    search's layouts × pairs) – at most a few percent more time."""
    total = sum(extension_count(n_sites, a, b) for a, b in itertools.pairwise(counts))
    budget = max(FREE_CHAIN_WORK, FREE_CHAIN_SHARE * search_work)
    return total <= max_exhaustive and total * n_pairs <= budget


def rollout_json(
    mode: str,
    objective: Objective,
    free: list[tuple[int, Layout, float]],
    steps: list[NestedStep] | None,
    note: str | None = None,
) -> dict[str, Any]:
    """plan.json ``rollout``: per count the free layout and objective, whether it contains the
    previous count's free layout (``nested``), and – where the chain was searched – the nested
    layout, its objective, the method and the price of nesting (objective units, ≥ 0 means
    the nested layout is worse; relative to |free objective|)."""
    rows = []
    for i, (count, lay, loss) in enumerate(free):
        free_obj = objective_from_loss(objective, loss)
        row: dict[str, Any] = {
            "ris_count": count,
            "free_layout": [int(s) for s in lay],
            "free_objective": finite_or_none(free_obj),
            "nested": None if i == 0 else set(free[i - 1][1]) <= set(lay),
        }
        if steps is not None:
            st = steps[i]
            nested_obj = objective_from_loss(objective, st.loss)
            # losses are "lower is better": the price is the nested loss above the free one
            price = st.loss - loss if math.isfinite(st.loss) and math.isfinite(loss) else math.inf
            row |= {
                "nested_layout": None if st.layout is None else [int(s) for s in st.layout],
                "nested_objective": finite_or_none(nested_obj),
                "method": st.method,
                "layouts_evaluated": st.evaluated,
                "price": finite_or_none(price),
                "price_relative": finite_or_none(price / abs(free_obj))
                if math.isfinite(price) and math.isfinite(free_obj) and free_obj != 0
                else None,
            }
        else:
            row |= {"price": None}
        rows.append(row)
    out: dict[str, Any] = {"mode": mode, "counts": rows}
    if note is not None:
        out["price_note"] = note
    return out


def plan_rollout(
    mode: str,
    scorer: Scorer,
    feasibility: Feasibility,
    free: list[tuple[int, Layout, float]],
    spec: SearchSpec,
    n_pairs: int,
    search_work: float,
) -> dict[str, Any]:
    """The ``rollout`` block of plan.json for ``mode`` (``free`` or ``nested``; module
    docstring): the nested chain is searched in nested mode, and in free mode when
    :func:`chain_is_cheap` (``search_work``: the free search's layouts × pairs)."""
    counts = [c for c, _, _ in free]
    n = feasibility.n_sites
    if mode == "nested" or chain_is_cheap(n, counts, spec.max_exhaustive, n_pairs, search_work):
        steps = nested_chain(scorer, feasibility, free, spec)
        return rollout_json(mode, scorer.objective, free, steps)
    note = (
        "the nested chain is not cheap next to the free search (planning.rollout."
        'chain_is_cheap): set rollout "nested" to search it'
    )
    return rollout_json(mode, scorer.objective, free, None, note)
