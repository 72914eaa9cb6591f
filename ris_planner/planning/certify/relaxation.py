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
valid. Unordered pairs counted in both directions (``Scorer.mirror``) have 2P metric columns;
the reverse direction's PEB_R is this direction's PEB_T, a trace of the same K_p(S)⁻¹ over the
TX rows, so every column gets the relaxation of its own rows (:func:`metric_columns`).
``require``/``exclude`` and cliques of mutually exclusive sites (one mounting point) are
kept; other constraints (separation, budget) are dropped by the relaxation, which only widens
the set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import n_observations
from ris_planner.inversion.ldl import packed_index
from ris_planner.model.objectives import objective_kind
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.scoring.site_cache import KeptInformation

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


FW_GAP_RTOL = 1e-4
"""A pair's Frank–Wolfe stops once its duality gap f(z) − lower ≤ this · f(z): the bound is
then within 0.01 % of the relaxed optimum, which no further iteration can exceed."""


@dataclass
class RowRelaxation:
    """The relaxation of one metric column's trace Σ_{t∈rows} [K⁻¹]_tt for every pair.

    lower : [P] the best Frank–Wolfe lower bound on min_z f_p(z);
    const, grad : the tangent of the iterate that gave it (``None`` unless asked for):
    f̃_p(z) ≥ const_p + Σ_s grad[s, p] z_s for every z in the box (convexity), so a layout C
    (an indicator vertex) has f_p(C) ≥ const_p + Σ_{s∈C} grad[s, p] – the bound the
    branch-and-bound search (:mod:`ris_planner.planning.certify.branch_bound`) evaluates per
    subtree."""

    lower: FloatArray
    const: FloatArray | None = None
    grad: FloatArray | None = None


def _frank_wolfe(
    packed: KeptInformation,
    base: FloatArray,
    free: NDArray[np.bool_],
    k: int,
    n: int,
    rows: list[int],
    iterations: int,
    groups: NDArray[np.int_],
    settle: tuple[float, float] = (-np.inf, np.inf),
    tangent: bool = False,
) -> RowRelaxation:
    """Lower bounds on min over z of Σ_{t∈rows} [K(z)⁻¹]_tt per pair (the module docstring).

    packed : [E, S, P] site information; base : [E, P] fixed part (LOS + required sites);
    free : [S] sites z may use; k : Σ z; groups : [S] group of each site (Σ_group z ≤ 1: the
    sites of one mounting point). A pair stops iterating once its bound can no longer change
    the objective: f(z) ≤ settle[0] (the bound stays ≤ f(z) whatever follows), lower ≥
    settle[1] (bounds only rise), or its duality gap ≤ :data:`FW_GAP_RTOL`; ``tangent`` keeps
    the tangent of each pair's best iterate (:class:`RowRelaxation`; zero gradient on the
    sites z may not use). Only the free sites enter the iterations."""
    sel = np.flatnonzero(free)  # [F] the sites z may use
    _, dense = np.unique(groups[sel], return_inverse=True)
    grp = np.asarray(dense.reshape(-1), dtype=int)  # [F] their groups, 0 … G − 1
    n_groups = int(grp.max()) + 1
    order = np.argsort(grp, kind="stable")
    starts = np.searchsorted(grp[order], np.arange(n_groups))
    e_n, n_sites, p = packed.shape
    n_free = sel.size
    idx = packed_index(n)
    ii = np.array([i for i in range(n) for j in range(i + 1)])
    jj = np.array([j for i in range(n) for j in range(i + 1)])
    diag_e = np.array([idx[i, i] for i in range(n)])
    offdiag = np.ones(e_n)
    offdiag[ii != jj] = 2.0  # <M, F> over a symmetric pair of entries
    ridge = np.ones(e_n)
    ridge[diag_e] += RIDGE
    out = np.zeros(p)
    const = np.zeros(p) if tangent else None
    grads = np.zeros((n_sites, p)) if tangent else None
    diag = np.arange(n)
    for p0 in range(0, p, PAIR_BLOCK):
        act = np.arange(p0, min(p, p0 + PAIR_BLOCK))  # the pairs still iterating
        blk = packed.slab(sel, p0, int(act[-1]) + 1)  # [E, F, b]
        bse = base[:, act]
        z = np.full((n_free, act.size), k / n_free)  # [F, b]
        best = np.zeros(act.size)
        a_free = np.einsum("esb,sb->eb", blk, z)  # [E, b] Σ z_s F_s, then updated in place
        for t in range(iterations + 1):
            b = act.size
            # [E, b] relaxed FIM K̃(z), then [b, n, n] scaled to unit diagonal
            a = (bse + a_free) * ridge[:, None]
            mat = np.empty((b, n, n))
            mat[:, ii, jj] = a.T
            mat[:, jj, ii] = a.T
            d = np.sqrt(mat[:, diag, diag])  # [b, n]
            blank = d <= 0  # a state no site informs: adding e_i e_iᵀ only lowers the bound
            d[blank] = 1.0
            scaled = mat / d[:, :, None] / d[:, None, :]
            scaled[:, diag, diag] += blank
            inv = np.linalg.inv(scaled) / d[:, :, None] / d[:, None, :]  # [b, n, n] K̃⁻¹
            f = inv[:, rows, rows].sum(axis=1)  # [b]
            cols = inv[:, :, rows]  # [b, n, |T|]
            m = np.einsum("bit,bjt->bij", cols, cols)  # [b, n, n] K̃⁻¹ E_T K̃⁻¹
            mp = (m[:, ii, jj] * offdiag * ridge).T  # [E, b]
            grad = -np.einsum("esb,eb->sb", blk, mp)  # [F, b] ∂f/∂z_s
            pick = _vertex(grad, k, grp, order, starts, n_groups)  # [k, b] the vertex's sites
            g_v = np.take_along_axis(grad, pick, axis=0).sum(axis=0)  # [b] ∇f·v
            g_z = (grad * z).sum(axis=0)  # [b] ∇f·z
            lower = f + g_v - g_z
            good = np.isfinite(lower) & (lower > best)
            best[good] = lower[good]
            if tangent:
                assert const is not None and grads is not None
                tc = act[good]
                grads[np.ix_(sel, tc)] = grad[:, good]
                const[tc] = f[good] - g_z[good]
            out[act] = best
            if t == iterations:
                break
            go = (f > settle[0]) & (best < settle[1]) & (f - best > FW_GAP_RTOL * f)
            if not go.all():  # drop the settled pairs from the block
                act, blk, bse, z, best = act[go], blk[:, :, go], bse[:, go], z[:, go], best[go]
                a_free, pick = a_free[:, go], pick[:, go]
                if act.size == 0:
                    break
            gamma = 2.0 / (t + 2.0)
            z *= 1 - gamma
            np.put_along_axis(z, pick, np.take_along_axis(z, pick, axis=0) + gamma, axis=0)
            # Σ_s v_s F_s gathers the k chosen sites only (no pass over all sites)
            vert = np.take_along_axis(blk, pick[None, :, :], axis=1).sum(axis=1)  # [E, b]
            a_free = (1 - gamma) * a_free + gamma * vert
    return RowRelaxation(out, const, grads)


def _vertex(
    grad: FloatArray,
    k: int,
    groups: NDArray[np.int_],
    order: NDArray[np.int_],
    starts: NDArray[np.int_],
    n_groups: int,
) -> NDArray[np.int_]:
    """[k, b] the sites of the vertex v minimising grad·v over {0 ≤ z, Σ_group z ≤ 1,
    Σ z = k} per column: the k groups with the most negative best entry, their best site."""
    if n_groups == grad.shape[0]:  # singletons: the k most negative entries
        if k == 1:
            return np.argmin(grad, axis=0)[None, :]
        return np.argpartition(grad, k - 1, axis=0)[:k]
    g_sorted = grad[order]  # [F, b] grouped
    gmin = np.minimum.reduceat(g_sorted, starts, axis=0)  # [G, b]
    chosen = np.argpartition(gmin, k - 1, axis=0)[:k] if k < n_groups else None  # [k, b]
    # the best site of each group: the first minimum within the group's run of rows
    g_of = groups[order]
    hit = g_sorted == gmin[g_of]  # [F, b]
    first = np.zeros_like(hit)
    count = np.cumsum(hit, axis=0)
    before = np.concatenate([np.zeros((1, hit.shape[1]), dtype=count.dtype), count])[starts]
    first = hit & ((count - before[g_of]) == 1)
    rows_of = np.empty((n_groups, grad.shape[1]), dtype=int)  # [G, b] best site per group
    r, c = np.nonzero(first)
    rows_of[g_of[r], c] = order[r]
    if chosen is None:
        return rows_of
    return np.take_along_axis(rows_of, chosen, axis=0)


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


@dataclass
class SubsetProblem:
    """The relaxation's data for the feasible layouts of one count (``None`` fields: no layout
    has a finite metric, see :func:`subset_problem`)."""

    free: NDArray[np.bool_]
    """[S] sites a layout may add to the required ones."""
    k: int
    """Sites to add."""
    base: FloatArray
    """[E, P] LOS + the required sites' information."""
    groups: NDArray[np.int_]
    """[S] exclusive groups (:func:`exclusive_groups`)."""


def subset_problem(scorer: Scorer, n_ris: int, feasible: Feasibility) -> SubsetProblem | str:
    """The relaxation's data, or why every metric of this count is ``inf`` (``"blind"``: too
    few observations for the unknown states; ``"none"``: no feasible layout) or ``"single"``
    (only the required sites: one layout)."""
    keep, _, _ = scorer.states
    packed, los = scorer.selected_packed
    n_obs = n_observations(n_ris, los is not None, scorer.cache.wavefront)
    if n_obs is not None and n_obs < len(keep):
        return "blind"  # every layout of this count is underdetermined
    req = list(feasible.required)
    k = n_ris - len(req)
    if k == 0:
        return "single"
    free = feasible.allowed.copy()
    free[req] = False
    if req:  # sites in conflict with a required one are in no feasible layout
        free &= ~np.any(feasible.conflict[req], axis=0)
    groups = exclusive_groups(feasible, free)
    if len(np.unique(groups[free])) < k:
        return "none"
    p = scorer.cache.n_pairs
    base = np.zeros((packed.shape[0], p)) if los is None else los.copy()
    for r in req:
        base += packed.sites([r])[:, 0]
    return SubsetProblem(free, k, base, groups)


def metric_columns(scorer: Scorer) -> list[tuple[list[int], int]]:
    """(rows of the kept states, metric column block) for every trace the metric takes a
    square root of: block 0 holds this direction's P columns, block 1 the reverse direction's
    (``mirror``: the reverse direction's PEB_R is this direction's PEB_T, so its column is
    the relaxation of the TX rows of the same K_p). The metric of a column is the maximum of
    its traces' square roots (metric ``max``: PEB_T and PEB_R)."""
    _, tx, rx = scorer.states
    if scorer.mirror:
        first, second = (rx, tx) if scorer.objective.metric == "rx" else (tx, rx)
        return [(first, 0), (second, 1)]
    return [(rows, 0) for rows in (tx, rx) if rows]


def settle_limits(scorer: Scorer) -> tuple[float, float]:
    """Trace values beyond which a pair's bound no longer moves the objective of the bounds:
    coverage at threshold θ counts lb ≤ θ, so a relaxed value f(z) ≤ θ² stays counted and a
    bound with √lower·(1 − safety) > θ stays uncounted; mean_capped counts min(lb, cap), so a
    bound ≥ cap is final. Quantiles use every value (no limit). The objective kind's
    :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.settle_limits`."""
    obj = scorer.objective
    return objective_kind(obj.kind).settle_limits(obj, CERT_SAFETY)


def to_metric(trace_bound: FloatArray) -> FloatArray:
    """A metric bound from a trace bound: √ with the :data:`CERT_SAFETY` margin."""
    return np.sqrt(np.maximum(trace_bound, 0.0)) * (1.0 - CERT_SAFETY)


def row_relaxations(
    scorer: Scorer,
    problem: SubsetProblem,
    iterations: int,
    *,
    settle: bool = True,
    tangent: bool = False,
) -> list[RowRelaxation]:
    """One Frank–Wolfe relaxation per :func:`metric_columns` entry (``settle``: stop pairs
    whose bound cannot move the objective, :func:`settle_limits`)."""
    keep, _, _ = scorer.states
    packed, _ = scorer.selected_packed
    limits = settle_limits(scorer) if settle else (-np.inf, np.inf)
    return [
        _frank_wolfe(
            packed,
            problem.base,
            problem.free,
            problem.k,
            len(keep),
            rows,
            iterations,
            problem.groups,
            limits,
            tangent,
        )
        for rows, _ in metric_columns(scorer)
    ]


def combine_columns(scorer: Scorer, traces: list[FloatArray]) -> FloatArray:
    """[..., P] or [..., 2P] (mirror) metric bounds from one trace bound per
    :func:`metric_columns` entry: each column the maximum of its traces' metric bounds
    (max(PEB_T, PEB_R) ≥ each)."""
    blocks: dict[int, FloatArray] = {}
    for (_, col), tr in zip(metric_columns(scorer), traces, strict=True):
        lb = to_metric(tr)
        blocks[col] = lb if col not in blocks else np.maximum(blocks[col], lb)
    return np.concatenate([blocks[c] for c in sorted(blocks)], axis=-1)


def pair_lower_bounds(
    scorer: Scorer, n_ris: int, feasible: Feasibility, iterations: int, settle: bool = False
) -> FloatArray:
    """[P] lb_p ≤ the metric of pair p in every feasible layout of n_ris sites (``inf`` when
    every such layout is blind for the pair, as an underdetermined count is); [2P] with
    ``mirror``, in the columns of :meth:`Scorer.metric` (this direction, then the reverse).
    ``settle`` stops pairs early once their bound cannot change the objective (the objective of
    the bounds is the same; the bounds themselves may be lower)."""
    width = scorer.cache.n_pairs * (2 if scorer.mirror else 1)
    problem = subset_problem(scorer, n_ris, feasible)
    if problem == "single":  # one layout: its own metric
        return np.asarray(scorer.metric(np.array([sorted(feasible.required)], dtype=int))[0])
    if isinstance(problem, str):
        return np.full(width, np.inf)
    relax = row_relaxations(scorer, problem, iterations, settle=settle)
    return combine_columns(scorer, [r.lower for r in relax])


def relaxation_certificate(
    scorer: Scorer, n_ris: int, feasible: Feasibility, iterations: int
) -> Certificate:
    """The relaxation bound on the best loss of n_ris RISs (module docstring); pairs stop
    iterating once their bound cannot change the objective (:func:`settle_limits`)."""
    lb = pair_lower_bounds(scorer, n_ris, feasible, iterations, settle=True)
    obj = scorer.objective
    loss = float(
        objective_kind(obj.kind).relaxation_loss(obj, lb[None, :], scorer.metric_weights)[0]
    )
    return Certificate(loss, exact=False, method="frank_wolfe_pair_relaxation")
