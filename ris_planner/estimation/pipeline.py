"""One full estimate: Algorithm 1 (coarse + MLE) then Algorithm 2 (coarse + MLE).

The coarse position is computed from the coarse channel parameters (both coarse stages in a
row, as the paper's "coarse" curves); the refined position from the refined channel
parameters, started at the coarse position. Only the paths present for the pair (in an
environment: not blocked, in view) enter Algorithm 2.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ris_planner.estimation.channel_estimation import ChannelEstimate, ChannelEstimator
from ris_planner.estimation.position_estimation import (
    PositionEstimate,
    coarse_position,
    refine_position,
)
from ris_planner.estimation.signal import SignalSetup
from ris_planner.model.simulation import EstimatorSettings

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FullEstimate:
    """Coarse and refined channel and position estimates, and the time of each stage [s]."""

    channel_coarse: ChannelEstimate
    channel_refined: ChannelEstimate
    position_coarse: PositionEstimate
    position_refined: PositionEstimate
    seconds: dict[str, float] = field(default_factory=dict)


class Estimator:
    """Algorithms 1 and 2 for one setup and settings (caches what does not depend on data)."""

    def __init__(self, setup: SignalSetup, settings: EstimatorSettings, candidates: FloatArray):
        self.setup = setup
        self.settings = settings
        self.candidates = candidates
        self.channel = ChannelEstimator(setup, settings.delay_fft_size, settings.angle_fft_size)

    def estimate(self, ytilde: ComplexArray) -> FullEstimate:
        """Run both algorithms on the separated observations Ỹ [L+1, K, G̃]."""
        s, st = self.setup, self.settings
        t0 = time.perf_counter()
        ch_coarse = self.channel.coarse(ytilde)
        t1 = time.perf_counter()
        ch_fine = self.channel.refine(ytilde, ch_coarse, st.max_channel_iterations)
        t2 = time.perf_counter()
        used = s.ris_present
        ris = tuple(s.ris[i] for i in used)
        pair_w, path_w = present_weights(used, s.n_ris, st.pair_weights, st.path_weights)
        pos_coarse = coarse_position(
            ris, s.wavelength, ch_coarse.restricted(used), self.candidates, pair_w, path_w
        )
        t3 = time.perf_counter()
        pos_fine = refine_position(
            ris, s.wavelength, s.los, ch_fine.restricted(used), pos_coarse, st.sigma
        )
        t4 = time.perf_counter()
        times = {
            "channel_coarse": t1 - t0,
            "channel_refine": t2 - t1,
            "position_coarse": t3 - t2,
            "position_refine": t4 - t3,
        }
        return FullEstimate(ch_coarse, ch_fine, pos_coarse, pos_fine, times)


def present_weights(
    used: tuple[int, ...],
    n_ris: int,
    pair_weights: list[float] | None,
    path_weights: list[float] | None,
) -> tuple[list[float] | None, list[float] | None]:
    """The settings' w_ij (RIS pairs i<j of the layout, lexicographic) and w_ℓ restricted to
    the RISs ``used`` (their path exists for the pair); unchanged when all are used."""
    if used == tuple(range(n_ris)):
        return pair_weights, path_weights
    pairs = list(combinations(range(n_ris), 2))
    kept = set(combinations(used, 2))
    pair_w = (
        None
        if pair_weights is None
        else [w for w, ij in zip(pair_weights, pairs, strict=True) if ij in kept]
    )
    path_w = None if path_weights is None else [path_weights[i] for i in used]
    return pair_w, path_w
