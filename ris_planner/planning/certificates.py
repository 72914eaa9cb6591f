"""Certificates: a provable bound on the best objective any feasible layout of L RISs can reach.

Per pair p and any layout S of L sites (required ones included), the metric is
m_p(S) = sqrt(Σ_{t∈T} [K_p(S)⁻¹]_tt) with K_p(S) = LOS_p + Σ_{s∈S} F_{s,p} on the kept states
(eq. FIM_measurement summed over paths; T the metric's TX or RX position states).

Relaxation (Joshi & Boyd, "Sensor selection via convex optimisation", 2009): with z ∈ [0, 1]^S,
Σ z = L, K_p(z) = LOS_p + Σ z_s F̃_{s,p} the trace f_p(z) = Σ_t [K_p(z)⁻¹]_tt is convex in z
(the matrix inverse is operator-convex), and every layout is a vertex of the relaxed set, so
min_z f_p ≤ min_S f_p(S). Frank–Wolfe on f_p gives, at every iterate, the lower bound
f_p(z) + min_v ∇f_p(z)·(v − z) ≤ min_z f_p (convexity; v a vertex: the L most negative
gradient entries; with exclusive mounting points Σ_spot z ≤ 1 as well, v one best site of each
of the L best spots). F̃ = F + ε·Diag(F) (:data:`RIDGE`) only adds information, so the bound
stays valid while every inversion stays well conditioned.

Then lb_p ≤ m_p(S) for every S, and every objective is monotone in each pair's metric
(coverage: non-increasing; mean of min(m, cap) and weighted quantiles: non-decreasing), so
objective(lb) bounds the optimum: ≥ it for coverage, ≤ it for mean_capped and quantile. Pairs
that are blind (``inf``) in every layout only make the optimum worse, so a finite lb_p is still
valid. ``require``/``exclude`` and cliques of mutually exclusive sites (one mounting point) are
kept; other constraints (separation, budget) are dropped by the relaxation, which only widens
the set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import n_observations
from ris_planner.ldl import packed_index
from ris_planner.planning.constraints import Feasibility
from ris_planner.planning.objectives import Scorer, loss_from_metric

FloatArray = NDArray[np.float64]

RIDGE = 1e-8
"""ε of F̃ = F + ε·Diag(F): keeps the unit-diagonal-scaled relaxed FIM's condition number below
~(1 + ε)/ε ≈ 1e8, so the float64 inverses carry ≲ 1e-8 relative error."""

CERT_SAFETY = 1e-6
"""Relative margin taken off every per-pair bound: two orders above the inversion error the
ridge allows, so rounding can never lift a bound above the optimum."""

PAIR_BLOCK = 4096
"""Pairs per Frank–Wolfe block (the [block, n, n] inverses and [S, block] gradients)."""


@dataclass(frozen=True)
class Certificate:
    """A bound on the best loss (lower is better) over the feasible layouts of one count.

    loss_bound ≤ min loss; ``exact`` when it is the optimum itself (exhaustive search)."""

    loss_bound: float
    exact: bool
    method: str


def _frank_wolfe(
    packed: FloatArray,
    base: FloatArray,
    free: NDArray[np.bool_],
    k: int,
    n: int,
    rows: list[int],
    iterations: int,
    groups: NDArray[np.int_],
) -> FloatArray:
    """[P] lower bound on min over z of Σ_{t∈rows} [K(z)⁻¹]_tt (the module docstring).

    packed : [E, S, P] site information; base : [E, P] fixed part (LOS + required sites);
    free : [S] sites z may use; k : Σ z; groups : [S] group of each site (Σ_group z ≤ 1: the
    sites of one mounting point)."""
    n_groups = int(groups.max()) + 1
    order = np.argsort(groups, kind="stable")
    starts = np.searchsorted(groups[order], np.arange(n_groups))
    e_n, _, p = packed.shape
    idx = packed_index(n)
    ii = np.array([i for i in range(n) for j in range(i + 1)])
    jj = np.array([j for i in range(n) for j in range(i + 1)])
    diag_e = np.array([idx[i, i] for i in range(n)])
    offdiag = np.ones(e_n)
    offdiag[ii != jj] = 2.0  # <M, F> over a symmetric pair of entries
    ridge = np.ones(e_n)
    ridge[diag_e] += RIDGE
    n_free = int(free.sum())
    out = np.zeros(p)
    for p0 in range(0, p, PAIR_BLOCK):
        sl = slice(p0, min(p, p0 + PAIR_BLOCK))
        blk = packed[:, :, sl]  # [E, S, b]
        b = blk.shape[2]
        z = np.where(free, k / n_free, 0.0)[:, None] * np.ones((1, b))  # [S, b]
        best = np.zeros(b)
        a_free = np.einsum("esb,sb->eb", blk, z)  # [E, b] Σ z_s F_s, then updated in place
        for t in range(iterations + 1):
            # [E, b] relaxed FIM K̃(z), then [b, n, n] scaled to unit diagonal
            a = (base[:, sl] + a_free) * ridge[:, None]
            mat = np.empty((b, n, n))
            mat[:, ii, jj] = a.T
            mat[:, jj, ii] = a.T
            d = np.sqrt(mat[:, np.arange(n), np.arange(n)])  # [b, n]
            blank = d <= 0  # a state no site informs: adding e_i e_iᵀ only lowers the bound
            d[blank] = 1.0
            scaled = mat / d[:, :, None] / d[:, None, :]
            scaled[:, np.arange(n), np.arange(n)] += blank
            inv = np.linalg.inv(scaled) / d[:, :, None] / d[:, None, :]  # [b, n, n] K̃⁻¹
            f = inv[:, rows, rows].sum(axis=1)  # [b]
            cols = inv[:, :, rows]  # [b, n, |T|]
            m = np.einsum("bit,bjt->bij", cols, cols)  # [b, n, n] K̃⁻¹ E_T K̃⁻¹
            mp = (m[:, ii, jj] * offdiag * ridge).T  # [E, b]
            grad = -np.einsum("esb,eb->sb", blk, mp)  # [S, b] ∂f/∂z_s
            grad[~free] = np.inf
            v = _vertex(grad, k, groups, order, starts, n_groups)
            g_fin = np.where(free[:, None], grad, 0.0)
            lower = f + (g_fin * (v - z)).sum(axis=0)
            good = np.isfinite(lower)
            best[good] = np.maximum(best[good], lower[good])
            if t < iterations:
                gamma = 2.0 / (t + 2.0)
                z = (1 - gamma) * z + gamma * v
                # Σ_s v_s F_s gathers the k chosen sites only (no pass over all S)
                pick = np.argpartition(-v, k - 1, axis=0)[:k]  # [k, b]
                vert = np.take_along_axis(blk, pick[None, :, :], axis=1).sum(axis=1)  # [E, b]
                a_free = (1 - gamma) * a_free + gamma * vert
        out[sl] = best
    return out


def _vertex(
    grad: FloatArray,
    k: int,
    groups: NDArray[np.int_],
    order: NDArray[np.int_],
    starts: NDArray[np.int_],
    n_groups: int,
) -> FloatArray:
    """[S, b] the vertex v minimising grad·v over {0 ≤ z, Σ_group z ≤ 1, Σ z = k}: the k groups
    with the most negative best entry, one (their best) site each."""
    if n_groups == grad.shape[0]:  # singletons: the k most negative entries
        pick = np.argpartition(grad, k - 1, axis=0)[:k]  # [k, b]
        v = np.zeros_like(grad)
        np.put_along_axis(v, pick, 1.0, axis=0)
        return v
    g_sorted = grad[order]  # [S, b] grouped
    gmin = np.minimum.reduceat(g_sorted, starts, axis=0)  # [G, b]
    pick = np.argpartition(gmin, k - 1, axis=0)[:k]  # [k, b] chosen groups
    chosen = np.zeros(gmin.shape, dtype=bool)
    np.put_along_axis(chosen, pick, True, axis=0)
    g_of = groups[order]
    hit = chosen[g_of] & (g_sorted == gmin[g_of])  # [S, b] best sites of chosen groups
    count = np.cumsum(hit, axis=0)
    before = np.concatenate([np.zeros((1, hit.shape[1]), dtype=count.dtype), count])[starts]
    hit &= (count - before[g_of]) == 1  # the first best site of each group only
    v = np.zeros_like(grad)
    v[order] = hit
    return v


def exclusive_groups(feasible: Feasibility, free: NDArray[np.bool_]) -> NDArray[np.int_]:
    """[S] group ids for Σ_group z ≤ 1: connected components of the conflict graph among the
    free sites that are cliques (every two members conflict, so a feasible layout holds at most
    one); other sites are their own group, which only loosens the relaxation."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    conf = feasible.conflict & free[:, None] & free[None, :]
    _, comp = connected_components(csr_matrix(conf), directed=False)
    groups = np.arange(len(comp))
    for c in np.unique(comp):
        members = np.flatnonzero(comp == c)
        sub = conf[np.ix_(members, members)]
        if len(members) > 1 and sub.sum() == len(members) * (len(members) - 1):
            groups[members] = members[0]
    _, dense = np.unique(groups, return_inverse=True)
    return np.asarray(dense.reshape(-1), dtype=int)


def pair_lower_bounds(
    scorer: Scorer, n_ris: int, feasible: Feasibility, iterations: int
) -> FloatArray:
    """[P] lb_p ≤ the metric of pair p in every feasible layout of n_ris sites (``inf`` when
    every such layout is blind for the pair, as an underdetermined count is)."""
    keep, tx, rx = scorer.states
    packed, los = scorer.selected_packed
    p = scorer.cache.n_pairs
    n_obs = n_observations(n_ris, los is not None, scorer.cache.wavefront)
    if n_obs is not None and n_obs < len(keep):
        return np.full(p, np.inf)  # every layout of this count is underdetermined: all inf
    req = list(feasible.required)
    k = n_ris - len(req)
    if k == 0:  # one layout: its own metric
        return np.asarray(scorer.metric(np.array([sorted(req)], dtype=int))[0])
    free = feasible.allowed.copy()
    free[req] = False
    if req:  # sites in conflict with a required one are in no feasible layout
        free &= ~np.any(feasible.conflict[req], axis=0)
    groups = exclusive_groups(feasible, free)
    if len(np.unique(groups[free])) < k:
        return np.full(p, np.inf)  # no layout at all
    base = np.zeros((packed.shape[0], p)) if los is None else los.copy()
    for r in req:
        base += packed[:, r]
    n = len(keep)
    out = None
    for rows in (tx, rx):
        if not rows:
            continue
        tr = _frank_wolfe(packed, base, free, k, n, rows, iterations, groups)
        lb = np.sqrt(np.maximum(tr, 0.0)) * (1.0 - CERT_SAFETY)
        out = lb if out is None else np.maximum(out, lb)  # max(PEB_T, PEB_R) ≥ each
    assert out is not None
    return out


def relaxation_certificate(
    scorer: Scorer, n_ris: int, feasible: Feasibility, iterations: int
) -> Certificate:
    """The relaxation bound on the best loss of n_ris RISs (module docstring)."""
    lb = pair_lower_bounds(scorer, n_ris, feasible, iterations)
    loss = float(loss_from_metric(scorer.objective, lb[None, :], scorer.weights)[0])
    return Certificate(loss, exact=False, method="frank_wolfe_pair_relaxation")
