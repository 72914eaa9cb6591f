"""How much of a plan's (pair, candidate site) combinations a RIS serves, from a seeded sample
before any work: the share that the time and memory estimates scale the served work by
(docs/validation/resources.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.paths import ris_serves
from ris_planner.model.plan import PairList, PairSample, PlanDocument
from ris_planner.model.search_methods import sparse_search

if TYPE_CHECKING:
    from ris_planner.environment import Scene
    from ris_planner.planning.inputs.sites import Site
    from ris_planner.planning.inputs.ue_maps import PointMap

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SERVE_SAMPLE_SITES = 32
"""Candidate sites of the served-share sample (:func:`served_share`)."""

SERVE_SAMPLE_POINTS = 192
"""TX and RX map points of the served-share sample (each, drawn ∝ the maps' weights)."""


def _serves(sites: list[Site], points: FloatArray, scene: Scene) -> BoolArray:
    """[S, N] whether each site's RIS serves each point (the plan's visibility rules)."""
    return np.stack([ris_serves(scene, s.ris, points) for s in sites])


def served_share(
    sites: list[Site], tx_map: PointMap, rx_map: PointMap, scene: Scene, seed: int = 0
) -> float:
    """The share of (TX–RX pair, candidate site) combinations in which the site's RIS serves
    both UEs (its field of view and clear legs, the plan's visibility rules), from a seeded
    sample: :data:`SERVE_SAMPLE_SITES` sites, :data:`SERVE_SAMPLE_POINTS` TX and RX points
    drawn ∝ the maps' weights; per site the share of the TX points it serves times that of the
    RX points, averaged over the sites. 1 in an open hall whose candidates face the UEs, a few
    percent on a street of a city block: the work of the stages that follow the served pairs
    (the search's identifiable pairs, the cache, the codebook checks, the per-point bounds,
    the estimator's validation) scales with it (:func:`stage_terms`). It treats TX and RX as
    independent; the district search's entries follow its sidelink pairs
    (:func:`pair_served_share`)."""
    if not sites:
        return 0.0
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(sites), min(len(sites), SERVE_SAMPLE_SITES), replace=False)

    def points(m: PointMap) -> FloatArray:
        w = m.weights / m.weights.sum()
        n = min(len(m.points), SERVE_SAMPLE_POINTS)
        return m.points[rng.choice(len(m.points), n, replace=False, p=w if n < len(w) else None)]

    tx, rx = points(tx_map), points(rx_map)
    serves = _serves([sites[i] for i in pick], np.concatenate([tx, rx]), scene)  # [S, T + R]
    shares = serves[:, : len(tx)].mean(axis=1) * serves[:, len(tx) :].mean(axis=1)
    return float(np.mean(shares))


def pair_served_share(
    sites: list[Site],
    tx: FloatArray,
    rx: FloatArray,
    weights: FloatArray,
    scene: Scene,
    seed: int = 0,
) -> float:
    """The share of (pair, candidate site) combinations in which the site's RIS serves both
    UEs of the pair, over the given pairs (positions ``tx``, ``rx`` [P, 3], ``weights`` [P]):
    a seeded sample of :data:`SERVE_SAMPLE_SITES` sites and :data:`SERVE_SAMPLE_POINTS` pairs
    drawn ∝ their weights. Unlike :func:`served_share` the two UEs of a pair are taken
    together: a sidelink pair's UEs are near each other, so a site that serves one often
    serves the other (on the Helsinki district of docs/validation/benchmarks.md 0.08 of the
    combinations, where the independent product says 0.014). The district search's
    (pair, serving site) entries are this share × pairs × sites (:func:`district_terms`)."""
    if not sites or len(weights) == 0:
        return 0.0
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(sites), min(len(sites), SERVE_SAMPLE_SITES), replace=False)
    n = min(len(weights), SERVE_SAMPLE_POINTS)
    w = weights / weights.sum()
    drawn = rng.choice(len(weights), n, replace=False, p=w if n < len(w) else None)
    serves = _serves([sites[i] for i in pick], np.concatenate([tx[drawn], rx[drawn]]), scene)
    return float(np.mean(serves[:, :n] & serves[:, n:]))


def near_pairs_sample(
    tx_map: PointMap, rx_map: PointMap, spec: PairSample, seed: int = 0
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(TX [n, 3], RX [n, 3], weights [n]) of about :data:`SERVE_SAMPLE_POINTS` sidelink pairs
    drawn before the plan draws its own (:func:`pair_served_share` of a document): a TX point
    ∝ its weight times the number of RX points within ``max_separation_m`` in a straight line
    (the plan draws a pair ∝ w_i · w_j among the near ones: exact for uniform RX weights), then
    an RX point ∝ its weight among those (a street separation is never shorter, so its pairs
    are among these); a TX point with no RX within reach but itself is left out."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    radius = float(spec.max_separation_m) if spec.max_separation_m is not None else np.inf
    tree = cKDTree(rx_map.points)
    # a pair (i, j) is drawn ∝ w_i · w_j among the near ones: TX i ∝ w_i times its reach
    reach = (
        np.full(len(tx_map.points), float(len(rx_map.points)))
        if not np.isfinite(radius)
        else np.asarray(tree.query_ball_point(tx_map.points, radius, return_length=True), float)
    )
    wt = tx_map.weights * reach
    if wt.sum() <= 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    picks = rng.choice(len(wt), SERVE_SAMPLE_POINTS, p=wt / wt.sum())
    tx, rx = [], []
    for i in picks.tolist():
        p = tx_map.points[i]
        near = (
            np.arange(len(rx_map.points))
            if not np.isfinite(radius)
            else np.asarray(tree.query_ball_point(p, radius), dtype=int)
        )
        near = near[np.linalg.norm(rx_map.points[near] - p, axis=1) > 1e-9]
        if near.size == 0:
            continue
        w = rx_map.weights[near]
        tx.append(p)
        rx.append(rx_map.points[near[rng.choice(near.size, p=w / w.sum())]])
    if not tx:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    return np.array(tx), np.array(rx), np.ones(len(tx))


def listed_sample(
    tx_map: PointMap, rx_map: PointMap, spec: PairList
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(TX [n, 3], RX [n, 3], weights [n]) of the explicit pairs before the plan builds them:
    their positions (map indices looked up in the maps as the document gives them; an index
    beyond a map is left to the plan's own check), for :func:`pair_served_share`."""
    w = np.ones(spec.size) if spec.weights is None else np.asarray(spec.weights, dtype=float)
    if not spec.by_index:
        return np.asarray(spec.tx, dtype=float), np.asarray(spec.rx, dtype=float), w
    it = np.asarray(spec.tx_index, dtype=np.int64)
    ir = np.asarray(spec.rx_index, dtype=np.int64)
    ok = (it < len(tx_map.points)) & (ir < len(rx_map.points))
    return tx_map.points[it[ok]], rx_map.points[ir[ok]], w[ok]


def document_shares(
    doc: PlanDocument,
    maps: tuple[PointMap, PointMap] | None = None,
    sites: list[Site] | None = None,
) -> tuple[float, float]:
    """(:func:`served_share`, :func:`pair_served_share` over :func:`near_pairs_sample` – for a
    district plan with sampled pairs, else the former) of a validated document: its sites
    (``sites`` when the caller expanded them), maps (``maps``, likewise) and environment,
    nothing computed on them beyond the sample. Explicit pairs are their own sample: both
    shares are :func:`pair_served_share` over the listed pairs (:func:`listed_sample`)."""
    from ris_planner.environment import Scene
    from ris_planner.planning.inputs.sites import expand_sites
    from ris_planner.planning.inputs.ue_maps import build_map

    sites = expand_sites(doc) if sites is None else sites
    if maps is None:
        maps = build_map(doc.tx_map, "tx_map"), build_map(doc.rx_map, "rx_map")
    tx_map, rx_map = maps
    scene = Scene.from_environment(doc.environment)
    if isinstance(doc.pairs, PairList):
        listed = pair_served_share(sites, *listed_sample(tx_map, rx_map, doc.pairs), scene)
        return listed, listed
    share = served_share(sites, tx_map, rx_map, scene)
    by_pair = share
    if sparse_search(doc) and isinstance(doc.pairs, PairSample):
        tx, rx, w = near_pairs_sample(tx_map, rx_map, doc.pairs)
        by_pair = pair_served_share(sites, tx, rx, w, scene)
    return share, by_pair
