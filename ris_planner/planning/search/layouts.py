"""Placement search: exhaustive over all C(S, L) layouts within a limit, otherwise greedy
forward selection plus swap-based local search from seeded random restarts.

Infinite losses (a quantile objective whose blind pairs weigh more than 1 − q) are equal as
losses; the search orders them by a tie-break (:meth:`Scorer.ranked_loss`: by default the
weight of the pairs with a finite bound, more first), so greedy steps and swaps climb out of
an all-infinite region towards a finite layout instead of stopping there, and a finite loss
always ranks before every infinite one. A NaN loss (no bound) counts as ``inf``.
docs/concepts/planning.md, "Search"."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import LimitExceededError
from ris_planner.inversion.ldl import packed_index
from ris_planner.model.plan import SearchSpec
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.scoring.scorer import Scorer, score_chunk, score_chunk_ranked, site_groups
from ris_planner.planning.scoring.site_cache import N_STATES, SiteCache
from ris_planner.runtime.executor import Executor

IntArray = NDArray[np.int_]
FloatArray = NDArray[np.float64]

CHUNK_MATRICES = 4_000_000
"""Layout × pair evaluations per executor task at most: ≈ 0.3–0.5 s of work on one core at
the measured 8–13 M matrices/s, so transfer and scheduling (a task carries its layouts and a
few-KB handle of the shared scorer) stay a small fraction while the last task of a call leaves
the other workers idle for a fraction of a second only."""

Layout = tuple[int, ...]

NO_LIMIT = 2**62

RANK_RTOL = 1e-6
"""Losses closer than this (relative) are equal for every decision of the search and the
ranking: the bounds a loss is made of are accurate to relative 1e-6 (docs/concepts/numerics.md),
so a smaller difference is rounding – it differs between BLAS kernels, SIMD dispatch and
processes – and must not pick the recommended layout. Equal losses are ranked by a fixed key
(the sites' indices, or the site strength in greedy forward steps); infinite losses first by
their tie-break (:data:`TIEBREAK_ATOL`)."""

TIEBREAK_ATOL = 1e-9
"""Tie-breaks (minus a weight fraction in [−1, 0]) closer than this are equal: far above the
rounding of a sum of ≤ 10⁷ weights (~1e-12), far below one pair's weight in any plan."""


def _site_keys(layouts: IntArray) -> tuple[IntArray, ...]:
    """np.lexsort keys ordering layouts [N, L] by site 0, then site 1, …"""
    return tuple(layouts[:, c] for c in range(layouts.shape[1] - 1, -1, -1))


def ranked_order(
    losses: FloatArray,
    keys: tuple[Any, ...],
    k: int | None = None,
    tiebreak: FloatArray | None = None,
) -> IntArray:
    """Indices of the best ``k`` (all when None) losses [N], lower first, where a loss within
    :data:`RANK_RTOL` of the first loss of its group counts as equal to it: each group (from
    the smallest remaining loss up to that loss + RANK_RTOL·|loss|; every ``inf`` together) is
    ordered by ``keys`` (np.lexsort keys, the last one primary), so the order does not depend
    on rounding; the ``inf`` group first by ``tiebreak`` [N] (lower first, rounded to
    :data:`TIEBREAK_ATOL`) when given. ``nan`` ranks last."""
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
        gkeys = tuple(key[group] for key in keys)
        if tiebreak is not None and first == math.inf:
            gkeys = (*gkeys, np.round(tiebreak[group] / TIEBREAK_ATOL))
        out.append(group[np.lexsort(gkeys)] if gkeys else group)
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
    if math.isnan(old):
        return True
    if not math.isfinite(old):
        return new < old
    return new < old - RANK_RTOL * abs(old)


def improves_ranked(new: tuple[float, float], old: tuple[float, float]) -> bool:
    """:func:`improves` on (loss, tie-break) pairs: between two infinite losses, whether the
    tie-break is lower by more than :data:`TIEBREAK_ATOL`."""
    if new[0] == math.inf and old[0] == math.inf:
        return new[1] < old[1] - TIEBREAK_ATOL
    return improves(new[0], old[0])


@dataclass
class SearchOutcome:
    """Every evaluated layout [N, L] (sorted site indices) with its loss [N] (lower is better),
    and how the search ran."""

    layouts: IntArray
    losses: FloatArray
    method: str = "exhaustive"
    total_layouts: int = 0
    tiebreak: FloatArray | None = None
    """[N] the order of infinite losses (:meth:`Scorer.ranked_loss`), or None: by site."""

    @property
    def evaluated(self) -> int:
        return int(self.losses.shape[0])

    def ranked_index(self, k: int) -> IntArray:
        """Rows of the best k layouts (:func:`ranked_order`: losses equal to
        :data:`RANK_RTOL` ranked by the sites' indices – deterministic on every machine)."""
        return ranked_order(self.losses, _site_keys(self.layouts), k, self.tiebreak)

    def ranked(self, k: int) -> list[tuple[Layout, float]]:
        """The best k layouts, equal losses ranked by the sites' indices (deterministic)."""
        order = self.ranked_index(k)
        return [(tuple(int(s) for s in self.layouts[i]), float(self.losses[i])) for i in order]

    def as_dict(self) -> dict[Layout, float]:
        """layout → loss (for small outcomes)."""
        return {
            tuple(int(s) for s in lay): float(v)
            for lay, v in zip(self.layouts, self.losses, strict=True)
        }


MIN_TASK_MATRICES = 250_000
"""A batch is split into more tasks (up to :data:`TASKS_PER_WORKER` per worker) while each
still holds at least this many layout × pair evaluations (≈ 25 ms: far above a task's
scheduling cost of about a millisecond; the site cache is already on every worker). A greedy
step that completes a layout (≈ S candidates × P pairs: 1 M on the hall) is split too."""

TASKS_PER_WORKER = 4
"""Tasks per worker a batch is split into when it is large enough (:data:`MIN_TASK_MATRICES`):
a task's cost varies with its share of ill-conditioned pairs (the square-root route), and
several tasks per worker even that out."""

SITE_BLOCKS = 8
"""Site blocks of a cluster search: a task carries the blocks holding the sites its layouts
use (:func:`_task_groups`), each block sent to the cluster once."""

CLUSTER_TASK_MATRICES = 16_000_000
"""Layout × pair evaluations per cluster task at most (≈ 1 s on one core): a task first gathers
the ≲ 70 sites it uses from its blocks (~0.1 s at 50 000 pairs), which larger tasks amortise."""


def score_block_task(_shared: object, task: tuple[Any, list[SiteCache], IntArray]) -> FloatArray:
    """Executor task: the losses of layouts over the site blocks it carries (indices into
    their concatenation), scored on a cache of just the sites the layouts use (gathered once:
    a 6-RIS swap batch uses ~70 of the ~320 sites of its blocks)."""
    scorer, local = _block_scorer(task)
    return scorer.loss(local)


def score_block_task_ranked(
    _shared: object, task: tuple[Any, list[SiteCache], IntArray]
) -> FloatArray:
    """:func:`score_block_task` giving [B, 2] (loss, tie-break) (:meth:`Scorer.ranked_loss`)."""
    scorer, local = _block_scorer(task)
    return scorer.ranked_loss(local)


def _block_scorer(task: tuple[Any, list[SiteCache], IntArray]) -> tuple[Scorer, IntArray]:
    """(a scorer on the cache of the sites a block task's layouts use, the layouts in it)."""
    (weights, objective, known), parts, local = task
    used = np.unique(local)
    start = np.cumsum([0, *(c.n_sites for c in parts)])
    picks = [used[(used >= s0) & (used < s1)] - s0 for s0, s1 in itertools.pairwise(start)]
    cache = SiteCache.concat(parts, picks)
    return Scorer(cache, weights, objective, known), np.searchsorted(used, local)


def _evaluate_blocks(
    scorer: Scorer,
    layouts: IntArray,
    executor: Executor,
    on_fraction: Callable[[float], None] | None,
    n_blocks: int = SITE_BLOCKS,
    tiebreak: bool = False,
) -> FloatArray:
    """:func:`evaluate` on a cluster: tasks carry handles of only the site blocks their
    layouts use (each block sent once per executor; layouts grouped by :func:`_task_groups`),
    scores bit-identical to the whole cache's."""
    n_sites = scorer.cache.n_sites
    size = max(1, math.ceil(n_sites / n_blocks))
    # the executor keeps the handles of the current scorer's base and blocks (each sent once)
    memo = executor.block_memo
    if memo is None or memo[0] is not scorer:
        executor.release()  # the previous scorer's blocks
        blocks = [
            executor.share(scorer.cache.subset(np.arange(s0, min(n_sites, s0 + size))))
            for s0 in range(0, n_sites, size)
        ]
        base = executor.share((scorer.weights, scorer.objective, scorer.known))
        memo = executor.block_memo = (scorer, base, blocks)
    _, base, blocks = memo
    per = max(1, CLUSTER_TASK_MATRICES // max(1, scorer.cache.n_pairs))
    tasks: list[tuple[Any, list[Any], IntArray]] = []
    rows_of: list[IntArray] = []
    for group in _task_groups(layouts, n_sites, size, size + 2 * layouts.shape[1]):
        for c0 in range(0, group.size, per):
            rows = group[c0 : c0 + per]
            carried = np.unique(layouts[rows] // size)  # the blocks the task carries
            ranges = [np.arange(b * size, min(n_sites, (b + 1) * size)) for b in carried]
            local = np.searchsorted(np.concatenate(ranges), layouts[rows])
            tasks.append((base, [blocks[int(b)] for b in carried], local))
            rows_of.append(rows)
    out = np.empty((layouts.shape[0], 2) if tiebreak else layouts.shape[0])

    def done_t(n: int) -> None:
        if on_fraction is not None:
            on_fraction(n / len(tasks))

    task_fn = score_block_task_ranked if tiebreak else score_block_task
    for rows, vals in zip(rows_of, executor.map(task_fn, None, tasks, done_t), strict=True):
        out[rows] = vals
    return out


def _task_groups(layouts: IntArray, n_sites: int, size: int, max_sites: int) -> list[IntArray]:
    """Rows of layouts [B, L] in groups that use ≤ max_sites sites together (≥ L), for the
    cluster's tasks: ordered by each layout's rarest site in the batch (a swap batch's
    candidate: the fixed sites are in nearly every layout), so the layouts whose candidates
    lie in one site block go together – L × size layouts on size + L sites – instead of one
    task per block combination; a run that uses more sites is cut by
    :func:`ris_planner.planning.scoring.scorer.site_groups`."""
    freq = np.bincount(layouts.reshape(-1), minlength=n_sites)
    rare = np.take_along_axis(layouts, np.argmin(freq[layouts], axis=1)[:, None], axis=1)[:, 0]
    order = np.argsort(rare // size, kind="stable")
    cuts = np.flatnonzero(np.diff(rare[order] // size)) + 1
    groups: list[IntArray] = []
    for run in np.split(order, cuts):
        if np.unique(layouts[run]).size <= max_sites:
            groups.append(run)
        else:
            groups += [run[rows] for rows, _ in site_groups(layouts[run], max_sites)]
    return groups


def chunk_count(n_layouts: int, n_pairs: int, workers: int) -> int:
    """Tasks for a batch of layouts: none above :data:`CHUNK_MATRICES` evaluations, up to
    :data:`TASKS_PER_WORKER` per worker while each keeps ≥ :data:`MIN_TASK_MATRICES`, and a
    multiple of the workers when there are several (each worker gets as many); ≤ n_layouts."""
    work = n_layouts * max(1, n_pairs)
    balance = 1
    if workers > 1 and work >= workers * MIN_TASK_MATRICES:
        balance = min(TASKS_PER_WORKER * workers, work // MIN_TASK_MATRICES)
    n = max(math.ceil(work / CHUNK_MATRICES), balance)
    if n > 1:
        n = math.ceil(n / workers) * workers
    return max(1, min(n_layouts, n))


def evaluate(
    scorer: Scorer,
    layouts: IntArray,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
    *,
    tiebreak: bool = False,
) -> FloatArray:
    """Losses [B] of layouts [B, L] (with ``tiebreak``: [B, 2] (loss, tie-break),
    :meth:`Scorer.ranked_loss`), split into chunks of ≈ :data:`CHUNK_MATRICES` evaluations
    (on a cluster, :func:`_evaluate_blocks`: each task carries only its site blocks). A NaN
    loss is returned as ``inf``."""
    b = layouts.shape[0]
    if b == 0:
        return np.empty((0, 2) if tiebreak else 0)
    if executor.site_blocks:
        out = _evaluate_blocks(scorer, layouts, executor, on_fraction, tiebreak=tiebreak)
    else:
        n_chunks = chunk_count(b, scorer.cache.n_pairs, executor.workers)
        chunks = np.array_split(layouts, n_chunks)  # n_chunks ≤ b: none is empty

        def done(n: int) -> None:
            if on_fraction is not None:
                on_fraction(n / len(chunks))

        task = score_chunk_ranked if tiebreak else score_chunk
        out = np.concatenate(executor.map(task, scorer, chunks, done))
    loss = out[:, 0] if tiebreak else out
    loss[np.isnan(loss)] = np.inf
    return out


def all_layouts(n_sites: int, n_ris: int) -> IntArray:
    """Every layout [C(S, L), L] of n_ris among n_sites, lexicographic."""
    total = math.comb(n_sites, n_ris)
    flat = np.fromiter(
        itertools.chain.from_iterable(itertools.combinations(range(n_sites), n_ris)),
        dtype=int,
        count=total * n_ris,
    )
    return flat.reshape(total, n_ris)


def exhaustive(
    scorer: Scorer,
    n_sites: int,
    n_ris: int,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
    feasible: Feasibility | None = None,
    layouts: IntArray | None = None,
) -> SearchOutcome:
    """Every layout (every feasible one under ``feasible``; ``layouts`` when already
    enumerated)."""
    if layouts is None:
        if feasible is None or feasible.trivial:
            layouts = all_layouts(n_sites, n_ris)
        else:
            # no limit: the caller checked the feasible count (partial layouts of a large L
            # may outnumber the complete ones)
            enum = feasible.enumerate(n_ris, NO_LIMIT)
            assert enum is not None
            layouts = enum
    total = int(layouts.shape[0])
    ranked = evaluate(scorer, layouts, executor, on_fraction, tiebreak=True)
    return SearchOutcome(
        layouts,
        np.ascontiguousarray(ranked[:, 0]),
        method="exhaustive",
        total_layouts=total,
        tiebreak=np.ascontiguousarray(ranked[:, 1]),
    )


def site_strength(scorer: Scorer) -> FloatArray:
    """[S] weighted mean trace of each site's information on the metric's position states,
    a tie-breaker for greedy steps whose partial layouts are all underdetermined."""
    keep, tx, rx = scorer.states
    idx = packed_index(N_STATES)
    targets = [keep[i] for i in tx + rx]
    info = scorer.cache.information(np.array([idx[t, t] for t in targets]))  # [T, S, P]
    tr = sum(info[k] for k in range(len(targets)))
    return np.asarray(tr @ scorer.weights)


def greedy(
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
    start every layout and are never swapped out).

    Every comparison is on (loss, tie-break) (:meth:`Scorer.ranked_loss`): where the losses
    are infinite, a step or swap towards more pairs with a finite bound is taken, so a start
    in an all-infinite region does not stop there (:func:`improves_ranked`)."""
    memo: dict[Layout, tuple[float, float]] = {}
    strength = site_strength(scorer)
    cons = None if feasible is None or feasible.trivial else feasible

    def allowed(cands: list[Layout]) -> list[Layout]:
        if cons is None or not cands:
            return cands
        ok = cons.ok(np.array(cands, dtype=int))
        return [c for c, g in zip(cands, ok, strict=True) if g]

    def score(cands: list[Layout]) -> list[tuple[float, float]]:
        new = [c for c in dict.fromkeys(cands) if c not in memo]
        if new:
            vals = evaluate(scorer, np.array(new, dtype=int), executor, tiebreak=True)
            memo.update(zip(new, ((float(v), float(t)) for v, t in vals), strict=True))
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
                vals = evaluate(scorer, cand, executor, tiebreak=True)
            keys = (np.arange(len(rest)), -strength[rest])
            best = ranked_order(vals[:, 0], keys, 1, vals[:, 1])[0]
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
                keys = _site_keys(np.array(neigh, dtype=int))
                j = int(ranked_order(nvals[:, 0], keys, 1, nvals[:, 1])[0])
                if improves_ranked(memo[neigh[j]], cur[i][1]):
                    cur[i] = (neigh[j], memo[neigh[j]])
                    still.append(i)
                    continue
            n_done += 1
            if on_fraction is not None:
                on_fraction(n_done / len(starts))
        active = still
    ranked = np.array(list(memo.values())).reshape(len(memo), 2)
    return SearchOutcome(
        np.array(list(memo), dtype=int).reshape(len(memo), n_ris),
        np.ascontiguousarray(ranked[:, 0]),
        method="greedy",
        total_layouts=math.comb(n_sites, n_ris),
        tiebreak=np.ascontiguousarray(ranked[:, 1]),
    )


def search(
    scorer: Scorer,
    n_sites: int,
    n_ris: int,
    spec: SearchSpec,
    executor: Executor,
    on_fraction: Callable[[float], None] | None = None,
    seeds: tuple[Layout, ...] = (),
    feasible: Feasibility | None = None,
) -> SearchOutcome:
    """The search the spec asks for (``auto``: exhaustive within ``max_exhaustive`` feasible
    layouts); greedy also starts from the ``seeds`` (smaller layouts, completed greedily)."""
    total = math.comb(n_sites, n_ris)
    layouts = None
    if feasible is not None and not feasible.trivial and spec.method != "greedy":
        total = feasible.count_upper(n_ris)
        if total > spec.max_exhaustive:  # the feasible ones may still fit: count them
            layouts = feasible.enumerate(n_ris, spec.max_exhaustive)
            if layouts is not None:
                total = int(layouts.shape[0])
    method = spec.method
    if method == "auto":
        method = "exhaustive" if total <= spec.max_exhaustive else "greedy"
    if method == "exhaustive":
        if total > spec.max_exhaustive:
            raise LimitExceededError(
                f"{total} layouts of {n_ris} among {n_sites} sites exceed"
                f" search.max_exhaustive = {spec.max_exhaustive}; use method 'greedy' or 'auto'",
                spec.max_exhaustive,
            )
        return exhaustive(scorer, n_sites, n_ris, executor, on_fraction, feasible, layouts)
    out = greedy(scorer, n_sites, n_ris, spec, executor, on_fraction, seeds, feasible)
    if feasible is not None and not feasible.trivial:
        out.total_layouts = feasible.count_upper(n_ris)
    return out
