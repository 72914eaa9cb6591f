"""Quantile: the weighted ``q``-quantile of the bound [m] (lower is better; blind pairs rank
last, so the quantile is ``inf`` once they weigh more than 1 − q). docs/concepts/planning.md,
"Objectives"."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ris_planner.model.objectives.protocol import FloatArray, ObjectiveKind, register

if TYPE_CHECKING:
    from ris_planner.model.objectives.protocol import Objective


def weighted_quantile(values: FloatArray, weights: FloatArray, q: float | FloatArray) -> FloatArray:
    """Smallest v with Σ_{values ≤ v} w ≥ q·Σw per row of values [B, P] (``inf`` ranks last).

    weights : [P] shared by the rows, or [B, P] (each row's sum > 0);
    q : scalar or [Q]; returns [B] or [B, Q]."""
    idx = np.argsort(values, axis=1, kind="stable")
    w = np.broadcast_to(weights, values.shape)
    cw = np.cumsum(np.take_along_axis(w, idx, axis=1), axis=1)
    cw /= cw[:, -1:]
    qs = np.atleast_1d(np.asarray(q, dtype=float))
    # tolerance: the cumulative sums carry ~P·ε rounding; a quantile exactly on a step is kept
    pos = np.empty((values.shape[0], qs.size), dtype=int)
    for k, qk in enumerate(qs):
        pos[:, k] = np.argmax(cw >= qk - 1e-12, axis=1)
    rows = np.arange(values.shape[0])[:, None]
    out = values[rows, idx[rows, pos]]
    return out[:, 0] if np.ndim(q) == 0 else out


class Quantile(ObjectiveKind):
    name = "quantile"
    label = "quantile"
    parameter = "q"
    parameter_label = "Quantile q (0–1)"

    def value(self, spec: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
        assert spec.q is not None
        return weighted_quantile(metric, weights, spec.q)

    def level_label(self, spec: Objective) -> tuple[float | None, str]:
        return None, f"the layout's {spec.q:g}-quantile"


register(Quantile())
