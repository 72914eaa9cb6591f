"""Power control of the DIR+DER codebook by one ratio γ_P (eq. opt_formulation_3).

The objective is the mean PEB² over the sampled prior positions as a function of the beam
powers (``run_power`` passes the stacked-information evaluator and re-evaluates the answer with
``compute_bounds``). The search is bounded in log10 γ_P: a coarse
grid with step 1/4 decade that contains γ_P = 1 (uniform power, so the result is never worse
than uniform), then Brent's bounded method between the best grid point's neighbours.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from ris_planner.physics.beams import gamma_p_powers
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]

LOG10_GAMMA_RANGE = (-3.0, 3.0)
"""Searched γ_P range, 1e-3 … 1e3: beyond it the weaker beam family holds < 1e-6 of the power,
which is indistinguishable from DIR only / DER only."""

GRID_STEP_DECADES = 0.25
BRENT_XATOL_DECADES = 1e-3


@dataclass(frozen=True)
class GammaSearch:
    """Best γ_P, its objective [m²] and powers [G̃]; the evaluated (γ_P, objective) pairs."""

    value: float
    objective: float
    powers: FloatArray
    evaluations: list[tuple[float, float]]


def search_gamma_p(
    objective: Callable[[FloatArray], float],
    beam_types: NDArray[np.int_],
    progress: ProgressCallback = no_progress,
) -> GammaSearch:
    """Minimise ``objective(powers)`` over γ_P ≥ 0 by the bounded 1-D search.

    objective : mean PEB² [m²] of the first-block powers (``inf`` allowed for blind spots).
    """
    evaluations: list[tuple[float, float]] = []

    def f(log_g: float) -> float:
        val = objective(gamma_p_powers(beam_types, 10.0**log_g))
        evaluations.append((float(10.0**log_g), val))
        return val if np.isfinite(val) else 1e300

    lo, hi = LOG10_GAMMA_RANGE
    grid = np.arange(lo, hi + GRID_STEP_DECADES / 2, GRID_STEP_DECADES)
    values = []
    for i, x in enumerate(grid):
        values.append(f(float(x)))
        progress(0.7 * (i + 1) / grid.size, "γ_P grid")
    best = int(np.argmin(values))
    x_best, v_best = float(grid[best]), values[best]
    left, right = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    if right > left:
        res = minimize_scalar(
            f,
            bounds=(float(left), float(right)),
            method="bounded",
            options={"xatol": BRENT_XATOL_DECADES},
        )
        if float(res.fun) < v_best:
            x_best, v_best = float(res.x), float(res.fun)
    progress(1.0, "γ_P search done")
    value = float(10.0**x_best)
    return GammaSearch(
        value=value,
        objective=v_best if v_best < 1e300 else float("inf"),
        powers=gamma_p_powers(beam_types, value),
        evaluations=evaluations,
    )
