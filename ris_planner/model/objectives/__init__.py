"""Objective kinds – part of the plan document's contract: a kind's JSON name, its parameter,
its direction and its value over per-pair bounds, with the relaxation bound and screening the
planner's certificates and scorer use (docs/concepts/scoring.md, "Objectives"). One module per
kind behind :mod:`.protocol`; importing this package registers the built-in kinds."""

from ris_planner.model.objectives import coverage, mean_capped, quantile  # noqa: F401
from ris_planner.model.objectives.protocol import (
    ObjectiveKind,
    objective_kind,
    objective_names,
    register,
    unregister,
)
from ris_planner.model.objectives.quantile import weighted_quantile

__all__ = [
    "ObjectiveKind",
    "objective_kind",
    "objective_names",
    "register",
    "unregister",
    "weighted_quantile",
]
