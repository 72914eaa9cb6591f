"""Layer 6, bounds: PEB_T, PEB_R, CEB and the channel bounds of a scenario, the visibility of its
paths and the warnings that state a result's assumptions (docs/reference/layers.md).

:func:`compute_bounds` and :class:`BoundsResult` live in :mod:`ris_planner.bounds.compute`."""

from ris_planner.bounds.compute import BoundsResult, compute_bounds

__all__ = ["BoundsResult", "compute_bounds"]
