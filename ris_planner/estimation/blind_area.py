"""The blind-area interpretation (section 'Interpretation of the Blind Area'): the noise-free
cost J of eq. coarse_position_costFun over TX candidates for a fixed true TX/RX pair, as a
map over x–y at the TX height, and the candidate TX/RX pairs at its local minima. In a blind
spot the global minimum is shallow and other candidates give almost the same spatial
frequencies and delay differences, so noise moves the estimate far. In an environment the
cost uses the paths present for the true pair, as the estimator does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import minimum_filter

from ris_planner.bounds.compute import scenario_path_presence
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.estimation.channel_estimation import ChannelEstimate
from ris_planner.estimation.pipeline import present_weights
from ris_planner.estimation.position_estimation import candidate_costs, channel_model
from ris_planner.estimation.signal import ris_arrays
from ris_planner.model.limits import count
from ris_planner.model.scenario import Scenario

FloatArray = NDArray[np.float64]

MAX_MAP_POINTS = 4_000_000


@dataclass(frozen=True)
class Minimum:
    """A local minimum of J: the TX candidate, its RX candidate and clock offset, and J."""

    tx: FloatArray
    rx: FloatArray
    clock_offset_m: float
    cost: float

    def to_json(self) -> dict[str, Any]:
        return {
            "tx": [float(v) for v in self.tx],
            "rx": [float(v) for v in self.rx],
            "clock_offset_m": self.clock_offset_m,
            "cost_m": self.cost,
        }


@dataclass(frozen=True)
class CostMap:
    """J over the grid x [nx] × y [ny] at height z: cost [nx, ny] (inf = no consistent RX)."""

    x: FloatArray
    y: FloatArray
    z: float
    cost: FloatArray
    minima: list[Minimum]
    true_tx: FloatArray
    true_rx: FloatArray
    ris_positions: FloatArray

    def to_json(self) -> dict[str, Any]:
        finite = np.isfinite(self.cost)
        return {
            "true_tx": [float(v) for v in self.true_tx],
            "rx": [float(v) for v in self.true_rx],
            "z_m": self.z,
            "grid": {
                "x_m": [float(self.x[0]), float(self.x[-1]), len(self.x)],
                "y_m": [float(self.y[0]), float(self.y[-1]), len(self.y)],
            },
            "consistent_fraction": float(finite.mean()),
            "minima": [m.to_json() for m in self.minima],
        }


def noise_free_channel(scenario: Scenario, tx: FloatArray, rx: FloatArray) -> ChannelEstimate:
    """The true η_N of a pair as a channel estimate (what a noise-free Algorithm 1 returns);
    paths missing for the pair in an environment are NaN, as Algorithm 1 leaves them."""
    ris = ris_arrays(scenario)
    presence = scenario_path_presence(scenario, tx[None, :], rx[None, :])
    los = bool(presence["los"][0])
    state = np.concatenate([tx, rx, [scenario.system.clock_offset_m]])
    eta, _ = channel_model(ris, los, state)
    n = len(ris)
    ris_eta = eta[1:] if los else eta
    length = np.concatenate([[eta[0] if los else np.nan], ris_eta[2::3]])
    xi, zeta = ris_eta[0::3], ris_eta[1::3]
    missing = ~np.array([bool(presence[f"ris{i + 1}"][0]) for i in range(n)])
    if np.any(missing):
        xi, zeta = np.where(missing, np.nan, xi), np.where(missing, np.nan, zeta)
        length[1:][missing] = np.nan
    return ChannelEstimate(length=length, xi=xi, zeta=zeta, gain=np.zeros(n + 1, dtype=complex))


def cost_map(
    scenario: Scenario,
    rx: ArrayLike | None = None,
    tx: ArrayLike | None = None,
    *,
    extent: tuple[float, float, float, float] | None = None,
    step_m: float = 0.05,
    n_minima: int = 5,
    pair_weights: list[float] | None = None,
    path_weights: list[float] | None = None,
) -> CostMap:
    """J(p̌_T) on an x–y grid at the TX height, and its ``n_minima`` deepest local minima.

    extent : (xmin, xmax, ymin, ymax) [m]; default the box around the RISs and the UEs with
    a 1 m margin. step_m > 0 is the grid step.
    """
    if not (step_m > 0 and math.isfinite(step_m)):
        raise RisPlannerError(f"step_m must be > 0, got {step_m}")
    tx_a = scenario.tx_array[0] if tx is None else np.asarray(tx, dtype=float).reshape(3)
    rx_a = scenario.rx_array[0] if rx is None else np.asarray(rx, dtype=float).reshape(3)
    ris = ris_arrays(scenario)
    ris_pos = np.stack([a.position for a in ris])
    if extent is None:
        pts = np.vstack([ris_pos, tx_a, rx_a])
        lo, hi = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
        extent = (lo[0], hi[0], lo[1], hi[1])
    xmin, xmax, ymin, ymax = extent
    if not (xmax >= xmin and ymax >= ymin):
        raise RisPlannerError(f"the map area is empty: extent = {list(extent)} needs max ≥ min")
    # the counts first (overflow-safe), the arrays only within the limit
    nx, ny = count((xmax - xmin) / step_m + 1e-9) + 1, count((ymax - ymin) / step_m + 1e-9) + 1
    if nx * ny > MAX_MAP_POINTS:
        raise LimitExceededError(
            f"{nx * ny} map points exceed the limit {MAX_MAP_POINTS}; use a larger step",
            MAX_MAP_POINTS,
        )
    x = np.asarray(xmin + step_m * np.arange(nx))
    y = np.asarray(ymin + step_m * np.arange(ny))
    gx, gy = np.meshgrid(x, y, indexing="ij")
    cand = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, tx_a[2])], axis=-1)
    channel = noise_free_channel(scenario, tx_a, rx_a)
    # in an environment only the RIS paths present for the pair (as the estimator)
    used = tuple(int(i) for i in np.flatnonzero(np.isfinite(channel.length[1:])))
    if len(used) < 2:
        raise RisPlannerError(
            f"the blind-area map needs at least 2 RIS paths; {len(used)} exist for this pair"
            " (the others are blocked or out of view)"
        )
    pair_w, path_w = present_weights(used, len(ris), pair_weights, path_weights)
    cc = candidate_costs(
        tuple(ris[i] for i in used),
        scenario.system.wavelength,
        channel.restricted(used),
        cand,
        pair_w,
        path_w,
    )
    cost = cc.cost.reshape(gx.shape)
    # candidate_costs maps every non-finite cost to inf
    local = (minimum_filter(cost, size=3, mode="nearest") == cost) & np.isfinite(cost)
    idx = np.flatnonzero(local.ravel())
    idx = idx[np.argsort(cc.cost[idx])][:n_minima]
    minima = [
        Minimum(cand[i].copy(), cc.rx[i].copy(), float(cc.clock_offset_m[i]), float(cc.cost[i]))
        for i in idx
    ]
    return CostMap(
        x=x,
        y=y,
        z=float(tx_a[2]),
        cost=cost,
        minima=minima,
        true_tx=tx_a,
        true_rx=rx_a,
        ris_positions=ris_pos,
    )
