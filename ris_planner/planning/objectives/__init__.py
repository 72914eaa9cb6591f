"""Objectives (one module per kind behind :mod:`.protocol`, looked up by name in its registry)
and the batched layout score (:mod:`.scoring`). docs/concepts/scoring.md, "Objectives"."""

from ris_planner.planning.objectives import coverage, mean_capped, quantile  # noqa: F401
from ris_planner.planning.objectives.protocol import (
    ObjectiveKind,
    objective_kind,
    objective_names,
    register,
    unregister,
)
from ris_planner.planning.objectives.quantile import weighted_quantile
from ris_planner.planning.objectives.scoring import (
    BATCH_MATRICES,
    EXACT_SITES,
    KERNEL_MATRICES,
    RX_STATES,
    SCREEN_MARGIN,
    TX_STATES,
    Scorer,
    loss_from_metric,
    objective_from_loss,
    objective_value,
    score_chunk,
    score_chunk_ranked,
    select_metric,
    site_groups,
    underdetermined,
)

__all__ = [
    "BATCH_MATRICES",
    "EXACT_SITES",
    "KERNEL_MATRICES",
    "RX_STATES",
    "SCREEN_MARGIN",
    "TX_STATES",
    "ObjectiveKind",
    "Scorer",
    "loss_from_metric",
    "objective_from_loss",
    "objective_kind",
    "objective_names",
    "objective_value",
    "register",
    "score_chunk",
    "score_chunk_ranked",
    "select_metric",
    "site_groups",
    "underdetermined",
    "unregister",
    "weighted_quantile",
]
