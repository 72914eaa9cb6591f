"""Per-site information cache: each candidate RIS path's 7×7 information on [p_T, p_R, B]
for every pair, computed once (DESIGN.md, performance model).

With the ``expected_random`` codebook a RIS path's equivalent FIM after eliminating its gain
(α, β) by a Schur complement is E[Q]-based with Σ_g δ_g² = Γ·G̃ = G (the core's
:func:`ris_planner.bounds.ris_path_information` weights it by ``block_count * weights.sum()``),
so it does not depend on how many RISs share the time-orthogonal blocks: the cached matrix of a
site is exactly the contribution :func:`ris_planner.bounds.compute_bounds` adds for that RIS in
any layout, and a layout's state FIM is the LOS matrix plus the sum of its sites' matrices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner import fim
from ris_planner.bounds import los_path_information, ris_path_information, stand_ins, ue_on_ris
from ris_planner.ldl import pack
from ris_planner.planning.maps import PairSet
from ris_planner.planning.sites import Site
from ris_planner.progress import ProgressCallback, no_progress
from ris_planner.scenario import SystemParams

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

N_STATES = 7
N_PACKED = N_STATES * (N_STATES + 1) // 2


@dataclass(frozen=True)
class SiteCache:
    """packed : [28, S, P] packed 7×7 state information of each site's RIS path;
    los : [28, P] the LOS path's (``None`` when the LOS is blocked);
    degenerate : [S, P] a UE within 1 mm of the site (the pair is a blind spot there);
    far_field : [S, P] d_T d_R/(d_T + d_R) ≥ 2D²/λ for the site (footnote 3)."""

    packed: FloatArray
    los: FloatArray | None
    degenerate: NDArray[np.bool_]
    far_field: NDArray[np.bool_]

    @property
    def n_sites(self) -> int:
        return int(self.packed.shape[1])

    @property
    def n_pairs(self) -> int:
        return int(self.packed.shape[2])

    @staticmethod
    def concat(parts: list[SiteCache]) -> SiteCache:
        """The sites of several sub-caches of one cache, in order (the inverse of
        :meth:`subset` over consecutive blocks)."""
        return SiteCache(
            np.concatenate([c.packed for c in parts], axis=1),
            parts[0].los,
            np.concatenate([c.degenerate for c in parts]),
            np.concatenate([c.far_field for c in parts]),
        )

    def subset(self, sites: IntArray) -> SiteCache:
        """The cache of the given sites only (ascending indices; a task's site block). Every
        per-site field is sliced here, so a sub-cache scores its layouts exactly as the full
        one does."""
        return SiteCache(
            self.packed[:, sites], self.los, self.degenerate[sites], self.far_field[sites]
        )


def build_site_cache(
    system: SystemParams,
    sites: list[Site],
    pairs: PairSet,
    progress: ProgressCallback = no_progress,
) -> SiteCache:
    """LOS once and every candidate RIS path once, each as packed 7×7 information per pair."""
    radio = fim.Radio.from_system(system)
    g = system.transmissions
    ones = np.ones(g)  # Γ·G̃ = G: with Γ = 1 and G̃ = G the weights sum to the same G
    tx, rx = pairs.tx, pairs.rx
    los = None
    if system.los:
        los = pack(los_path_information(tx, rx, radio, float(g)).state_information())
    packed = np.empty((N_PACKED, len(sites), pairs.size))
    degenerate = np.zeros((len(sites), pairs.size), dtype=bool)
    far = np.zeros((len(sites), pairs.size), dtype=bool)
    for s, site in enumerate(sites):
        bad = ue_on_ris(tx, rx, site.ris.position)
        t, r = stand_ins(tx, rx, bad)  # as compute_bounds: bounds of these pairs become inf
        info, far[s] = ris_path_information(site.ris, t, r, radio, None, 1, ones)
        packed[:, s] = pack(info.state_information())
        degenerate[s] = bad
        far[s] &= ~bad
        progress((s + 1) / len(sites), f"site {s + 1}/{len(sites)}")
    return SiteCache(packed, los, degenerate, far)
