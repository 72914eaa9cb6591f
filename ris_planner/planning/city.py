"""A city as one map (docs/concepts/district.md, "A city").

:func:`split_city` draws the city's pairs once, over the whole city – its pair model, street
separations along the roads of every cell – and cuts the city into square cells of ``cell_m``
(local metres). Each pair is **owned** by the cell that holds its midpoint; each cell's
district document gets the pairs it owns as explicit pairs (:class:`~ris_planner.model.plan.
PairList`), with the UE points, candidates and obstacles within the cell and a **halo** of the
pair separation around it, so a pair that crosses a cell border is planned whole, in one cell.
Every cell document is admitted (its limits and memory checked) before any cell is planned.

:func:`plan_city` plans every cell with the district search on an executor
(:class:`~ris_planner.runtime.executor.SerialExecutor`, ``LocalExecutor`` or
``DaskExecutor``): one task per cell, carrying its own document, so workers share no state and
any executor gives the same answer. :func:`city_json` stitches the cells' plans into the
city's plan.json: the same keys as a plan where they apply (candidates, points and sites at
city-level indices, ``by_count`` with its certificate, ``pairs_summary``, ``sizing``) plus
``cells`` and ``city``.

RIS counts: with ``ris_count`` each entry is a **city budget**, shared out to the cells by
their share of the pair weight (at least one RIS each; :func:`allocate`); the city's coverage
is the cells' coverages weighted by their pair-weight shares, and its certified upper bound the
cells' bounds weighted likewise – the bound on every layout that places the same number of
RISs among each cell's candidates. In target mode each cell searches up to its own smallest
count that meets the target; the city's count is their sum. With ``sizing`` each cell answers
the sizing question; the city's certified interval is the sum of the cells' certified lower
counts to the sum of their found counts (each cell meeting the target share of its servable
pairs, so the city meets it).
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import DocumentFieldError, LimitExceededError, RisPlannerError
from ris_planner.core.io_json import finite_or_none
from ris_planner.model.limits import Sizes, check_sizes
from ris_planner.model.plan import PairSample, PlanDocument, map_points
from ris_planner.planning.inputs.sites import candidate_json
from ris_planner.planning.inputs.ue_maps import PairSet, PointMap
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.resources.admission import Admitted, admit, resolve_search
from ris_planner.planning.resources.time_estimate import peak_memory_mib
from ris_planner.runtime.executor import Executor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, no_progress
from ris_planner.runtime.provenance import provenance

IntArray = NDArray[np.int_]
FloatArray = NDArray[np.float64]

CITY_METHOD = "district"
"""The search every cell runs."""

CELL_FIELDS = (
    "candidates",
    "walls",
    "facades",
    "environment",
    "tx_map",
    "rx_map",
    "pairs",
    "ris_count",
    "mode",
    "max_ris",
    "constraints",
    "search",
    "description",
)
"""Fields of the city document that each cell's document sets itself."""


@dataclass(frozen=True)
class Cell:
    """One cell of the city (:func:`split_city`)."""

    key: tuple[int, int]
    """(column, row) of the cell on the grid, from the city's origin."""
    bounds: tuple[float, float, float, float]
    """x_min, y_min, x_max, y_max [m] (local metres); the halo lies around it."""
    pairs: IntArray
    """The city's pairs it owns (their midpoint lies in it)."""
    tx: IntArray
    """City TX map indices of its document's TX map (cell and halo)."""
    rx: IntArray
    """City RX map indices of its document's RX map."""
    candidates: IntArray
    """City candidate indices of its document's candidates."""
    weight: float
    """Its share of the city's pair weight."""
    border_pairs: int
    """Owned pairs whose TX and RX lie in different cells."""
    document: dict[str, Any] | None
    """Its district document; ``None`` when no candidate lies within reach."""

    @property
    def id(self) -> str:
        return f"{self.key[0]},{self.key[1]}"


@dataclass(frozen=True)
class City:
    """A city document split into cells (:func:`split_city`)."""

    document: PlanDocument
    """The city document as planned (validated, ``search.method`` the district search)."""
    given: dict[str, Any]
    """The city document in local metres, as given."""
    cell_m: float
    halo_m: float
    origin: tuple[float, float]
    """The grid's corner: the smallest x and y of the UE points [m]."""
    candidates: list[dict[str, Any]]
    """Every candidate of the city (walls and facades expanded), at city-level indices."""
    tx_map: PointMap
    rx_map: PointMap
    pairs: PairSet
    owner: IntArray
    """[P] the index in :attr:`cells` of each pair's owner."""
    border: NDArray[np.bool_]
    """[P] whether the pair's TX and RX lie in different cells."""
    cells: list[Cell]
    budgets: list[tuple[int, dict[str, int]]]
    """Compare mode: (city RIS count, the count of each planned cell); empty in target mode."""
    split_s: float = 0.0
    """Seconds the split took (the pairs, the cells' documents and their admission)."""

    @property
    def planned(self) -> list[Cell]:
        """The cells with a document (a candidate within reach)."""
        return [c for c in self.cells if c.document is not None]


def _cell_error(cell: str, exc: RisPlannerError) -> RisPlannerError:
    """``exc`` with the cell named first in its message (same type, same field or limit)."""
    if isinstance(exc, DocumentFieldError):
        return DocumentFieldError(exc.field, f"cell {cell}: {exc.reason}")
    if isinstance(exc, LimitExceededError):
        return LimitExceededError(f"cell {cell}: {exc}", exc.limit)
    return RisPlannerError(f"cell {cell}: {exc}")


def city_document(document: dict[str, Any]) -> PlanDocument:
    """The city document validated for a city: the district search (``search.method``
    ``auto`` or ``district``), sampled sidelink pairs with ``max_separation_m`` or explicit
    pairs, no required candidates; what the district search cannot honour is refused
    (:func:`~ris_planner.planning.resources.admission.resolve_search`) – before any work."""
    search = dict(document.get("search") or {})
    if search.get("method", "auto") not in ("auto", CITY_METHOD):
        raise DocumentFieldError(
            "search.method",
            f"a city is planned by the district search, not {search['method']!r}",
        )
    doc = PlanDocument.model_validate(document | {"search": search | {"method": CITY_METHOD}})
    pairs = doc.pairs
    if isinstance(pairs, str) or (isinstance(pairs, PairSample) and pairs.max_separation_m is None):
        raise DocumentFieldError(
            "pairs.max_separation_m",
            "a city plans sidelink pairs: a sample with max_separation_m (its cells' halo) or"
            " explicit pairs",
        )
    if doc.constraints.require:
        raise DocumentFieldError(
            "constraints.require",
            "a city's cells are planned apart: required candidates are not supported (exclude"
            " candidates or list fewer)",
        )
    # sizes that are checked before anything is built (a road step of 5e-324 builds forever)
    check_sizes(
        Sizes(tx_points=map_points(doc.tx_map), rx_points=map_points(doc.rx_map)),
        memory_mb=None,
    )
    return resolve_search(doc)[0]


def allocate(budget: int, shares: list[float], caps: list[int]) -> list[int]:
    """A city RIS ``budget`` shared out to cells by their pair-weight ``shares``: one RIS each,
    then one at a time to the cell furthest below ``budget · share`` (ties: the first cell),
    never more than its ``caps`` (its candidates). Raises when the budget is below one per cell
    or above every candidate."""
    n = len(shares)
    if budget < n:
        raise DocumentFieldError(
            "ris_count",
            f"a city budget of {budget} RISs is below its {n} cells with pairs and candidates"
            " (one RIS each at least): give at least {n}, or larger cells",
        )
    if budget > sum(caps):
        raise DocumentFieldError(
            "ris_count", f"a city budget of {budget} RISs exceeds its {sum(caps)} candidates"
        )
    alloc = [1] * n
    want = [budget * s for s in shares]
    for _ in range(budget - n):
        open_cells = [k for k in range(n) if alloc[k] < caps[k]]
        k = max(open_cells, key=lambda k: (want[k] - alloc[k], -k))
        alloc[k] += 1
    return alloc


def _in_box(xy: FloatArray, box: tuple[float, float, float, float]) -> IntArray:
    x0, y0, x1, y1 = box
    inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
    return np.flatnonzero(inside)


def _local(indices: IntArray, within: IntArray) -> list[int]:
    """Positions of ``indices`` in the sorted ``within``."""
    return [int(v) for v in np.searchsorted(within, indices)]


def split_city(document: dict[str, Any], cell_m: float, memory_mb: int | None = None) -> City:
    """The :class:`City` of a city document in local metres (module docstring): its pairs
    drawn once, its cells (row-major by (column, row)) each with the pairs it owns and its
    district document, every cell document admitted (``memory_mb``: the job memory budget of
    one cell) – a refusal names the cell."""
    t0 = time.perf_counter()
    if not (math.isfinite(cell_m) and cell_m > 0):
        raise DocumentFieldError("cell_m", f"the cell size must be a number > 0 m, got {cell_m}")
    doc = city_document(document)
    admitted = Admitted(*resolve_search(doc))
    inputs = prepare_plan(admitted)  # the city's maps and pairs, drawn once
    sites, tx_map, rx_map, pairs = inputs.sites, inputs.tx_map, inputs.rx_map, inputs.pairs
    if isinstance(doc.pairs, PairSample):
        assert doc.pairs.max_separation_m is not None
        halo = float(doc.pairs.max_separation_m)
    else:  # explicit pairs: their longest straight separation
        halo = float(np.linalg.norm(pairs.tx - pairs.rx, axis=1).max())
    candidates = [candidate_json(s) for s in sites]
    cand_xy = np.array([s.ris.position[:2] for s in sites], dtype=np.float64).reshape(-1, 2)
    origin_xy = np.concatenate([tx_map.points[:, :2], rx_map.points[:, :2]]).min(axis=0)
    origin = (float(origin_xy[0]), float(origin_xy[1]))

    def cell_of(xy: FloatArray) -> IntArray:
        return np.floor((xy - origin_xy) / cell_m).astype(np.int_)

    mid = cell_of((pairs.tx[:, :2] + pairs.rx[:, :2]) / 2)
    border = np.any(cell_of(pairs.tx[:, :2]) != cell_of(pairs.rx[:, :2]), axis=1)
    keys = sorted({(int(i), int(j)) for i, j in mid.tolist()})
    index = {k: n for n, k in enumerate(keys)}
    owner = np.array([index[(int(i), int(j))] for i, j in mid.tolist()], dtype=np.int_)
    env = document.get("environment") or None
    raw_obstacles = (env or {}).get("obstacles") or []
    obstacles = [] if doc.environment is None else list(doc.environment.obstacles)
    boxes = [
        (*ob.outline().min(axis=0).tolist(), *ob.outline().max(axis=0).tolist()) for ob in obstacles
    ]
    excluded = set(doc.constraints.exclude)
    base = {k: v for k, v in document.items() if k not in CELL_FIELDS}
    base["search"] = {**(document.get("search") or {}), "method": CITY_METHOD}
    base.pop("sweep", None)
    total_w = float(pairs.weights.sum())
    cells: list[Cell] = []
    for n, key in enumerate(keys):
        owned = np.flatnonzero(owner == n)
        x0, y0 = (origin_xy + np.asarray(key) * cell_m).tolist()
        bounds = (x0, y0, x0 + cell_m, y0 + cell_m)
        box = (x0 - halo, y0 - halo, x0 + cell_m + halo, y0 + cell_m + halo)
        tx = np.union1d(_in_box(tx_map.points[:, :2], box), pairs.tx_index[owned])
        rx = np.union1d(_in_box(rx_map.points[:, :2], box), pairs.rx_index[owned])
        cand = _in_box(cand_xy, box)
        cell = Cell(
            key,
            bounds,
            owned,
            tx,
            rx,
            cand,
            float(pairs.weights[owned].sum()) / total_w,
            int(border[owned].sum()),
            None,
        )
        if cand.size:
            kept = [
                raw
                for raw, (a, b, c, d) in zip(raw_obstacles, boxes, strict=True)
                if a <= box[2] and c >= box[0] and b <= box[3] and d >= box[1]
            ]
            listed: dict[str, Any] = {
                "tx_index": _local(pairs.tx_index[owned], tx),
                "rx_index": _local(pairs.rx_index[owned], rx),
            }
            w = pairs.weights[owned]
            if not np.all(w == w[0]):
                listed["weights"] = (w / w.max()).tolist()
            constraints = document.get("constraints") or {}
            if constraints:
                constraints = constraints | {
                    "exclude": [i for i, k in enumerate(cand.tolist()) if k in excluded]
                }
            cell_doc = base | {
                "description": f"cell {cell.id} of {document.get('description') or 'the city'}",
                "candidates": [candidates[k] for k in cand.tolist()],
                "tx_map": {
                    "points": tx_map.points[tx].tolist(),
                    "weights": tx_map.weights[tx].tolist(),
                },
                "rx_map": {
                    "points": rx_map.points[rx].tolist(),
                    "weights": rx_map.weights[rx].tolist(),
                },
                "pairs": listed,
                **({"constraints": constraints} if constraints else {}),
                **({"environment": env | {"obstacles": kept}} if env else {}),
            }
            cell = replace(cell, document=cell_doc)
        cells.append(cell)
    planned = [c for c in cells if c.document is not None]
    if not planned:
        raise RisPlannerError("no cell holds a pair and a candidate within its halo")
    budgets = _counts(doc, planned)
    cells = [_with_counts(c, doc, budgets) for c in cells]
    for c in cells:  # every cell admitted before any is planned
        if c.document is None:
            continue
        try:
            admit(c.document, memory_mb)
        except RisPlannerError as exc:
            raise _cell_error(c.id, exc) from None
    return City(
        doc,
        document,
        float(cell_m),
        halo,
        origin,
        candidates,
        tx_map,
        rx_map,
        pairs,
        owner,
        border,
        cells,
        budgets,
        time.perf_counter() - t0,
    )


def _counts(doc: PlanDocument, planned: list[Cell]) -> list[tuple[int, dict[str, int]]]:
    """Compare mode: each city count and its allocation to the planned cells (:func:`allocate`
    by their shares of the planned cells' pair weight); target mode: none."""
    if doc.target_mode or doc.ris_count is None:
        return []
    weight = sum(c.weight for c in planned)
    shares = [c.weight / weight for c in planned]
    excluded = set(doc.constraints.exclude)
    caps = [sum(k not in excluded for k in c.candidates.tolist()) for c in planned]
    return [
        (b, {c.id: n for c, n in zip(planned, allocate(b, shares, caps), strict=True)})
        for b in doc.ris_count
    ]


def _with_counts(cell: Cell, doc: PlanDocument, budgets: list[tuple[int, dict[str, int]]]) -> Cell:
    """The cell with its RIS counts in its document: the allocated counts (compare mode), else
    target mode up to ``max_ris`` (at most its candidates)."""
    if cell.document is None:
        return cell
    if budgets:
        counts = sorted({alloc[cell.id] for _, alloc in budgets})
        update: dict[str, Any] = {"ris_count": counts, "mode": "compare"}
    else:
        update = {"mode": "target", "max_ris": min(doc.max_ris, int(cell.candidates.size))}
    return replace(cell, document=cell.document | update)


def _cell_task(_shared: None, task: tuple[str, dict[str, Any]]) -> dict[str, Any]:
    """One cell's plan.json (runs on a worker), its wall time and the worker's peak memory."""
    cell, document = task
    t0 = time.perf_counter()
    plan = run_plan(document, executor=SerialExecutor()).to_json()
    peak_mib = peak_memory_mib()
    return {
        "cell": cell,
        "plan": plan,
        "wall_s": time.perf_counter() - t0,
        "worker_peak_mib": peak_mib,
    }


def plan_city(
    city: City, executor: Executor | None = None, progress: ProgressCallback = no_progress
) -> dict[str, Any]:
    """Every planned cell of ``city`` on ``executor`` (one task each; default this process),
    then the city's plan.json (:func:`city_json`)."""
    ex = executor or SerialExecutor()
    tasks = [(c.id, c.document) for c in city.planned if c.document is not None]
    n = len(tasks)
    progress(0.0, f"{n} cells")
    t0 = time.perf_counter()
    done = ex.map(_cell_task, None, tasks, lambda k: progress(k / (n + 1), f"cell {k}/{n}"))
    cells_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    plan = city_json(city, {d["cell"]: d for d in done})
    plan["timing_s"] = {"split": city.split_s, "cells": cells_s, "stitch": time.perf_counter() - t1}
    progress(1.0, "city")
    return plan


@dataclass
class _Row:
    """One city count: each cell's count and its by_count entry (``None``: not reached)."""

    count: int
    per_cell: dict[str, int]
    entries: dict[str, dict[str, Any] | None] = field(default_factory=dict)


def _rows(city: City, plans: dict[str, dict[str, Any]]) -> list[_Row]:
    """The city's counts: each budget's allocation, or in target mode each cell's last count
    (the smallest that meets the target, else the largest searched)."""
    rows = []
    if city.budgets:
        for budget, alloc in city.budgets:
            entries = {
                cid: next((e for e in plans[cid]["by_count"] if e["ris_count"] == n), None)
                for cid, n in alloc.items()
            }
            rows.append(_Row(budget, alloc, entries))
        return rows
    last = {c.id: plans[c.id]["by_count"][-1] for c in city.planned}
    per_cell = {cid: int(e["ris_count"]) for cid, e in last.items()}
    rows.append(_Row(sum(per_cell.values()), per_cell, dict(last)))
    return rows


def _global_sites(cell: Cell, sites: list[int]) -> list[int]:
    return [int(cell.candidates[s]) for s in sites]


def _row_json(city: City, row: _Row, servable: float) -> dict[str, Any]:
    """One ``by_count`` entry of the city (module docstring)."""
    cells = {c.id: c for c in city.cells}
    objective, bound = 0.0, 0.0
    sites: list[int] = []
    complete = True
    for cid, entry in row.entries.items():
        cell = cells[cid]
        if entry is None:
            complete = False
            continue
        objective += cell.weight * float(entry["objective"] or 0.0)
        cert = entry.get("certificate") or {}
        ub = cert.get("objective_bound")
        if ub is None:
            complete = False
        else:
            bound += cell.weight * float(ub)
        sites += _global_sites(cell, entry["sites"])
    distinct = sorted(set(sites))
    upper = bound if complete else None
    gap = None if upper is None else max(0.0, upper - objective)
    target = city.document.objective.target
    return {
        "ris_count": row.count,
        "ris_per_cell": dict(row.per_cell),
        "sites": distinct,
        "site_names": [city.candidates[s].get("name") for s in distinct],
        "shared_sites": len(sites) - len(distinct),
        "objective": objective,
        "share_of_servable": objective / servable if servable > 0 else None,
        "method": CITY_METHOD,
        "found_by": "each cell's district search",
        "top_layouts": [{"sites": distinct, "objective": objective}],
        "certificate": {
            "objective_bound": upper,
            "bound_side": "upper",
            "gap": gap,
            "relative_gap": None if upper is None or upper <= 0 or gap is None else gap / upper,
            "exact": False,
            "method": "the cells' district relaxations, weighted by their pair-weight shares"
            " (each cell's count as allocated)",
        },
        **(
            {"target_met": all(bool(e and e.get("target_met")) for e in row.entries.values())}
            if target is not None
            else {}
        ),
        **({} if complete else {"note": "a cell did not reach its count: no certified bound"}),
    }


def _pairs_summary(city: City, plans: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The cells' ``pairs_summary`` summed (pair counts) and weighted by their pair-weight
    shares (weights); the pairs of a cell without a candidate within reach are blind
    everywhere."""
    out: dict[str, Any] = {"pairs": int(city.pairs.size)}
    weighted: dict[str, float] = defaultdict(float)
    counted: dict[str, int] = defaultdict(int)
    denominator = None
    for cell in city.cells:
        if cell.document is None:
            weighted["blind_everywhere.weight"] += cell.weight
            counted["blind_everywhere.pairs"] += int(cell.pairs.size)
            continue
        s = plans[cell.id].get("pairs_summary") or {}
        denominator = s.get("denominator", denominator)
        for key, value in s.items():
            if isinstance(value, dict):
                weighted[f"{key}.weight"] += cell.weight * float(value.get("weight") or 0.0)
                counted[f"{key}.pairs"] += int(value.get("pairs") or 0)
            elif key.endswith("_weight"):
                weighted[key] += cell.weight * float(value or 0.0)
    out["denominator"] = denominator
    for key in sorted({k.split(".")[0] for k in [*weighted, *counted] if "." in k}):
        out[key] = {"pairs": counted[f"{key}.pairs"], "weight": weighted[f"{key}.weight"]}
    for key in sorted(k for k in weighted if "." not in k):
        out[key] = weighted[key]
    # the blind pairs of unplanned cells are not servable
    unplanned = sum(c.weight for c in city.cells if c.document is None)
    if "servable_weight" in out:
        out["servable_weight"] = max(0.0, out["servable_weight"])
    if unplanned and "servable_weight" not in out:
        out["servable_weight"] = 1.0 - unplanned
    if out.get("servable_weight"):
        out["coverable_share"] = out.get("coverable_weight", 0.0) / out["servable_weight"]
    return out


def _points(city: City, plans: dict[str, dict[str, Any]], rows: list[_Row]) -> list[Any]:
    """plan.json ``points`` of the city: each RX map point once, from the cell that owns the
    most weight of the pairs that end there (a point no pair ends at: the cell that holds it,
    else the first that lists it), at city-level indices (point, serving sites), keyed by the
    city's counts."""
    n_cells = len(city.cells)
    n_rx = len(city.rx_map.points)
    votes = np.bincount(
        city.pairs.rx_index * n_cells + city.owner, city.pairs.weights, minlength=n_rx * n_cells
    ).reshape(n_rx, n_cells)
    listed: dict[int, dict[int, dict[str, Any]]] = defaultdict(dict)  # point → cell → entry
    for k, cell in enumerate(city.cells):
        if cell.document is None:
            continue
        for entry in plans[cell.id].get("points") or []:
            listed[int(cell.rx[entry["index"]])][k] = entry
    out = []
    for point in sorted(listed):
        by_cell = listed[point]
        home = _cell_id(city, city.rx_map.points[point].tolist())
        k = max(by_cell, key=lambda k: (votes[point, k], city.cells[k].id == home, -k))
        cell, entry = city.cells[k], by_cell[k]
        item: dict[str, Any] = {
            "index": point,
            "position": entry["position"],
            "weight": entry["weight"],
            "cell": cell.id,
        }
        for name in ("bound_m", "served_fraction", "serving", "reason"):
            values = entry.get(name) or {}
            item[name] = {}
            for row in rows:
                v = values.get(str(row.per_cell.get(cell.id, -1)))
                if name == "serving" and v is not None:
                    v = _global_sites(cell, v)
                item[name][str(row.count)] = v
        out.append(item)
    return out


def _answers_sum(city: City, per_cell: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The cells' sizing answers summed: RISs, certified lower counts, elements, sites."""
    chosen = list(per_cell.values())
    count = sum(int(a["count"]) for a in chosen)
    lowers = [a.get("lower_bound") for a in chosen]
    lower = None if None in lowers else sum(int(v or 0) for v in lowers)
    cells = {c.id: c for c in city.planned}
    return {
        "count": count,
        "lower_bound": lower,
        "gap": None if lower is None else count - lower,
        "elements": sum(int(a["elements"]) for a in chosen),
        "ris_size_per_cell": {cid: a["ris_size"] for cid, a in per_cell.items()},
        "count_per_cell": {cid: a["count"] for cid, a in per_cell.items()},
        "sites": sorted(
            {s for cid, a in per_cell.items() for s in _global_sites(cells[cid], a["sites"] or [])}
        ),
    }


def _sizing(city: City, plans: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """The city's sizing: each RIS size of the ladder summed over the cells (a size a cell did
    not answer leaves the city's row open) and the answer, the sum of the cells' answers – the
    certified lower counts to the found counts –, when every cell reaches the target; else the
    sum over the cells that do (``reaching``), the others named."""
    answers = {c.id: (plans[c.id].get("sizing") or {}) for c in city.planned}
    if not any(answers.values()):
        return None
    first = next(iter(answers.values()))
    sizes = []
    for k, row in enumerate(first.get("sizes") or []):
        per = [(a.get("sizes") or [])[k] for a in answers.values()]
        counts = [p.get("count") for p in per]
        lowers = [p.get("lower_bound") for p in per]
        sizes.append(
            {
                "ris_size": row["ris_size"],
                "count": None if None in counts else sum(counts),
                "lower_bound": None if None in lowers else sum(lowers),
                "cells_answered": sum(c is not None for c in counts),
            }
        )
    found = {cid: a["answer"] for cid, a in answers.items() if a.get("answer")}
    missing = [cid for cid in answers if cid not in found]
    weight = {c.id: c.weight for c in city.cells}
    out: dict[str, Any] = {
        "target": first.get("target"),
        "of": first.get("of"),
        "sizes": sizes,
        "answer": None,
    }
    if not missing:
        out["answer"] = answer = _answers_sum(city, found)
        if answer["lower_bound"] is None:
            out["message"] = f"{answer['count']} RISs over the city reach the target in every cell"
        else:
            out["message"] = (
                f"between {answer['lower_bound']} and {answer['count']} RISs over the city reach"
                " the target in every cell (certified lower count: the cells' lower counts"
                " summed)"
            )
        return out
    share = sum(weight[cid] for cid in found)
    out["unreached_cells"] = missing
    if not found:
        out["message"] = "no cell reaches the target at any RIS size of the ladder"
        return out
    out["reaching"] = part = _answers_sum(city, found) | {"cells": len(found), "weight": share}
    between = (
        f"{part['count']}"
        if part["lower_bound"] is None
        else f"between {part['lower_bound']} and {part['count']}"
    )
    out["message"] = (
        f"cells {', '.join(missing)} reach the target at no RIS size of the ladder (each"
        f" cell's reason in its plan); the other {len(found)} cells ({100 * share:.1f} % of the"
        f" pair weight) reach it with {between} RISs"
    )
    return out


def city_json(city: City, plans: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The city's plan.json from its cells' (``plans``: cell id → the task's answer, its
    plan.json under ``plan``; module docstring)."""
    cell_plans = {cid: d["plan"] for cid, d in plans.items()}
    doc = city.document
    summary = _pairs_summary(city, cell_plans)
    servable = float(summary.get("servable_weight") or 0.0)
    rows = _rows(city, cell_plans)
    first = cell_plans[city.planned[0].id]
    warnings: dict[str, list[str]] = defaultdict(list)
    for cell in city.planned:
        for w in cell_plans[cell.id].get("warnings") or []:
            warnings[w].append(cell.id)
    by_count = [_row_json(city, r, servable) for r in rows]
    if any(r["shared_sites"] for r in by_count):
        warnings[
            "two cells chose the same candidate in their halos: the city's layout holds it once"
            " (by_count shared_sites); the coverage is a lower bound of that layout's"
        ] = []
    cells_json = []
    for cell in city.cells:
        plan = cell_plans.get(cell.id)
        entry: dict[str, Any] = {
            "id": cell.id,
            "bounds": list(cell.bounds),
            "pairs": int(cell.pairs.size),
            "border_pairs": cell.border_pairs,
            "weight": cell.weight,
            "candidates": int(cell.candidates.size),
            "tx_points": int(cell.tx.size),
            "rx_points": int(cell.rx.size),
            "planned": plan is not None,
        }
        if plan is None:
            entry["note"] = "no candidate within the cell and its halo: its pairs are blind"
        else:
            entry["ris_count"] = {str(r.count): r.per_cell.get(cell.id) for r in rows}
            entry["by_count"] = [
                {
                    "ris_count": e["ris_count"],
                    "objective": e["objective"],
                    "objective_bound": (e.get("certificate") or {}).get("objective_bound"),
                    "sites": _global_sites(cell, e["sites"]),
                    **({"target_met": e["target_met"]} if "target_met" in e else {}),
                }
                for e in plan["by_count"]
            ]
            entry["pairs_summary"] = plan.get("pairs_summary")
            answer = (plan.get("sizing") or {}).get("answer")
            if plan.get("sizing") is not None:
                entry["sizing"] = (
                    None
                    if answer is None
                    else {k: answer.get(k) for k in ("ris_size", "count", "lower_bound")}
                )
            entry["resources"] = {
                "time_s": plans[cell.id]["wall_s"],
                "worker_peak_mib": plans[cell.id]["worker_peak_mib"],
            }
        cells_json.append(entry)
    sizing = _sizing(city, cell_plans)
    nx = 1 + max(c.key[0] for c in city.cells) - min(c.key[0] for c in city.cells)
    ny = 1 + max(c.key[1] for c in city.cells) - min(c.key[1] for c in city.cells)
    return {
        "objective": doc.objective.model_dump(),
        "objective_better": first.get("objective_better"),
        "objective_unit": first.get("objective_unit"),
        "search_method": {
            "requested": "city",
            "used": CITY_METHOD,
            "why": "a city: every cell planned by the district search",
        },
        "pairs_summary": summary,
        "by_count": by_count,
        "candidates": [
            {"index": i, **c, "cell": _cell_id(city, c["position"])}
            for i, c in enumerate(city.candidates)
        ],
        "pairs": int(city.pairs.size),
        "tx_points": len(city.tx_map.points),
        "rx_points": len(city.rx_map.points),
        "known": list(doc.known),
        "points": _points(city, cell_plans, rows),
        "warnings": [
            f"{w} (cells {', '.join(cells)})" if cells else w for w, cells in warnings.items()
        ],
        **({"sizing": sizing} if sizing is not None else {}),
        "city": {
            "cell_m": city.cell_m,
            "halo_m": city.halo_m,
            "origin": list(city.origin),
            "grid": [nx, ny],
            "cells": len(city.cells),
            "planned_cells": len(city.planned),
            "border_pairs": int(city.border.sum()),
            "border_weight": float(city.pairs.weights[city.border].sum()),
        },
        "cells": cells_json,
        "provenance": provenance(city.given),
    }


def _cell_id(city: City, position: list[float]) -> str:
    i, j = (math.floor((position[a] - city.origin[a]) / city.cell_m) for a in (0, 1))
    return f"{i},{j}"


def city_summary(plan: dict[str, Any]) -> list[str]:
    """The command line's lines about a city plan: per city count its RISs, coverage and
    certified bound, and the sizing answer."""
    lines = []
    for row in plan["by_count"]:
        bound = row["certificate"]["objective_bound"]
        lines.append(
            f"{row['ris_count']} RISs over {len(row['ris_per_cell'])} cells"
            f" ({len(row['sites'])} sites): coverage {finite_or_none(row['objective']):.3g},"
            f" certified ≤ {'–' if bound is None else f'{bound:.3g}'}"
        )
    if plan.get("sizing"):
        lines.append(f"sizing: {plan['sizing']['message']}")
    return lines
