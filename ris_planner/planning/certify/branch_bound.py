"""Branch-and-bound over sorted site sets: the exact best layout (gap 0) where it finishes.

A node is a sorted partial layout P of free sites and the position from which its remaining
sites R are taken (sites after max P in index order, compatible with P), so every layout is
one leaf. The bound of a node comes from the per-pair Frank–Wolfe relaxation at the root
(:mod:`ris_planner.planning.certify.relaxation`): each pair p and trace keeps the tangent of its
best
iterate, f̃_p(z) ≥ c_p + Σ_s g_{s,p} z_s on the whole box (f̃ convex, F̃ = F + ε·Diag(F) only
adds information), so every layout C of the subtree (P ⊂ C, C ∖ P ⊂ R, |C| = k) has

    f_p(C) ≥ c_p + Σ_{s∈P} g_{s,p} + (sum of the k − |P| smallest g_{r,p}, r ∈ R),

a minimum over a superset of the subtree's layouts (conflicts among R and the budget are
dropped, which only widens it). A child's layouts are a subset of its parent's, so it also
keeps the parent's bound. The objective is monotone in each pair's metric (certificates.py),
so the objective of these per-pair bounds bounds every layout of the subtree.

Best-first order (lowest bound first), incumbent = the greedy search's best. A node whose
bound is above the incumbent's loss is pruned (a bound equal to it is expanded, so ties with
a lexicographically smaller layout are found as exhaustive search finds them). A popped inner
node is bounded again by its own subtree's relaxation (P in the base, k − |P| sites from R:
the same Frank–Wolfe, valid for the same reasons, and far tighter than the root's tangents),
and its children get bounds from that relaxation's tangents; a node whose children are leaves
bounds each leaf that way (with many leaves) and scores the survivors in one batch. The
search stops at ``max_nodes`` expansions, ``max_leaves`` scored layouts or ``max_work``
layout scorings (:func:`node_work`); unfinished, the smallest bound left open (or the
incumbent) is still a valid bound on the optimum – never below the root's. A search whose
:func:`estimated_work` exceeds ``max_work`` is not begun.

Where it pays (measured, README): random instances of 10–24 candidates finish, exact, after
scoring 30–75 % of the layouts; on the 156-candidate hall (coverage) the subtree bounds stay
near the root's (0.985 → 0.977 at L = 3 after 200 nodes) and a finish would need ≈ C(156, 2)
node relaxations, so the plan does not begin it there.
"""

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.model.objectives import objective_kind
from ris_planner.planning.certify.relaxation import (
    RowRelaxation,
    SubsetProblem,
    combine_columns,
    row_relaxations,
    subset_problem,
)
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.scoring.site_cache import KeptInformation
from ris_planner.planning.search.layouts import Layout, SearchOutcome, evaluate
from ris_planner.runtime.executor import Executor

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

BNB_MAX_NODES = 20_000
"""Subtree expansions per count (each costs ≈ |R|·(k − |P|) vector operations over the pairs
per trace; ≈ 10 ms at 6400 pairs)."""

BNB_WORK_FACTOR = 2.0
"""A plan's branch-and-bound may spend this many times the greedy search's scored layouts
(a node's relaxation counted by :func:`node_work`): where the bounds prune
well it finishes inside that; where they do not it stops, and the plan costs at most 3× the
greedy search."""

BNB_MIN_WORK = 20_000
"""…but at least this many layout scorings (small instances, whose greedy search is short).
Before it starts, :func:`estimated_work` is checked against the budget: a search that cannot
finish is not begun (the plan then takes the plain relaxation certificate)."""

BNB_NODE_ITERATIONS = 10
"""Frank–Wolfe iterations of a node's own relaxation (the root uses the document's
``certificate_iterations``)."""


@dataclass
class BranchBoundOutcome:
    """What the search did: every layout it scored (with the incumbent's), whether it
    finished (exact), the valid bound on the best loss, and its effort."""

    outcome: SearchOutcome
    finished: bool
    loss_bound: float
    nodes: int
    leaves: int
    root_bound: float
    reason: str

    def to_json(self) -> dict[str, object]:
        return {
            "finished": self.finished,
            "nodes": self.nodes,
            "layouts_scored": self.leaves,
            "reason": self.reason,
        }


def suffix_smallest_sums(g: FloatArray, m: int) -> FloatArray:
    """[n, P] → [n, P]: row j is the sum of the m smallest entries of g[j+1:] per column
    (``inf`` where fewer than m follow; 0 for m = 0)."""
    n, p = g.shape
    out = np.empty((n, p))
    if m == 0:
        out[:] = 0.0
        return out
    best = np.full((m, p), np.inf)  # ascending per column
    for j in range(n - 1, -1, -1):
        out[j] = best.sum(axis=0)
        x = g[j]
        for q in range(m):  # insert x into the sorted m smallest
            lo = np.minimum(best[q], x)
            x = np.maximum(best[q], x)
            best[q] = lo
    return out


def _child_bounds(
    scorer: Scorer, relax: list[RowRelaxation], partial: list[int], rest: IntArray, m: int
) -> FloatArray:
    """[len(rest)] loss bounds of the children P + rest[j] (each then takes m more sites from
    rest[j+1:]) from tangents of ``relax`` (taken at the root or at the node itself, whose
    own sites P are then part of the base and carry no gradient)."""
    traces = []
    for r in relax:
        assert r.const is not None and r.grad is not None
        base = r.const + r.grad[partial].sum(axis=0)  # [P]
        gr = r.grad[rest]  # [n, P]
        traces.append(base[None, :] + gr + suffix_smallest_sums(gr, m))
    metric = combine_columns(scorer, traces)  # [n, P or 2P]
    return relaxation_loss(scorer, metric)


def node_work(iterations: int, n_rest: int) -> float:
    """A node relaxation's cost in layout scorings over the same pairs: per iteration one
    inversion per pair plus the gradient over the node's remaining sites (measured on the
    hall, 800 pairs: ≈ 0.46 s per node with |R| ≈ 130 against 0.68 ms per scored layout)."""
    return iterations * (1.0 + n_rest / 2.0)


def estimated_work(n_free: int, k: int, iterations: int) -> float:
    """A-priori cost of a search that prunes only at the leaves (as measured on small
    instances: the inner nodes' bounds rarely fall above the incumbent): every node of depth
    1 … k − 1 relaxed once, at the average |R| = n_free / 2."""
    nodes = sum(math.comb(n_free, d) for d in range(1, k))
    return nodes * node_work(iterations, n_free // 2)


def _subtree(
    problem: SubsetProblem, packed: KeptInformation, partial: tuple[int, ...], rest: IntArray
) -> SubsetProblem:
    """The relaxation of a node's subtree: its sites P in the base, k − |P| sites from R."""
    mask = np.zeros_like(problem.free)
    mask[rest] = True
    base = problem.base + packed.sites(list(partial)).sum(axis=1)
    return SubsetProblem(mask, problem.k - len(partial), base, problem.groups)


def _relaxed_loss(scorer: Scorer, relax: list[RowRelaxation]) -> float:
    """The loss of the relaxation's per-pair bounds."""
    metric = combine_columns(scorer, [r.lower for r in relax])[None, :]
    return float(relaxation_loss(scorer, metric)[0])


def relaxation_loss(scorer: Scorer, lower: FloatArray) -> FloatArray:
    """[B] the objective kind's bound on the loss from per-pair metric lower bounds [B, P]
    (:meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.relaxation_loss`)."""
    obj = scorer.objective
    return objective_kind(obj.kind).relaxation_loss(obj, lower, scorer.metric_weights)


def branch_and_bound(
    scorer: Scorer,
    n_ris: int,
    feasible: Feasibility,
    incumbent: SearchOutcome,
    executor: Executor,
    iterations: int,
    max_nodes: int = BNB_MAX_NODES,
    max_leaves: int = 100_000,
    max_work: float | None = None,
) -> BranchBoundOutcome:
    """Best-first branch-and-bound from the ``incumbent`` search's best layout (the module
    docstring); the returned outcome holds the incumbent's layouts and every scored leaf."""
    memo: dict[Layout, float] = {
        tuple(int(s) for s in lay): float(v)
        for lay, v in zip(incumbent.layouts, incumbent.losses, strict=True)
    }
    # the order of infinite losses (search.ranked_order's tie-break) of every scored layout
    ties_of: dict[Layout, float] = dict.fromkeys(memo, 0.0)
    if incumbent.tiebreak is not None:
        ties_of.update(zip(memo, (float(t) for t in incumbent.tiebreak), strict=True))
    best_lay, best = incumbent.ranked(1)[0]
    problem = subset_problem(scorer, n_ris, feasible)

    def result(
        finished: bool, bound: float, nodes: int, leaves: int, root: float, why: str
    ) -> BranchBoundOutcome:
        out = SearchOutcome(
            np.array(list(memo), dtype=int).reshape(len(memo), n_ris),
            np.array(list(memo.values())),
            method="branch_and_bound" if finished else incumbent.method,
            total_layouts=incumbent.total_layouts,
            tiebreak=np.array([ties_of[lay] for lay in memo]),
        )
        return BranchBoundOutcome(out, finished, bound, nodes, leaves, root, why)

    if isinstance(problem, str):  # every layout blind, or a single / no layout
        return result(True, best, 0, 0, best, f"trivial ({problem})")
    assert isinstance(problem, SubsetProblem)
    packed, _ = scorer.selected_packed
    node_iter = min(iterations, BNB_NODE_ITERATIONS)
    if max_work is not None:
        need = estimated_work(int(problem.free.sum()), problem.k, node_iter)
        if need > max_work:
            why = f"does not pay: ≈ {need:.3g} layout scorings estimated > budget {max_work:.3g}"
            return result(False, -np.inf, 0, 0, -np.inf, why)
    relax = row_relaxations(scorer, problem, iterations, settle=False, tangent=True)
    root = _relaxed_loss(scorer, relax)
    free = np.flatnonzero(problem.free)
    req = list(feasible.required)
    k = problem.k
    tie = itertools.count()
    heap: list[tuple[float, int, tuple[int, ...], int]] = [(root, next(tie), (), 0)]
    nodes = leaves = 0
    work = 0.0  # layout scorings spent, a node's relaxation counted by :func:`node_work`
    work_cap = max_work if max_work is not None else np.inf
    while heap:
        bound, _, partial, start = heap[0]
        if bound > best:  # every open node is pruned: the incumbent is optimal
            heap.clear()
            break
        if nodes >= max_nodes or leaves >= max_leaves or work + leaves > work_cap:
            return result(False, min(best, bound), nodes, leaves, root, "budget")
        heapq.heappop(heap)
        nodes += 1
        rest = free[start:]
        if partial:
            chosen = np.array(partial, dtype=int)
            rest = rest[~np.any(feasible.conflict[np.ix_(chosen, rest)], axis=0)]
        m = k - len(partial) - 1  # sites a child still takes after its own
        if rest.size <= m:
            continue
        if m == 0 and partial and rest.size > node_iter:
            # many leaves: the node's own relaxation (k' = 1) bounds each before it is scored
            node_relax = row_relaxations(
                scorer,
                _subtree(problem, packed, partial, rest),
                node_iter,
                tangent=True,
                settle=False,
            )
            work += node_work(node_iter, rest.size)
            leaf = np.maximum(_child_bounds(scorer, node_relax, [], rest, 0), bound)
            rest = rest[leaf <= best]
        if m == 0:  # the children are leaves: score them
            lays = np.sort(
                np.column_stack([np.tile(req + list(partial), (rest.size, 1)).astype(int), rest]),
                axis=1,
            )
            lays = lays[feasible.ok(lays)] if not feasible.trivial else lays
            keys = [tuple(int(s) for s in lay) for lay in lays]
            new = [i for i, key in enumerate(keys) if key not in memo]
            if new:
                vals = evaluate(scorer, lays[new], executor, tiebreak=True)
                leaves += len(new)
                fresh = [keys[i] for i in new]
                memo.update(zip(fresh, (float(v) for v in vals[:, 0]), strict=True))
                ties_of.update(zip(fresh, (float(t) for t in vals[:, 1]), strict=True))
            for key in keys:
                if (memo[key], key) < (best, best_lay):
                    best, best_lay = memo[key], key
            continue
        node_relax, fixed = relax, list(partial)
        if partial:  # the subtree's own relaxation: P fixed, k − |P| of its remaining sites
            sub = _subtree(problem, packed, partial, rest)
            node_relax = row_relaxations(scorer, sub, node_iter, settle=False, tangent=True)
            work += node_work(node_iter, rest.size)
            bound = max(bound, _relaxed_loss(scorer, node_relax))
            if bound > best:
                continue
            fixed = []  # P is in the node relaxation's base
        child = np.maximum(_child_bounds(scorer, node_relax, fixed, rest, m), bound)
        pos = np.searchsorted(free, rest)  # each child's position in the free list
        for j in np.flatnonzero(child <= best):
            if rest.size - j - 1 < m:
                break
            heapq.heappush(
                heap, (float(child[j]), next(tie), (*partial, int(rest[j])), int(pos[j]) + 1)
            )
    return result(True, best, nodes, leaves, root, "finished")
