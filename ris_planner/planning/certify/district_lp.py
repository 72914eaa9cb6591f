"""The district search's certificate (docs/concepts/district.md, "Certificate"): an upper
bound on the coverage of every layout of L sites and a lower bound on the count any layout
reaching a coverage needs, from a linear relaxation.

A pair covered by a layout C needs at least m_p of its serving sites in C (m_p from the
counting rule and, where few enough, from every m-subset of its sites: :func:`sites_needed`),
and none when even all its sites leave it above the threshold. So with z_s = 1[s ∈ C],
y_p = 1[p covered]: y_p ≤ Σ_{s∈S_p} z_s / m_p and Σ z = L. The linear relaxation
(0 ≤ y, z ≤ 1, HiGHS) bounds the best coverage of any L-site layout from above
(:func:`relaxed_coverage`); :func:`count_lower_bound` is the relaxation's smallest Σ z with
Σ w_p y_p ≥ target, rounded up.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog
from scipy.sparse import csr_matrix, vstack

from ris_planner.core.errors import RisPlannerError
from ris_planner.planning.scoring.sparse import (
    DistrictProblem,
    LayoutState,
    entry_metric,
    servable_pairs,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

MAX_SUBSETS = 4096
"""Per pair, the most m-subsets of its serving sites evaluated (:func:`sites_needed`): all
pairs of up to 91 serving sites; a pair with more keeps the counting rule's m_p and no cover
sets (still valid, looser)."""

MAX_SUBSET_EVALUATIONS = 2_000_000
"""In all, the most (pair, m-subset) combinations :func:`sites_needed` evaluates (about 2 µs
each): the pairs with the fewest subsets first; the others keep the counting rule's m_p and no
cover sets (still valid, looser). Forty serving sites per pair and m = 2 over 20 000 pairs
would otherwise be 15.6 million evaluations."""

SUBSET_BATCH = 200_000
"""(pair, subset) combinations evaluated per batch by :func:`sites_needed` (memory: about
300 bytes each)."""

LP_PAD = 1e-7
"""HiGHS' primal feasibility tolerance: the coverage bound is padded by it and the sizing
target lowered by it, so a relaxation solved to that tolerance still bounds."""


@dataclass(frozen=True)
class Needs:
    """What covering a pair takes (:func:`sites_needed`).

    need [P]: a lower bound m_p on the serving sites a layout needs for pair p to be covered
    (0: never covered); complete [P]: every m_p-subset of the pair's sites was tried and some
    covers it; cover_pair, cover_site [U]: for the complete pairs, each site that belongs to a
    covering m_p-subset (the union of the pair's cover sets), as (pair, site) in pair order."""

    need: IntArray
    complete: BoolArray
    cover_pair: IntArray
    cover_site: IntArray


def sites_needed(problem: DistrictProblem) -> Needs:
    """m_p and the cover sets' sites (:class:`Needs`).

    The counting rule gives m ≥ ⌈(k − LOS)/3⌉. Where a pair has at most :data:`MAX_SUBSETS`
    m-subsets they are all evaluated (in batches of at most :data:`SUBSET_BATCH`): the sites
    of the covering ones are recorded, and when none covers, m_p is raised by one and the
    (m+1)-subsets are tried the same way (a larger layout contains some m-subset, and adding
    information never raises a bound, so needing more than m is exact). At most
    :data:`MAX_SUBSET_EVALUATIONS` (pair, subset) combinations are evaluated in all, the pairs
    with the fewest subsets first. A pair that even all its serving sites leave above the
    threshold has m_p = 0."""
    pr = problem
    n_serving = np.diff(pr.pair_start)
    full = LayoutState(pr, list(range(pr.n_sites)))
    coverable = full.metric <= pr.threshold
    need = np.maximum(1, -(-(pr.n_kept - pr.los_present.astype(int)) // 3))
    if not pr.counting:
        need = np.ones(pr.n_pairs, dtype=int)
    need = np.where(coverable, need, 0)
    complete = np.zeros(pr.n_pairs, dtype=bool)
    used = np.zeros(pr.n_entries, dtype=bool)  # entries in some covering m_p-subset
    budget = MAX_SUBSET_EVALUATIONS
    for _ in range(2):  # m, then m + 1 for the pairs no m-subset covers
        tried = np.zeros(pr.n_pairs, dtype=bool)
        found = np.zeros(pr.n_pairs, dtype=bool)
        # the pairs with the fewest subsets first, within the budget left
        open_ = np.flatnonzero(coverable & ~complete & (need <= n_serving))
        n_subsets = np.array(
            [math.comb(int(n), int(m)) for n, m in zip(n_serving[open_], need[open_], strict=True)],
            dtype=float,
        )
        order = np.argsort(n_subsets, kind="stable")
        within = np.cumsum(n_subsets[order]) <= budget
        chosen = np.zeros(pr.n_pairs, dtype=bool)
        chosen[open_[order[within]]] = True
        chosen[open_[n_subsets > MAX_SUBSETS]] = False
        budget -= int(n_subsets[chosen[open_]].sum())
        for n in np.unique(n_serving[chosen]):
            for m in np.unique(need[chosen & (n_serving == n)]):
                group = np.flatnonzero(chosen & (n_serving == n) & (need == m))
                subsets = np.array(list(itertools.combinations(range(int(n)), int(m))))
                step = max(1, SUBSET_BATCH // len(subsets))
                for g0 in range(0, group.size, step):
                    part = group[g0 : g0 + step]
                    covers = _covering_subsets(pr, part, subsets)  # [G, C]
                    tried[part] = True
                    found[part] = covers.any(axis=1)
                    g, c = np.nonzero(covers)
                    used[pr.pair_start[part[g]][:, None] + subsets[c]] = True
        complete |= tried & found
        need = np.where(tried & ~found, need + 1, need)
    used &= complete[pr.entry_pair]
    return Needs(np.asarray(need), complete, pr.entry_pair[used], pr.entry_site[used])


def _covering_subsets(problem: DistrictProblem, group: IntArray, subsets: IntArray) -> BoolArray:
    """[G, C] whether each subset [C, m] (positions among a pair's serving sites) of each
    pair of the group covers it."""
    pr = problem
    m = subsets.shape[1]
    # [G, C, m] entries of every subset of every pair of the group
    entries = pr.pair_start[group][:, None, None] + subsets[None]
    info = pr.los.T[group][:, None] + pr.info[entries].sum(axis=2)
    flat_p = np.repeat(group, len(subsets))
    flat_e = entries.reshape(-1, m)
    count = pr.los_present[flat_p].astype(int) + 3 * m

    def rows(i: IntArray) -> FloatArray:
        f = pr.factor[flat_e[i]].reshape(len(i), -1, pr.n_kept)
        return np.concatenate([pr.los_factor[flat_p[i]], f], axis=1)

    metric = entry_metric(pr, info.reshape(-1, info.shape[-1]), rows, count)
    return np.asarray((metric <= pr.threshold).reshape(len(group), -1))


def _relaxation(problem: DistrictProblem, needs: Needs) -> tuple[csr_matrix, int, IntArray]:
    """The relaxation's constraints A v ≤ 0 over v = [z (S), y (live pairs), u (complete
    pairs)], the number of variables, and the live pairs (m_p > 0):

    * every live pair: y_p ≤ Σ_{s∈S_p} z_s / m_p (a covering layout holds m_p of its sites);
    * a pair with cover sets also: y_p ≤ Σ_{s∈U_p} z_s / m_p + u_p with U_p the sites of its
      covering m_p-subsets, and u_p ≤ Σ_{s∈S_p} z_s / (m_p + 1): a covering layout holds a
      covering m_p-subset (m_p sites of U_p) or at least m_p + 1 of its serving sites."""
    pr, need = problem, needs.need
    live = np.flatnonzero(need > 0)
    y_of = np.full(pr.n_pairs, -1)
    y_of[live] = pr.n_sites + np.arange(live.size)
    comp = np.flatnonzero(needs.complete & (need > 0))
    u_of = np.full(pr.n_pairs, -1)
    u_of[comp] = pr.n_sites + live.size + np.arange(comp.size)
    n_var = pr.n_sites + live.size + comp.size
    open_ = np.setdiff1d(live, comp)
    # rows: the open pairs' y, the complete pairs' y, the complete pairs' u
    row_y = np.full(pr.n_pairs, -1)
    row_y[open_] = np.arange(open_.size)
    row_y[comp] = open_.size + np.arange(comp.size)
    row_u = np.full(pr.n_pairs, -1)
    row_u[comp] = open_.size + comp.size + np.arange(comp.size)
    e_open = np.flatnonzero(np.isin(pr.entry_pair, open_))
    e_comp = np.flatnonzero(np.isin(pr.entry_pair, comp))
    rows = np.concatenate(
        [
            row_y[live],
            row_y[pr.entry_pair[e_open]],
            row_y[needs.cover_pair],
            row_y[comp],
            row_u[comp],
            row_u[pr.entry_pair[e_comp]],
        ]
    )
    cols = np.concatenate(
        [
            y_of[live],
            pr.entry_site[e_open],
            needs.cover_site,
            u_of[comp],
            u_of[comp],
            pr.entry_site[e_comp],
        ]
    )
    vals = np.concatenate(
        [
            np.ones(live.size),
            -1.0 / need[pr.entry_pair[e_open]],
            -1.0 / need[needs.cover_pair],
            -np.ones(comp.size),
            np.ones(comp.size),
            -1.0 / (need[pr.entry_pair[e_comp]] + 1),
        ]
    )
    n_rows = open_.size + 2 * comp.size
    # a complete pair's counting row too: a covering layout holds m_p of its sites (the cover
    # form alone is looser where the cover sets' sites are most of the pair's)
    row_c = np.full(pr.n_pairs, -1)
    row_c[comp] = n_rows + np.arange(comp.size)
    rows = np.concatenate([rows, row_c[comp], row_c[pr.entry_pair[e_comp]]])
    cols = np.concatenate([cols, y_of[comp], pr.entry_site[e_comp]])
    vals = np.concatenate([vals, np.ones(comp.size), -1.0 / need[pr.entry_pair[e_comp]]])
    n_rows += comp.size
    return csr_matrix((vals, (rows, cols)), shape=(n_rows, n_var)), n_var, live


def _bounds(
    problem: DistrictProblem, n_var: int, fixed: tuple[int, ...], excluded: tuple[int, ...]
) -> list[tuple[float, float]]:
    z = [(0.0, 1.0)] * problem.n_sites
    for s in fixed:
        z[s] = (1.0, 1.0)
    for s in excluded:
        z[s] = (0.0, 0.0)
    return z + [(0.0, 1.0)] * (n_var - problem.n_sites)


def _objective_y(problem: DistrictProblem, n_var: int, live: IntArray) -> FloatArray:
    """The vector w·y over the relaxation's variables (the live pairs' weights on y)."""
    c = np.zeros(n_var)
    c[problem.n_sites : problem.n_sites + live.size] = problem.weights[live]
    return c


def coverage_upper_bound(
    problem: DistrictProblem,
    count: int,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """An upper bound on the coverage of every layout of ``count`` sites (the relaxation of
    :func:`_relaxation`; ``needs`` from :func:`sites_needed`)."""
    return relaxed_coverage(problem, count, needs, required, excluded)[0]


def relaxed_coverage(
    problem: DistrictProblem,
    count: int,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> tuple[float, FloatArray]:
    """(:func:`coverage_upper_bound`, the relaxation's site weights z [S])."""
    a, n_var, live = _relaxation(problem, needs)
    if live.size == 0:
        return 0.0, np.zeros(problem.n_sites)
    eq = np.zeros(n_var)
    eq[: problem.n_sites] = 1.0
    res = linprog(
        -_objective_y(problem, n_var, live),
        A_ub=a,
        b_ub=np.zeros(a.shape[0]),
        A_eq=csr_matrix(eq[None]),
        b_eq=[float(count)],
        bounds=_bounds(problem, n_var, required, excluded),
        method="highs",
    )
    if res.status != 0:
        raise RisPlannerError(f"coverage relaxation failed: {res.message}")
    # HiGHS' optimum to its feasibility tolerance: pad by it so the bound stays a bound
    return float(min(1.0, -res.fun + LP_PAD)), np.asarray(res.x[: problem.n_sites])


def count_lower_bound(
    problem: DistrictProblem,
    target: float,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> int | None:
    """The fewest sites any layout reaching coverage ``target`` can have (relaxation: the
    smallest Σ z with Σ w_p y_p ≥ target, rounded up); ``None`` when no layout reaches it
    (the pairs some layout covers weigh less than the target: known before any LP)."""
    if float(problem.weights[needs.need > 0].sum()) < target - 1e-12:
        return None
    a, n_var, live = _relaxation(problem, needs)
    c = np.zeros(n_var)
    c[: problem.n_sites] = 1.0
    cover = -_objective_y(problem, n_var, live)
    res = linprog(
        c,
        A_ub=vstack([a, csr_matrix(cover[None])]).tocsr(),
        b_ub=np.concatenate([np.zeros(a.shape[0]), [-(target - LP_PAD)]]),
        bounds=_bounds(problem, n_var, required, excluded),
        method="highs",
    )
    if res.status != 0:
        return None
    return max(len(required), math.ceil(res.fun - 1e-6))


def summary(problem: DistrictProblem, needs: Needs) -> dict[str, Any]:
    """What the site can give at all: the pairs no candidate layout can serve (too few paths
    with every candidate: blind whatever the layout), those every candidate together still
    leaves blind numerically or above the threshold, and the coverable weight."""
    need = needs.need
    served = servable_pairs(problem)
    blind = ~served
    w = problem.weights
    short = (need == 0) & served
    return {
        "pairs": problem.n_pairs,
        "blind_everywhere": {"pairs": int(blind.sum()), "weight": float(w[blind].sum())},
        "above_threshold_everywhere": {"pairs": int(short.sum()), "weight": float(w[short].sum())},
        "coverable_weight": float(w[need > 0].sum()),
        "entries": problem.n_entries,
        "serving_sites_per_pair": float(np.diff(problem.pair_start).mean()),
        "pairs_with_cover_sets": int(needs.complete.sum()),
    }
