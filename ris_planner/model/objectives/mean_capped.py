"""Capped mean: the weighted mean of min(bound, ``cap_m``) [m] (lower is better; a blind pair
counts as the cap). docs/concepts/planning.md, "Objectives"."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ris_planner.model.objectives.protocol import FloatArray, ObjectiveKind, register

if TYPE_CHECKING:
    from ris_planner.model.objectives.protocol import Objective


class MeanCapped(ObjectiveKind):
    name = "mean_capped"
    label = "capped mean"
    parameter = "cap_m"
    parameter_label = "Cap on the bound [m]"

    @staticmethod
    def _cap(spec: Objective) -> float:
        assert spec.cap_m is not None
        return float(spec.cap_m)

    def value(self, spec: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
        return np.asarray((np.minimum(metric, self._cap(spec)) * weights).sum(axis=1))

    def settle_limits(self, spec: Objective, safety: float) -> tuple[float, float]:
        """min(lb, cap) counts: a bound ≥ cap is final."""
        return -np.inf, (self._cap(spec) / (1.0 - safety)) ** 2 * (1 + 1e-12)

    def reference_level(self, spec: Objective) -> float:
        return self._cap(spec)

    def screen_level(self, spec: Objective) -> float | None:
        return self._cap(spec)

    def level_label(self, spec: Objective) -> tuple[float | None, str]:
        cap = self._cap(spec)
        return cap, f"cap {cap:g} m"


register(MeanCapped())
