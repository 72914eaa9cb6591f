"""The inputs stage of a plan (docs/concepts/planning.md, "Pipeline"): the document checked,
its sites expanded, its maps built (points inside prisms dropped), its pairs drawn and every
limit checked before any bound is computed."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.limits import cache_layout
from ris_planner.model.plan import PlanDocument
from ris_planner.model.search_methods import sparse_search
from ris_planner.planning.inputs.constraints import build_feasibility
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import PointMap, build_pairs, unordered_directions
from ris_planner.planning.resources.admission import Admitted, admit
from ris_planner.planning.scoring.visibility import check_sites_outside, drop_inside
from ris_planner.planning.search.layouts import MIN_TASK_MATRICES


def validate_document(document: PlanDocument | dict[str, Any]) -> PlanDocument:
    """The plan document with the CLI's and the service's checks, sizes before work
    (:func:`ris_planner.planning.resources.admission.validate_plan`)."""
    return admit(document).document


def prepare_plan(plan: Admitted | PlanDocument | dict[str, Any]) -> PlanInputs:
    """The inputs of an admitted plan (a document is admitted first:
    :func:`~ris_planner.planning.resources.admission.admit`): its sites expanded, its maps
    built (each once: the admission's), points inside obstacles dropped, its pairs drawn and
    every limit that :func:`run_plan` checks before its work (RIS counts vs sites,
    ``max_pairs``, the site cache) – a dry run: raises what ``run_plan`` would raise, computes
    no bound."""
    admitted = plan if isinstance(plan, Admitted) else admit(plan)
    doc = admitted.document
    # the fields of view apply in free space too (an empty scene); obstacles where given
    scene = Scene.from_environment(doc.environment)
    sites = admitted.sites
    wanted = doc.max_counts
    if doc.ris_count is None:  # target mode up to max_ris: at most every candidate
        wanted = [c for c in wanted if c <= len(sites)]
    elif max(wanted) > len(sites):
        raise RisPlannerError(f"ris_count {max(wanted)} exceeds the {len(sites)} candidate sites")
    feasibility = build_feasibility(sites, doc.constraints, doc.cost)
    wanted = [c for c in wanted if c >= len(feasibility.required)]
    tx_map, rx_map = admitted.maps
    dropped = {"tx": 0, "rx": 0}
    if not scene.empty:
        check_sites_outside(scene, sites)
        tx_map, dropped["tx"], rx_map, dropped["rx"] = _drop_points(scene, doc, tx_map, rx_map)
    directions = unordered_directions(doc.pairs, doc.objective.metric, tuple(doc.known))
    pairs = build_pairs(
        tx_map, rx_map, doc.pairs, doc.max_pairs, directions == "explicit", scene=scene
    )
    if not sparse_search(doc):  # the district search keeps no site cache
        cache_layout(len(sites) * pairs.size, doc.system.wavefront)  # the budget, before work
    return PlanInputs(
        doc,
        sites,
        tx_map,
        rx_map,
        pairs,
        scene,
        dropped,
        directions,
        wanted,
        feasibility,
        admitted.choice,
        admitted.sizing_choice,
    )


def rebased(inputs: PlanInputs, document: PlanDocument) -> PlanInputs:
    """``inputs`` for another run over the same maps and pairs – a sweep value or a sizing
    size: ``document`` (validated; its maps, pairs and environment those of ``inputs``) with
    its own sites (the RIS grid may differ), constraints and counts, the same search."""
    sites = expand_sites(document)
    counts = document.max_counts
    if document.ris_count is None:
        counts = [c for c in counts if c <= len(sites)]
    feasibility = build_feasibility(sites, document.constraints, document.cost)
    counts = [c for c in counts if c >= len(feasibility.required)]
    return replace(
        inputs,
        document=document,
        sites=sites,
        counts=counts,
        feasibility=feasibility,
        sizing_choice=None,
    )


def _drop_points(
    scene: Scene, doc: PlanDocument, tx_map: PointMap, rx_map: PointMap
) -> tuple[PointMap, int, PointMap, int]:
    """The UE maps without their points inside prisms (and the counts); raises when a map or
    the fixed heatmap TX lies inside."""
    tx_map, n_tx = drop_inside(tx_map, scene)
    rx_map, n_rx = drop_inside(rx_map, scene)
    for what, pm in (("tx_map", tx_map), ("rx_map", rx_map)):
        if len(pm.points) == 0:
            raise RisPlannerError(f"{what}: every point lies inside a prism of the environment")
    if doc.heatmap_tx is not None:
        hit = int(scene.inside(np.asarray(doc.heatmap_tx, dtype=float))[0])
        if hit >= 0:
            raise RisPlannerError(
                f"heatmap_tx {doc.heatmap_tx} lies inside environment"
                f" {scene.environment.label(hit)}"
            )
    return tx_map, n_tx, rx_map, n_rx


def needs_workers(inputs: PlanInputs, max_exhaustive: int, workers: int, min_work: int = 0) -> bool:
    """Whether the plan starts its executor's workers: the search will split a batch over
    them (:func:`~ris_planner.planning.search.layouts.chunk_count`: some count's layouts – all of
    them, or ``max_exhaustive`` as many as a greedy search's rounds come to at most – times
    the pairs reach one minimal task per worker) and the whole search's layout-pair
    evaluations reach ``min_work`` (``search.pool_min_work``). Otherwise every batch runs
    in-process."""
    n_sites, n_pairs = len(inputs.sites), inputs.pairs.size
    per_count = [min(math.comb(n_sites, c), max_exhaustive) * n_pairs for c in inputs.counts]
    splits = max(per_count, default=0) >= workers * MIN_TASK_MATRICES
    return workers > 1 and splits and sum(per_count) >= min_work
