"""Per-point plan results: the bound, the serving RISs and the blind reason at every RX map
point for each RIS count's best layout (``plan.json`` key ``"points"``), and the heatmap grid
the web page draws its overlay and threshold contour from (key ``"heatmap"``), each with the
fraction of a point's TX partners the layout serves.

Both are pure functions over a :class:`~ris_planner.planning.outputs.result.PlanResult` whose maps
stage has run; the numbers come from :func:`~ris_planner.planning.outputs.rx_fields.rx_fields` –
the same
computation as the heatmap figure – so a point's bound for the largest count is exactly the
PNG's value at that point.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import finite_or_none
from ris_planner.environment import Scene
from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import local_pairs
from ris_planner.planning.outputs.rx_fields import (
    RxField,
    cell_medians,
    heatmap_rx_index,
    rx_fields,
    served_level,
)
from ris_planner.planning.scoring.scorer import objective_from_loss
from ris_planner.planning.search.layouts import Layout
from ris_planner.runtime.progress import ProgressCallback, no_progress

if TYPE_CHECKING:
    from ris_planner.planning.outputs.result import PlanResult

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

HEATMAP_GRID_MAX_CELLS = 200
"""Largest number of heatmap cells along x or y: maps finer than span/200 are binned coarser
(each cell then holds the weighted median of its points)."""

GRID_SNAP = 1e-6
"""Relative tolerance (of the cell size) when snapping a point to its cell: grid maps built from
[start, stop, step] ranges carry rounding of order ε·|x|/step."""


def points_json(result: PlanResult) -> list[dict[str, Any]]:
    """``plan.json["points"]``: one entry per RX map point the heatmap evaluates (all of them up
    to ``HEATMAP_MAX_PAIRS``, :meth:`PlanResult.heatmap_index`), in map order.

    ``{"index", "position": [x, y, z], "weight", "bound_m": {"2": v | null, …},
    "served_fraction": {"2": f | null, …}, "serving": {"2": [site indices], …},
    "reason": {"2": null | str, …}}``, keyed by RIS count (the best layout of each count);
    ``bound_m`` is null where the bound is infinite (reason given) or where no TX point differs
    from the point (reason says so); ``served_fraction`` is the weighted fraction of the
    point's TX partners served (:attr:`~ris_planner.planning.outputs.rx_fields.RxField.served`),
    null
    where no TX point differs from the point."""
    fields = {str(cr.ris_count): result.rx_field(cr.ranked[0][0]) for cr in result.counts}
    pm = result.rx_map
    return [
        {
            "index": int(i),
            "position": [float(v) for v in pm.points[i]],
            "weight": float(pm.weights[i]),
            "bound_m": {k: finite_or_none(f.bound[m]) for k, f in fields.items()},
            "served_fraction": {k: finite_or_none(f.served[m]) for k, f in fields.items()},
            "serving": {k: [int(s) for s in f.serving[m]] for k, f in fields.items()},
            "reason": {k: f.reason[m] for k, f in fields.items()},
        }
        for m, i in enumerate(result.heatmap_index())
    ]


def raster_cells(xy: FloatArray) -> tuple[dict[str, float | int], IntArray]:
    """A regular x–y grid for points [M, 2] and each point's cell index [M] (row-major,
    ``iy · nx + ix``).

    The cell size is the median nearest-neighbour distance of the distinct x–y positions (a
    grid map's step: its points then sit exactly on cell centres), at least span/
    :data:`HEATMAP_GRID_MAX_CELLS`; cell (0, 0) is centred on the smallest x and y."""
    uniq = np.unique(np.round(xy, 9), axis=0)  # [U, 2]
    span = float(np.ptp(uniq, axis=0).max()) if len(uniq) > 1 else 0.0
    if len(uniq) > 1:
        from scipy.spatial import cKDTree  # on first use: a plan's start-up skips it

        dist, _ = cKDTree(uniq).query(uniq, k=2)
        cell = float(np.median(dist[:, 1]))
    else:
        cell = 1.0
    cell = max(cell, span / HEATMAP_GRID_MAX_CELLS, 1e-6)
    lo = xy.min(axis=0)
    idx = np.floor((xy - lo) / cell + 0.5 + GRID_SNAP).astype(int)  # [M, 2]
    nx, ny = int(idx[:, 0].max()) + 1, int(idx[:, 1].max()) + 1
    grid: dict[str, float | int] = {
        "x0": float(lo[0]),
        "y0": float(lo[1]),
        "cell_m": cell,
        "nx": nx,
        "ny": ny,
    }
    return grid, idx[:, 1] * nx + idx[:, 0]


def levels_per_count(result: PlanResult) -> tuple[dict[str, float | None], str]:
    """The objective's bound level per RIS count and its label: coverage → ``threshold_m``,
    mean_capped → ``cap_m``, quantile → the best layout's q-quantile itself."""
    obj = result.document.objective
    counts = [str(cr.ris_count) for cr in result.counts]
    level, label = objective_kind(obj.kind).level_label(obj)
    if level is not None:
        return dict.fromkeys(counts, level), label
    levels = {
        str(cr.ris_count): finite_or_none(objective_from_loss(obj, cr.ranked[0][1]))
        for cr in result.counts
    }
    return levels, label


def heatmap_json(result: PlanResult) -> dict[str, Any]:
    """``plan.json["heatmap"]``: the per-point bounds binned on a regular x–y grid, per count.

    ``{"metric", "tx", "grid": {"x0", "y0", "cell_m", "nx", "ny"}, "sites": {"2": […]},
    "bound_m": {"2": [[row y0], [row y0 + cell], …]}, "blind": {"2": [[bool, …], …]},
    "served_fraction": {"2": [[row y0], …]}, "served_level_m", "threshold_m": {"2": v},
    "threshold_label", "ris_count"}`` – cell (ix, iy) is centred on (x0 + ix·cell,
    y0 + iy·cell); a cell holds the RX-weighted median of its points' bounds (null: no point,
    or blind – then ``blind`` is true) and, in ``served_fraction``, the RX-weighted median of
    its points' served fractions (the weighted fraction of a point's TX partners whose bound
    is finite and ≤ ``served_level_m``; null: no point; ``served_level_m`` null: any finite
    bound counts); ``ris_count`` is the count the heatmap figure shows (the largest)."""
    doc = result.document
    pm = result.rx_map
    idx = result.heatmap_index()
    grid, cells = raster_cells(pm.points[idx, :2])
    n = int(grid["nx"]) * int(grid["ny"])
    bound: dict[str, list[list[float | None]]] = {}
    blind: dict[str, list[list[bool]]] = {}
    served: dict[str, list[list[float | None]]] = {}
    sites: dict[str, list[int]] = {}
    shape = (int(grid["ny"]), int(grid["nx"]))
    for cr in result.counts:
        key = str(cr.ris_count)
        f = result.rx_field(cr.ranked[0][0])
        med = cell_medians(cells, f.bound, pm.weights[idx], n).reshape(shape)
        bound[key] = [[finite_or_none(v) for v in row] for row in med]
        blind[key] = [[bool(v) for v in row] for row in np.isposinf(med)]
        frac = cell_medians(cells, f.served, pm.weights[idx], n).reshape(shape)
        served[key] = [[finite_or_none(v) for v in row] for row in frac]
        sites[key] = [int(s) for s in f.layout]
    levels, label = levels_per_count(result)
    n_tx = len(result.heatmap_tx()[0])
    tx = (
        f"fixed TX {list(doc.heatmap_tx)}"
        if doc.heatmap_tx is not None
        else f"weighted median over {n_tx} TX map points"
    )
    return {
        "metric": doc.objective.metric,
        "tx": tx,
        "ris_count": result.counts[-1].ris_count,
        "grid": grid,
        "sites": sites,
        "bound_m": bound,
        "blind": blind,
        "served_fraction": served,
        "served_level_m": finite_or_none(served_level(doc)),
        "threshold_m": levels,
        "threshold_label": label,
    }


REASON_NO_PAIR = "no pair of the plan has this RX point"

REASON_TOO_FEW_PATHS = (
    "underdetermined: the layout's paths to the point's pairs give fewer channel parameters"
    " than unknown states"
)


def pair_local(result: PlanResult) -> bool:
    """Whether a plan's per-point fields come from its own pairs (:func:`pair_fields`): a
    pair model that keeps a pair's UEs near each other (``pairs.max_separation_m``) – the
    heatmap's TX population would pair a point with UEs far beyond it –, explicit pairs (the
    caller's own), or the district search's sparse scoring, whose pairs are the district's."""
    own = local_pairs(result.document.pairs)
    return own or result.scorer.storage_json().get("storage") == "sparse"


def plan_fields(
    result: PlanResult, layouts: list[Layout], progress: ProgressCallback = no_progress
) -> dict[Layout, RxField]:
    """Each layout's per-point field: over the plan's own pairs where they are local
    (:func:`pair_local`, :func:`pair_fields`), else against the heatmap's TX population
    (:func:`rx_fields`)."""
    if pair_local(result):
        return pair_fields(result, layouts, progress)
    scene = result.scene
    if scene is None:
        scene = Scene.from_environment(result.document.environment)
    doc = result.document
    return rx_fields(doc, result.sites, scene, result.tx_map, result.rx_map, layouts, progress)


def pair_fields(
    result: PlanResult, layouts: list[Layout], progress: ProgressCallback = no_progress
) -> dict[Layout, RxField]:
    """Each layout at every RX map point of :func:`heatmap_rx_index`, over the plan's pairs
    that end there: the weighted median of their bound, the weighted fraction served
    (:func:`served_level`), the layout's sites that serve at least one of them; a point no
    pair ends at is NaN (:data:`REASON_NO_PAIR`). The bounds are the plan's own scores of its
    pairs (the search's metric, re-scored exactly): nothing is computed again."""
    layouts = list(dict.fromkeys(tuple(int(s) for s in lay) for lay in layouts))
    pairs = result.pairs
    index = heatmap_rx_index(len(result.rx_map.points))
    where = np.full(len(result.rx_map.points), -1)
    where[index] = np.arange(index.size)
    cell = where[pairs.rx_index]  # [P] the pair's heatmap point, −1: not evaluated
    keep = cell >= 0
    cell, w = cell[keep], pairs.weights[keep]
    n = index.size
    total = np.bincount(cell, w, minlength=n)
    empty = total <= 0
    level = served_level(result.document)
    out: dict[Layout, RxField] = {}
    for i, layout in enumerate(layouts):
        progress(i / len(layouts), f"per-point fields of {len(layout)} RISs")
        metric = result.layout_metric(layout)[: pairs.size][keep]
        bound = cell_medians(cell, metric, w, n)
        ok = np.isfinite(metric) & (metric <= level)
        served = np.full(n, np.nan)
        served[~empty] = np.minimum(
            np.bincount(cell, w * ok, minlength=n)[~empty] / total[~empty], 1.0
        )
        serves = result.scorer.serves(layout)[:, keep]  # [L, P']
        by_point = (
            np.stack([np.bincount(cell, s, minlength=n) > 0 for s in serves])
            if len(layout)
            else np.zeros((0, n), dtype=bool)
        )
        serving = [[layout[j] for j in np.flatnonzero(by_point[:, m])] for m in range(n)]
        reasons: list[str | None] = [
            REASON_NO_PAIR if empty[m] else (REASON_TOO_FEW_PATHS if np.isinf(bound[m]) else None)
            for m in range(n)
        ]
        out[layout] = RxField(layout, bound, reasons, serving, served)
    progress(1.0, "per-point fields")
    return out
