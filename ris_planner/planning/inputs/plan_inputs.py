"""A plan's checked inputs, the bundle every later stage reads (docs/concepts/planning.md,
"Pipeline"); made by :func:`ris_planner.planning.prepare.prepare_plan`."""

from __future__ import annotations

from dataclasses import dataclass

from ris_planner.environment import Scene
from ris_planner.model.plan import PlanDocument
from ris_planner.model.search_methods import MethodChoice
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.inputs.sites import Site
from ris_planner.planning.inputs.ue_maps import PairSet, PointMap


@dataclass(frozen=True)
class PlanInputs:
    """A plan's checked inputs before any bound is computed (:func:`prepare_plan`)."""

    document: PlanDocument
    sites: list[Site]
    tx_map: PointMap
    rx_map: PointMap
    pairs: PairSet
    scene: Scene
    dropped: dict[str, int]
    """UE map points dropped inside prisms, per map."""
    directions: str
    """How unordered pairs count both directions (:func:`maps.unordered_directions`)."""
    counts: list[int]
    """The RIS counts to search (``ris_count``, or 1 … ``max_ris`` in target mode)."""
    feasibility: Feasibility
    """Constraints and costs of the candidate sites."""
    choice: MethodChoice
    """The search that runs and why (plan.json ``search_method``)."""
    sizing_choice: MethodChoice | None = None
    """The search that answers the sizing question and why (plan.json
    ``sizing.search_method``; ``None`` without ``sizing``)."""
