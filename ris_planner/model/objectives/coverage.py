"""Coverage: the weighted fraction of pairs whose bound is ≤ ``threshold_m`` (higher is
better; a blind pair is outside). docs/concepts/planning.md, "Objectives"."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ris_planner.model.objectives.protocol import FloatArray, ObjectiveKind, register

if TYPE_CHECKING:
    from ris_planner.model.objectives.protocol import Objective


class Coverage(ObjectiveKind):
    name = "coverage"
    label = "coverage"
    parameter = "threshold_m"
    parameter_label = "Coverage threshold [m]"
    higher_is_better = True
    unit = ""
    max_value = 1.0
    share_of_servable = True

    @staticmethod
    def _threshold(spec: Objective) -> float:
        assert spec.threshold_m is not None
        return float(spec.threshold_m)

    def value(self, spec: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
        return np.asarray(((metric <= self._threshold(spec)) * weights).sum(axis=1))

    def settle_limits(self, spec: Objective, safety: float) -> tuple[float, float]:
        """A relaxed PEB² ≤ θ² stays counted; a bound with √lower·(1 − safety) > θ stays
        uncounted."""
        thr = self._threshold(spec)
        return thr**2, (thr / (1.0 - safety)) ** 2 * (1 + 1e-12)

    def reference_level(self, spec: Objective) -> float:
        return self._threshold(spec)

    def screen_level(self, spec: Objective) -> float | None:
        return self._threshold(spec)

    def level_label(self, spec: Objective) -> tuple[float | None, str]:
        thr = self._threshold(spec)
        return thr, f"coverage threshold {thr:g} m"


register(Coverage())
