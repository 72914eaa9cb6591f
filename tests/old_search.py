"""Today's (pre-issue-14) greedy search and its chunking, kept verbatim: the reference the new
search must never lose to on the same input (tests/test_planning_decisions.py) and the
baseline of benchmarks/bench_search.py."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ris_planner.model.plan import SearchSpec
from ris_planner.planning.objectives import Scorer, score_chunk
from ris_planner.planning.search import (
    CHUNK_MATRICES,
    FloatArray,
    IntArray,
    Layout,
    SearchOutcome,
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
