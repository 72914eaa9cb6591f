"""A city as independent districts on an executor (docs/concepts/district.md, "A city").

:func:`split_city` cuts a plan document (local metres) into districts on a square grid of
``cell_m``: a district's UEs are the map points inside its cell (points of both maps, with
their weights; a pair's TX and RX are drawn from the district's own points, so sidelink pairs
never cross a cell border, and their separation is measured straight: the roads are cut into
points), its candidates those within ``cell_m`` plus the pair model's
separation of the cell (a RIS across the street from the border serves the cell's pairs), and
its sample the document's, shared out by the cells' UE weight. The obstacles stay whole.

:func:`plan_city` plans every district with the district search on an executor
(:class:`~ris_planner.runtime.executor.SerialExecutor`, ``LocalExecutor`` or ``DaskExecutor``):
each task carries its own district document and returns its plan.json, so workers share no
state. The city's answer sums the districts' RIS counts and weighs their coverage by their
share of the UE weight.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ris_planner.core.errors import RisPlannerError
from ris_planner.model.plan import PairSample, PlanDocument
from ris_planner.planning.inputs.separation import near_combinations
from ris_planner.planning.inputs.ue_maps import build_map
from ris_planner.planning.pipeline import run_plan
from ris_planner.runtime.executor import Executor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, no_progress

MIN_DISTRICT_PAIRS = 50
"""A cell whose share of the sample is below this many pairs still gets this many."""


def split_city(document: dict[str, Any], cell_m: float) -> list[dict[str, Any]]:
    """The district documents of a city document (module docstring): the cells with a
    sidelink pair and a candidate, in row-major cell order, each with ``"search": {"method":
    "district"}``, its ``district`` name ``"cell i,j"`` and its ``weight`` (UE weight share)."""
    if not cell_m > 0:
        raise RisPlannerError(f"the cell size must be > 0 m, got {cell_m}")
    doc = PlanDocument.model_validate(document)
    if not isinstance(doc.pairs, PairSample):
        raise RisPlannerError('a city is planned from sampled pairs: "pairs": {"sample": N, …}')
    tx = build_map(doc.tx_map, "tx_map")
    rx = build_map(doc.rx_map, "rx_map")
    margin = cell_m + (doc.pairs.max_separation_m or 0.0)
    cand = [c.model_dump(exclude_none=True) for c in doc.candidates]
    if doc.walls or doc.facades:
        raise RisPlannerError("split the city from explicit candidates (ris-planner sites)")
    pos = np.array([c["position"][:2] for c in cand]) if cand else np.zeros((0, 2))
    allpts = np.concatenate([tx.points[:, :2], rx.points[:, :2]])
    origin = allpts.min(axis=0)
    cells_t = np.floor((tx.points[:, :2] - origin) / cell_m).astype(int)
    cells_r = np.floor((rx.points[:, :2] - origin) / cell_m).astype(int)
    keys = sorted({tuple(c) for c in cells_t.tolist()} & {tuple(c) for c in cells_r.tolist()})
    total = float(tx.weights.sum())
    base = document | {"search": {"method": "district"}}
    base.pop("sweep", None)
    out = []
    for i, j in keys:
        in_t = np.all(cells_t == (i, j), axis=1)
        in_r = np.all(cells_r == (i, j), axis=1)
        centre = origin + (np.array([i, j]) + 0.5) * cell_m
        near = np.all(np.abs(pos - centre) <= margin / 2 + cell_m / 2, axis=1)
        if not near.any():
            continue
        pair_spec = doc.pairs.model_copy(update={"separation": "straight"})
        try:  # a cell whose UEs are never near each other has no sidelink pair
            near_combinations(tx.points[in_t], rx.points[in_r], None, None, pair_spec)
        except RisPlannerError:
            continue
        share = float(tx.weights[in_t].sum()) / total
        sample = max(MIN_DISTRICT_PAIRS, math.ceil(doc.pairs.sample * share))
        counts = doc.ris_count
        out.append(
            base
            | {
                "description": f"cell {i},{j} of {document.get('description') or 'the city'}",
                "tx_map": {
                    "points": tx.points[in_t].tolist(),
                    "weights": tx.weights[in_t].tolist(),
                },
                "rx_map": {
                    "points": rx.points[in_r].tolist(),
                    "weights": rx.weights[in_r].tolist(),
                },
                "candidates": [cand[k] for k in np.flatnonzero(near)],
                "pairs": doc.pairs.model_dump(exclude_none=True)
                | {"sample": sample, "separation": "straight"},
                "ris_count": None
                if counts is None
                else sorted({min(c, int(near.sum())) for c in counts}),
                "district": f"cell {i},{j}",
                "weight": share,
            }
        )
    if not out:
        raise RisPlannerError("no cell holds UE points of both maps and a candidate")
    return out


def _district_task(_shared: object, district: dict[str, Any]) -> dict[str, Any]:
    """One district's plan.json (runs on a worker)."""
    doc = {k: v for k, v in district.items() if k not in ("district", "weight")}
    if not doc.get("ris_count"):
        doc.pop("ris_count", None)
    plan = run_plan(doc, executor=SerialExecutor()).to_json()
    return {"district": district["district"], "weight": district["weight"], **plan}


def plan_city(
    districts: list[dict[str, Any]],
    executor: Executor | None = None,
    progress: ProgressCallback = no_progress,
) -> dict[str, Any]:
    """Every district planned on ``executor`` (one task each); plan.json of the city: the
    districts' plans and, per RIS count of the first district's, the city's RIS total and its
    UE-weighted coverage."""
    ex = executor or SerialExecutor()
    n = len(districts)
    plans = ex.map(_district_task, None, districts, lambda k: progress(k / n, f"district {k}/{n}"))
    totals = []
    for row in plans[0]["by_count"] if plans else []:
        c = row["ris_count"]
        rows = [r for p in plans for r in p["by_count"] if r["ris_count"] == c]
        if len(rows) < len(plans):
            continue  # a district whose path stopped before this count
        weight = sum(p["weight"] for p in plans)
        totals.append(
            {
                "ris_per_district": c,
                "ris_total": c * len(plans),
                "coverage": sum(
                    p["weight"] * r["objective"] for p, r in zip(plans, rows, strict=True)
                )
                / weight,
                "upper_bound": sum(
                    p["weight"] * r["certificate"]["objective_bound"]
                    for p, r in zip(plans, rows, strict=True)
                )
                / weight,
            }
        )
    return {"method": "city", "districts": plans, "by_count": totals}
