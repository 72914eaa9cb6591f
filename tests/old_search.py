"""The greedy search from before targets, constraints and certificates, and its chunking, kept
verbatim: the reference the new search must never lose to on the same input
(tests/test_planning_decisions.py) and the baseline of benchmarks/planning/bench_search.py; and the
greedy search as it was before the search-quality work (:func:`pre_quality_greedy`, verbatim:
infinite losses compared as plain floats, restarts = the spec's), the baseline of
benchmarks/planning/bench_search_quality.py."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ris_planner.model.plan import SearchSpec
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.scoring.scorer import Scorer, score_chunk
from ris_planner.planning.search.layouts import (
    CHUNK_MATRICES,
    RANK_RTOL,
    FloatArray,
    IntArray,
    Layout,
    SearchOutcome,
    _site_keys,
    evaluate,
    site_strength,
)
from ris_planner.runtime.executor import Executor


def old_evaluate(
    scorer: Scorer,
    layouts: IntArray,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
) -> FloatArray:
    """Losses of layouts [B, L], split into chunks of ≈ :data:`CHUNK_MATRICES` evaluations."""
    b = layouts.shape[0]
    if b == 0:
        return np.empty(0)
    per = max(1, CHUNK_MATRICES // max(1, scorer.cache.n_pairs))
    n_chunks = math.ceil(b / per)
    if n_chunks > 1:  # balance the workers: a multiple of their count, each ≳ half a chunk
        n_chunks = min(b, math.ceil(n_chunks / executor.workers) * executor.workers)
    chunks = np.array_split(layouts, n_chunks)  # n_chunks ≤ b: none is empty

    def done(n: int) -> None:
        if on_fraction is not None:
            on_fraction(n / len(chunks))

    return np.concatenate(executor.map(score_chunk, scorer, chunks, done))


def old_greedy(
    scorer: Scorer,
    n_sites: int,
    n_ris: int,
    spec: SearchSpec,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
    seeds: tuple[Layout, ...] = (),
) -> SearchOutcome:
    """Greedy forward selection (ties → the stronger site), then best-improvement swaps until
    no swap improves or ``max_rounds``; also from each smaller ``seeds`` layout (e.g. the best
    layout of the previous RIS count) completed greedily, and from ``restarts`` seeded random
    layouts."""
    memo: dict[Layout, float] = {}
    strength = site_strength(scorer)

    def score(cands: list[Layout]) -> list[float]:
        new = [c for c in dict.fromkeys(cands) if c not in memo]
        if new:
            vals = old_evaluate(scorer, np.array(new, dtype=int), executor)
            memo.update(zip(new, (float(v) for v in vals), strict=True))
        return [memo[c] for c in cands]

    def complete(partial: Layout) -> Layout:
        """Greedy forward selection from a partial layout; intermediate (smaller) layouts are
        scored on their own, ties (e.g. all underdetermined) go to the stronger site."""
        cur = list(partial)
        while len(cur) < n_ris:
            rest = [s for s in range(n_sites) if s not in cur]
            cand = np.array([sorted([*cur, s]) for s in rest], dtype=int)
            if len(cur) + 1 == n_ris:
                vals = np.array(score([tuple(int(x) for x in c) for c in cand]))
            else:
                vals = old_evaluate(scorer, cand, executor)
            key = np.lexsort((-strength[rest], vals))
            cur.append(rest[int(key[0])])
        return tuple(sorted(cur))

    starts: list[Layout] = [complete(())]
    for partial in seeds:
        if len(partial) < n_ris:
            starts.append(complete(tuple(partial)))
    rng = np.random.default_rng(spec.seed)
    for _ in range(spec.restarts):
        starts.append(tuple(sorted(int(x) for x in rng.choice(n_sites, n_ris, replace=False))))
    for i, start in enumerate(starts):
        layout = start
        best = score([layout])[0]
        for _ in range(spec.max_rounds):
            neigh = [
                tuple(sorted((*(x for x in layout if x != out_s), in_s)))
                for out_s in layout
                for in_s in range(n_sites)
                if in_s not in layout
            ]
            if not neigh:
                break
            nvals = score(neigh)
            j = min(range(len(neigh)), key=lambda k: (nvals[k], neigh[k]))
            if not nvals[j] < best:
                break
            layout, best = neigh[j], nvals[j]
        if on_fraction is not None:
            on_fraction((i + 1) / len(starts))
    return SearchOutcome(
        np.array(list(memo), dtype=int).reshape(len(memo), n_ris),
        np.array(list(memo.values())),
        method="greedy",
        total_layouts=math.comb(n_sites, n_ris),
    )


def ranked_order(losses: FloatArray, keys: tuple[Any, ...], k: int | None = None) -> IntArray:
    """Indices of the best ``k`` (all when None) losses [N], lower first, where a loss within
    :data:`RANK_RTOL` of the first loss of its group counts as equal to it: each group (from
    the smallest remaining loss up to that loss + RANK_RTOL·|loss|; every ``inf`` together) is
    ordered by ``keys`` (np.lexsort keys, the last one primary), so the order does not depend
    on rounding. ``nan`` ranks last."""
    n = losses.shape[0]
    k = n if k is None else min(k, n)
    order = np.lexsort((*keys, losses))
    ordered = losses[order]
    out: list[IntArray] = []
    taken, i = 0, 0
    while taken < k and i < n:
        first = float(ordered[i])
        if math.isnan(first):
            j = n
        else:
            limit = first + (RANK_RTOL * abs(first) if math.isfinite(first) else 0.0)
            j = i + 1 + int(np.searchsorted(ordered[i + 1 :], limit, side="right"))
        group = order[i:j]
        out.append(group[np.lexsort(tuple(key[group] for key in keys))] if keys else group)
        taken += j - i
        i = j
    if not out:
        return np.zeros(0, dtype=int)
    return np.concatenate(out)[:k]


def improves(new: float, old: float) -> bool:
    """Whether loss ``new`` is better than ``old`` by more than :data:`RANK_RTOL` (a search
    step that gains only rounding is not taken)."""
    if math.isnan(new):
        return False
    if not math.isfinite(old):
        return new < old
    return new < old - RANK_RTOL * abs(old)


def pre_quality_greedy(
    scorer: Scorer,
    n_sites: int,
    n_ris: int,
    spec: SearchSpec,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
    seeds: tuple[Layout, ...] = (),
    feasible: Feasibility | None = None,
) -> SearchOutcome:
    """Greedy forward selection (ties → the stronger site), then best-improvement swaps until
    no swap improves or ``max_rounds``; also from each smaller ``seeds`` layout (e.g. the best
    layout of the previous RIS count) completed greedily, and from ``restarts`` seeded random
    layouts. Under ``feasible`` every step stays inside the feasible layouts (required sites
    start every layout and are never swapped out)."""
    memo: dict[Layout, float] = {}
    strength = site_strength(scorer)
    cons = None if feasible is None or feasible.trivial else feasible

    def allowed(cands: list[Layout]) -> list[Layout]:
        if cons is None or not cands:
            return cands
        ok = cons.ok(np.array(cands, dtype=int))
        return [c for c, g in zip(cands, ok, strict=True) if g]

    def score(cands: list[Layout]) -> list[float]:
        new = [c for c in dict.fromkeys(cands) if c not in memo]
        if new:
            vals = evaluate(scorer, np.array(new, dtype=int), executor)
            memo.update(zip(new, (float(v) for v in vals), strict=True))
        return [memo[c] for c in cands]

    def complete(partial: Layout) -> Layout | None:
        """Greedy forward selection from a partial layout; intermediate (smaller) layouts are
        scored on their own, ties (e.g. all underdetermined) go to the stronger site."""
        cur = list(partial)
        while len(cur) < n_ris:
            if cons is None:
                rest = [s for s in range(n_sites) if s not in cur]
            else:
                rest = [int(s) for s in np.flatnonzero(cons.compatible(cur))]
                if not rest:
                    return None
            cand = np.array([sorted([*cur, s]) for s in rest], dtype=int)
            if len(cur) + 1 == n_ris:
                vals = np.array(score([tuple(int(x) for x in c) for c in cand]))
            else:
                vals = evaluate(scorer, cand, executor)
            best = ranked_order(vals, (np.arange(len(rest)), -strength[rest]), 1)[0]
            cur.append(rest[int(best)])
        return tuple(sorted(cur))

    first = complete(tuple(cons.required) if cons is not None else ())
    starts: list[Layout] = [] if first is None else [first]
    for partial in seeds:
        if len(partial) < n_ris and (cons is None or allowed([tuple(partial)])):
            done = complete(tuple(partial))
            if done is not None:
                starts.append(done)
    rng = np.random.default_rng(spec.seed)
    for _ in range(spec.restarts):
        if cons is None:
            starts.append(tuple(sorted(int(x) for x in rng.choice(n_sites, n_ris, replace=False))))
        else:
            drawn = cons.random_layout(n_ris, rng)
            if drawn is not None:
                starts.append(drawn)
    # every start's swap rounds run in lockstep: one evaluation call per round for all active
    # starts (bigger batches for the workers); each start's path is the one it takes alone
    vals0 = score(starts)
    cur = list(zip(starts, vals0, strict=True))
    active = list(range(len(starts)))
    n_done = 0
    for _ in range(spec.max_rounds):
        if not active:
            break
        neighs = {
            i: allowed(
                [
                    tuple(sorted((*(x for x in cur[i][0] if x != out_s), in_s)))
                    for out_s in cur[i][0]
                    for in_s in range(n_sites)
                    if in_s not in cur[i][0]
                ]
            )
            for i in active
        }
        score([c for i in active for c in neighs[i]])
        still = []
        for i in active:
            neigh = neighs[i]
            if neigh:
                nvals = np.array([memo[c] for c in neigh])
                j = int(ranked_order(nvals, _site_keys(np.array(neigh, dtype=int)), 1)[0])
                if improves(float(nvals[j]), cur[i][1]):
                    cur[i] = (neigh[j], float(nvals[j]))
                    still.append(i)
                    continue
            n_done += 1
            if on_fraction is not None:
                on_fraction(n_done / len(starts))
        active = still
    return SearchOutcome(
        np.array(list(memo), dtype=int).reshape(len(memo), n_ris),
        np.array(list(memo.values())),
        method="greedy",
        total_layouts=math.comb(n_sites, n_ris),
    )
