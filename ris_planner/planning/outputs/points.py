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
from ris_planner.model.objectives import objective_kind
from ris_planner.planning.outputs.rx_fields import served_level
from ris_planner.planning.scoring.scorer import objective_from_loss

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
