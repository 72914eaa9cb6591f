"""The maps stage of a plan (docs/concepts/planning.md, "Pipeline"): each needed layout's bound
at every RX map point against the heatmap's TX population, and the fraction of those TX
partners it serves – plan.json's ``points`` and ``heatmap`` and the heatmap figure.

The bounds are :func:`ris_planner.bounds.compute.compute_bounds`' (the plan's visibility rules, the
expected-random FIM). What a point's paths are does not depend on the layout: each site's
field of view and clear leg is decided once per map point and the LOS leg once per pair, for
every layout of the stage together, and handed to ``compute_bounds`` (``presence``) instead
of walking the T × M legs again per layout and RIS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import compute_bounds
from ris_planner.bounds.paths import los_clear, ris_serves
from ris_planner.environment import Scene
from ris_planner.model.limits import HEATMAP_MAX_PAIRS
from ris_planner.model.objectives import objective_kind, weighted_quantile
from ris_planner.model.plan import PlanDocument
from ris_planner.planning.beams import layout_scenario
from ris_planner.planning.inputs.sites import Site
from ris_planner.planning.inputs.ue_maps import PointMap
from ris_planner.planning.scoring.scorer import select_metric
from ris_planner.planning.search.layouts import Layout
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

REASON_NO_TX = "no TX point of the heatmap differs from this RX point"


@dataclass(frozen=True)
class RxField:
    """One layout evaluated at every RX map point (:func:`rx_fields`)."""

    layout: Layout
    bound: FloatArray
    """[M] weighted median over TX of the objective's metric [m]; inf = blind, NaN = no TX."""
    reason: list[str | None]
    """[M] why the bound is infinite (the dominant reason over TX) or absent; None otherwise."""
    serving: list[list[int]]
    """[M] the layout's sites (candidate indices) with a RIS path to the point from ≥ 1 TX."""
    served: FloatArray
    """[M] weighted fraction of the point's TX partners whose metric is finite and at or below
    the objective's reference level (:func:`served_level`); NaN = no TX."""


def served_level(doc: PlanDocument) -> float:
    """The bound [m] a pair must reach to count as served – the diagnosis' level (the objective
    kind's ``reference_level``, as :func:`ris_planner.planning.outputs.diagnosis.reference_level`:
    ``threshold_m`` of coverage, ``cap_m`` of mean_capped, ``target.max`` of quantile);
    ``inf``: any finite bound."""
    return objective_kind(doc.objective.kind).reference_level(doc.objective)


def served_fractions(metric: FloatArray, weights: FloatArray, level: float) -> FloatArray:
    """[M] per row of ``metric`` [M, T] (an RX point's bounds against its TX partners) the
    weighted fraction of partners whose bound is finite and ≤ ``level``; NaN for a row without
    weight."""
    ok = np.isfinite(metric) & (metric <= level)
    total = weights.sum(axis=1)
    out = np.full(len(metric), np.nan)
    has = total > 0
    out[has] = np.minimum((ok * weights).sum(axis=1)[has] / total[has], 1.0)
    return out


def heatmap_rx_index(n_points: int) -> NDArray[np.int_]:
    """Map indices of the RX points the heatmap and the per-point results evaluate: all of them
    up to :data:`HEATMAP_MAX_PAIRS`, else a seeded uniform sample of that many (map order
    kept), so the heatmap's pairs never exceed the limit whatever the map's size."""
    if n_points <= HEATMAP_MAX_PAIRS:
        return np.arange(n_points)
    rng = np.random.default_rng(0)
    return np.sort(rng.choice(n_points, HEATMAP_MAX_PAIRS, replace=False))


def heatmap_tx(doc: PlanDocument, tx_map: PointMap, n_rx: int) -> tuple[FloatArray, FloatArray]:
    """(TX points [T, 3], weights [T]) every RX map point is evaluated against: the document's
    fixed ``heatmap_tx``, else the whole TX map – a seeded weighted sample of it when
    T × n_rx would exceed :data:`HEATMAP_MAX_PAIRS` (the same sample for every layout)."""
    if doc.heatmap_tx is not None:
        return np.asarray(doc.heatmap_tx, dtype=float)[None], np.ones(1)
    tx_pts, tx_w = tx_map.points, tx_map.weights
    max_tx = max(1, HEATMAP_MAX_PAIRS // n_rx)
    if len(tx_pts) > max_tx:
        rng = np.random.default_rng(0)
        pick = rng.choice(len(tx_pts), max_tx, replace=False, p=tx_w / tx_w.sum())
        tx_pts, tx_w = tx_pts[pick], tx_w[pick]
    return tx_pts, tx_w


def dominant_reason(
    reason: NDArray[np.object_], weights: FloatArray, blind: BoolArray
) -> list[str | None]:
    """Per row (an RX point, [M, T] reasons and weights): for a blind point the reason carried by
    the largest weight of its infinite pairs (ties: the first reason in sorted order), else None."""
    out: list[str | None] = [None] * reason.shape[0]
    if not np.any(blind):
        return out
    r, w = reason[blind], weights[blind]  # [B, T]
    names = sorted({str(x) for x in r.ravel() if x is not None})
    if not names:
        return out
    # [K, B] weight of each distinct reason per blind point
    mass = np.stack([((r == name) * w).sum(axis=1) for name in names])
    best = np.argmax(mass, axis=0)
    for b, m in enumerate(np.nonzero(blind)[0]):
        out[m] = names[best[b]] if mass[best[b], b] > 0 else None
    return out


def rx_fields(
    doc: PlanDocument,
    sites: list[Site],
    scene: Scene,
    tx_map: PointMap,
    rx_map: PointMap,
    layouts: list[Layout],
    progress: ProgressCallback = no_progress,
) -> dict[Layout, RxField]:
    """Each layout's bound at every RX map point of :func:`heatmap_rx_index` against the
    :func:`heatmap_tx` population, with its blind reason and serving sites.

    The value is the weighted median over TX (a mean is undefined where some bounds are
    infinite); TX points that coincide with the RX point carry no weight, and a point with
    none left is NaN. The served fraction weighs the same partners (:func:`served_fractions`
    at :func:`served_level`). A RIS path exists for (TX, RX) iff the RIS serves both (the
    contract); serving: with ≥ 1 weighted TX."""
    layouts = list(dict.fromkeys(tuple(int(s) for s in lay) for lay in layouts))
    pts = rx_map.points[heatmap_rx_index(len(rx_map.points))]  # [M, 3]
    tx_pts, tx_w = heatmap_tx(doc, tx_map, len(pts))  # [T, 3], [T]
    n_tx, n_rx = len(tx_pts), len(pts)
    tx = np.repeat(tx_pts, n_rx, axis=0)  # [T·M, 3], TX-major
    rx = np.tile(pts, (n_tx, 1))
    w = np.where(np.linalg.norm(tx - rx, axis=1) > 0, np.repeat(tx_w, n_rx), 0.0)
    w = w.reshape(n_tx, n_rx).T  # [M, T]
    empty = w.sum(axis=1) <= 0
    w_med = w.copy()
    w_med[empty] = 1.0
    # visibility once per (site, point) and per LOS pair, for every layout
    used = sorted({s for lay in layouts for s in lay})
    on_tx = {s: ris_serves(scene, sites[s].ris, tx_pts) for s in used}  # [T]
    on_rx = {s: ris_serves(scene, sites[s].ris, pts) for s in used}  # [M]
    los = los_clear(scene, tx, rx) if doc.system.los else np.zeros(len(tx), dtype=bool)
    level = served_level(doc)
    out: dict[Layout, RxField] = {}
    for i, layout in enumerate(layouts):
        progress(i / len(layouts), f"per-point bounds of {len(layout)} RISs")
        presence = {"los": los} | {
            f"ris{j + 1}": np.repeat(on_tx[s], n_rx) & np.tile(on_rx[s], n_tx)
            for j, s in enumerate(layout)
        }
        ris = [sites[s].ris for s in layout]
        scenario = layout_scenario(doc.system, ris, list(doc.known), doc.environment)
        # the plan's visibility rules through compute_bounds; degenerate pairs: inf, a reason
        res = compute_bounds(
            scenario, tx=tx, rx=rx, profiles=None, presence=presence, channel=False
        )
        metric = select_metric(doc.objective.metric, res.peb_tx, res.peb_rx)
        metric = metric.reshape(n_tx, n_rx)
        vals = weighted_quantile(metric.T, w_med, 0.5)  # [M]
        vals[empty] = np.nan
        served = served_fractions(metric.T, w, level)
        reasons = dominant_reason(res.reason.reshape(n_tx, n_rx).T, w, np.isinf(vals))
        for m in np.nonzero(empty)[0]:
            reasons[m] = REASON_NO_TX
        serves = np.zeros((len(layout), n_rx), dtype=bool)  # [L, M]
        for j, s in enumerate(layout):
            any_tx = ((w > 0) & on_tx[s][None, :]).any(axis=1)  # [M]
            serves[j] = on_rx[s] & any_tx
        serving = [[layout[j] for j in np.nonzero(serves[:, m])[0]] for m in range(n_rx)]
        out[layout] = RxField(layout, vals, reasons, serving, served)
    progress(1.0, "per-point bounds")
    return out


def cell_medians(cells: IntArray, values: FloatArray, weights: FloatArray, n: int) -> FloatArray:
    """[n] weighted median (smallest v with cumulative weight ≥ half, as
    :func:`~ris_planner.model.objectives.weighted_quantile`) of the values [M] in each cell;
    NaN values are left out and a cell without values is NaN."""
    out = np.full(n, np.nan)
    ok = ~np.isnan(values) & (weights > 0)
    if not np.any(ok):
        return out
    c, v, w = cells[ok], values[ok], weights[ok]
    order = np.lexsort((v, c))  # by cell, then value (inf last)
    c, v, w = c[order], v[order], w[order]
    cw = np.cumsum(w)
    first = np.r_[True, c[1:] != c[:-1]]
    start = np.nonzero(first)[0]  # [G] group starts
    group = np.cumsum(first) - 1  # [K] group of each sorted entry
    before = np.r_[0.0, cw][start]  # cumulative weight before each group
    total = np.add.reduceat(w, start)
    frac = (cw - before[group]) / total[group]
    # tolerance as weighted_quantile: a median exactly on a step is kept
    hit = frac >= 0.5 - 1e-12
    hit_groups, at = np.unique(group[hit], return_index=True)
    out[c[start[hit_groups]]] = v[np.nonzero(hit)[0][at]]
    return out
