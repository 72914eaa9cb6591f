"""Objectives – the kinds (one module each behind the protocol of
:mod:`ris_planner.model.objectives`, looked up by name in its registry) and the batched layout
score (:mod:`.scoring`). docs/concepts/scoring.md, "Objectives"."""

from ris_planner.model.objectives import (  # registers the built-in kinds
    ObjectiveKind,
    objective_kind,
    objective_names,
    register,
    unregister,
    weighted_quantile,
)
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
