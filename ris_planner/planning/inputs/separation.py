"""Sidelink pairs: two UEs near each other (docs/concepts/planning.md, "Pairs").

A sidelink pair is drawn among the TX–RX combinations at most ``max_separation_m`` apart, with
probability ∝ w_i · w_j (two independently placed UEs, conditioned on being within range). The
separation is the straight 3D distance, or along the streets: the shortest way between the two
UEs that follows the roads' centre lines, plus each UE's lateral offset from its centre line
(two UEs on one straight piece of road: their straight distance). Both are lengths of a real
path between the UEs, so neither is below the straight distance, and the candidates of a street
separation are found among the straight neighbours first (a k-d tree) before the road graph is
walked (Dijkstra, cut at the separation).

With ``line_of_sight`` only pairs whose TX–RX leg is clear are drawn: rejection from the same
distribution, with the verdict of each combination kept, so a draw never rechecks a leg and the
accepted pairs follow the conditioned distribution exactly.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ris_planner.bounds.paths import los_clear
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.plan import PairSample
from ris_planner.model.scenario import MIN_UE_RIS_DISTANCE_M

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

MAX_NEAR_COMBINATIONS = 20_000_000
"""The largest number of TX–RX combinations within the separation that a draw enumerates
(memory: 32 bytes each); beyond it the document is refused before any bound is computed."""

NODE_MERGE_M = 1e-3
"""Road vertices closer than this (rounded to this grid) are one node of the road graph: the
shared vertex of two roads at a junction."""

SOURCE_CHUNK = 256
"""Road-graph nodes walked per Dijkstra call (memory: one row of node distances each)."""


def near_combinations(
    tx: FloatArray,
    rx: FloatArray,
    tx_street: FloatArray | None,
    rx_street: FloatArray | None,
    spec: PairSample,
) -> tuple[IntArray, IntArray]:
    """(TX index, RX index) of every combination of distinct positions ``tx`` [M, 3], ``rx``
    [N, 3] within the document's separation, in (TX, RX) index order (the street columns of
    :class:`~ris_planner.planning.inputs.ue_maps.PointMap` for a street separation); raises when
    there
    is none or too many."""
    radius = np.inf if spec.max_separation_m is None else float(spec.max_separation_m)
    tree_t, tree_r = cKDTree(tx), cKDTree(rx)
    count = int(tree_t.count_neighbors(tree_r, radius))
    if count > MAX_NEAR_COMBINATIONS:
        raise LimitExceededError(
            f"pairs.max_separation_m = {radius:g} m gives {count} TX–RX combinations to draw"
            f" from, above the limit of {MAX_NEAR_COMBINATIONS}; lower max_separation_m or"
            " sample the maps more coarsely",
            MAX_NEAR_COMBINATIONS,
        )
    near = tree_t.sparse_distance_matrix(tree_r, radius, output_type="ndarray")
    order = np.lexsort((near["j"], near["i"]))
    it, ir, d = near["i"][order], near["j"][order], near["v"][order]
    keep = d >= MIN_UE_RIS_DISTANCE_M
    if spec.separation == "street":
        keep &= street_distance(tx_street, rx_street, it, ir, radius) <= radius
    if not np.any(keep):
        how = "along the streets" if spec.separation == "street" else "apart"
        raise RisPlannerError(
            f"no TX–RX pair of distinct positions is at most max_separation_m = {radius:g} m"
            f" {how}; raise max_separation_m or check the maps"
        )
    return it[keep], ir[keep]


def street_distance(
    tx_street: FloatArray | None,
    rx_street: FloatArray | None,
    it: IntArray,
    ir: IntArray,
    limit: float,
) -> FloatArray:
    """[n] the street separation of the combinations (it, ir) of two maps' street columns:
    ``inf`` where a UE is not on a road or the way along the roads is longer than ``limit``."""
    out = np.full(len(it), np.inf)
    if tx_street is None or rx_street is None or len(it) == 0:
        return out
    on_road = ~(np.isnan(tx_street[it, 0]) | np.isnan(rx_street[ir, 0]))
    if not np.any(on_road):
        return out
    it, ir = it[on_road], ir[on_road]
    # road graph over the segments of both maps; node ids by the rounded vertex coordinates,
    # once per map point (not per combination)
    both = np.concatenate([tx_street, rx_street])
    ends = np.nan_to_num(both[:, :4]).reshape(-1, 2)
    keys = np.round(ends / NODE_MERGE_M).astype(np.int64)
    _, node_of = np.unique(keys, axis=0, return_inverse=True)
    node_of = node_of.reshape(-1, 2)
    n_tx = len(tx_street)
    ua, va = node_of[it, 0], node_of[it, 1]
    ub, vb = node_of[n_tx + ir, 0], node_of[n_tx + ir, 1]
    st, sr = tx_street[it], rx_street[ir]
    n_t = len(st)
    len_a = np.hypot(st[:, 2] - st[:, 0], st[:, 3] - st[:, 1])
    len_b = np.hypot(sr[:, 2] - sr[:, 0], sr[:, 3] - sr[:, 1])
    n_nodes = int(node_of.max()) + 1
    # one straight piece of road: the straight distance in the (along, lateral) plane
    same = (ua == ub) & (va == vb)
    flipped = (ua == vb) & (va == ub) & ~same
    s_b = np.where(flipped, len_b - sr[:, 4], sr[:, 4])
    o_b = np.where(flipped, -sr[:, 5], sr[:, 5])
    result = np.full(n_t, np.inf)
    one = same | flipped
    result[one] = np.hypot(st[one, 4] - s_b[one], st[one, 5] - o_b[one])
    other = ~one
    if np.any(other):
        edges_u = np.concatenate([ua, ub])
        edges_v = np.concatenate([va, vb])
        edges_w = np.concatenate([len_a, len_b])
        graph = _graph(edges_u, edges_v, edges_w, n_nodes)
        lateral = np.abs(st[other, 5]) + np.abs(sr[other, 5])
        # the four ways out of the two segments: (end of a, its distance) × (end of b, …)
        outs_a = ((ua[other], st[other, 4]), (va[other], len_a[other] - st[other, 4]))
        outs_b = ((ub[other], sr[other, 4]), (vb[other], len_b[other] - sr[other, 4]))
        sources = np.unique(np.concatenate([ua[other], va[other]]))
        between = _node_distances(graph, sources, limit)
        row = np.full(n_nodes, -1)
        row[sources] = np.arange(len(sources))
        best = np.full(int(other.sum()), np.inf)
        for na, da in outs_a:
            for nb, db in outs_b:
                best = np.minimum(best, da + between[row[na], nb] + db)
        result[other] = best + lateral
    out[on_road] = result
    return out


def _graph(u: IntArray, v: IntArray, w: FloatArray, n: int) -> coo_matrix:
    """The undirected road graph: one edge per node pair, its shortest segment."""
    a, b = np.minimum(u, v), np.maximum(u, v)
    keep = a != b
    a, b, w = a[keep], b[keep], w[keep]
    order = np.lexsort((w, b, a))
    a, b, w = a[order], b[order], w[order]
    first = np.ones(len(a), dtype=bool)
    first[1:] = (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    return coo_matrix((w[first], (a[first], b[first])), shape=(n, n))


def _node_distances(graph: coo_matrix, sources: IntArray, limit: float) -> FloatArray:
    """[len(sources), n] shortest distances along the roads from each source node (``inf``
    beyond ``limit``)."""
    csr = graph.tocsr()
    rows = [
        dijkstra(csr, directed=False, indices=sources[k : k + SOURCE_CHUNK], limit=limit)
        for k in range(0, len(sources), SOURCE_CHUNK)
    ]
    return np.concatenate(rows).reshape(len(sources), -1)


def draw_near(
    tx: FloatArray,
    rx: FloatArray,
    it: IntArray,
    ir: IntArray,
    w: FloatArray,
    spec: PairSample,
    scene: Scene,
) -> IntArray:
    """``spec.sample`` draws (indices into ``it``, ``ir``), with replacement, ∝ ``w``; with
    ``line_of_sight`` only combinations whose TX–RX leg is clear."""
    rng = np.random.default_rng(spec.seed)
    if not spec.line_of_sight or scene.empty:
        return rng.choice(len(it), size=spec.sample, p=w / w.sum())
    return _draw_clear(tx, rx, it, ir, w, spec.sample, rng, scene)


def _draw_clear(
    tx: FloatArray,
    rx: FloatArray,
    it: IntArray,
    ir: IntArray,
    w: FloatArray,
    n: int,
    rng: np.random.Generator,
    scene: Scene,
) -> IntArray:
    """``n`` draws ∝ ``w`` among the combinations whose TX–RX leg is clear: each round draws
    what is missing from the combinations not yet known to be blocked, checks the legs not yet
    checked and keeps the clear ones."""
    verdict = np.zeros(len(it), dtype=np.int8)  # 0 unknown, 1 clear, -1 blocked
    picks: list[IntArray] = []
    have = 0
    while have < n:
        p = np.where(verdict < 0, 0.0, w)
        if not p.sum() > 0:
            raise RisPlannerError(
                "pairs.line_of_sight: no TX–RX pair within max_separation_m has a clear line"
                " of sight; turn line_of_sight off or raise max_separation_m"
            )
        draw = rng.choice(len(it), size=n - have, p=p / p.sum())
        new = np.unique(draw[verdict[draw] == 0])
        clear = los_clear(scene, tx[it[new]], rx[ir[new]])
        verdict[new] = np.where(clear, 1, -1)
        ok = draw[verdict[draw] > 0]
        picks.append(ok)
        have += len(ok)
    return np.concatenate(picks)
