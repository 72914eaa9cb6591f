"""Per-site information cache: each candidate RIS path's 7×7 information on [p_T, p_R, B]
for every pair, computed once (DESIGN.md, performance model).

With the ``expected_random`` codebook a RIS path's equivalent FIM after eliminating its gain
(α, β) by a Schur complement is E[Q]-based with Σ_g δ_g² = Γ·G̃ = G (the core's
:func:`ris_planner.bounds.ris_path_information` weights it by ``block_count * weights.sum()``),
so it does not depend on how many RISs share the time-orthogonal blocks: the cached matrix of a
site is exactly the contribution :func:`ris_planner.bounds.compute_bounds` adds for that RIS in
any layout, and a layout's state FIM is the LOS matrix plus the sum of its sites' matrices.

With an environment (:mod:`ris_planner.planning.visibility`) a site's matrix is zero for the
pairs it cannot serve and the LOS matrix zero where the LOS leg is blocked – adding an exact
zero is removing the path – and ``present`` / ``los_present`` let the scorer count each pair's
geometric channel parameters per layout (DESIGN.md: fewer than the unknown states is ``inf``).
The RIS pattern factor (cos θ_T cos θ_R)^q is in the path gain
(:func:`ris_planner.bounds.ris_path_gain`).
The cache also holds each path's square-root rows (:func:`ris_planner.crb.path_factor`), from
which the scorer recomputes the few ill-conditioned (layout, pair) combinations
(:func:`ris_planner.crb.crb_diagonal`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner import fim
from ris_planner.blas import one_blas_thread
from ris_planner.bounds import (
    los_gradient,
    los_path_information,
    los_referenced,
    ris_path_information,
    stand_ins,
    to_los_reference,
    ue_on_ris,
    uses_los_reference,
)
from ris_planner.ldl import pack
from ris_planner.planning.maps import PairSet
from ris_planner.planning.sites import Site
from ris_planner.planning.visibility import Visibility
from ris_planner.progress import ProgressCallback, no_progress
from ris_planner.scenario import KnownPart, SystemParams, Wavefront

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

N_STATES = 7
N_PACKED = N_STATES * (N_STATES + 1) // 2


@dataclass(frozen=True)
class SiteCache:
    """packed : [28, S, P] packed 7×7 state information of each site's RIS path;
    los : [28, P] the LOS path's (``None`` when the LOS is blocked);
    degenerate : [S, P] a UE within 1 mm of the site (the pair is a blind spot there);
    far_field : [S, P] d_T d_R/(d_T + d_R) ≥ 2D²/λ for the site (footnote 3), or the path
    is absent;
    factor : [S, P, m, 7] square-root rows of each site's RIS path (F_site = factorᵀ factor;
    m = 3 planar, 7 spherical), zero where the path is absent;
    los_factor : [P, 1, 7] the LOS path's (``None`` when the system has no LOS);
    los_referenced : the states are [p_T, p_R, B + d_TR] (:func:`ris_planner.bounds.
    los_referenced`, used with the LOS and an unknown clock, as ``compute_bounds`` does);
    present : [S, P] the site's RIS path exists (``None``: every path does);
    los_present : [P] the LOS path exists (``None``: every pair's does, or no LOS)."""

    packed: FloatArray
    los: FloatArray | None
    degenerate: NDArray[np.bool_]
    far_field: NDArray[np.bool_]
    factor: FloatArray
    los_factor: FloatArray | None
    los_referenced: bool = False
    wavefront: Wavefront = "planar"
    present: NDArray[np.bool_] | None = None
    los_present: NDArray[np.bool_] | None = None

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
        first = parts[0]
        present = None if first.present is None else np.concatenate([c.present for c in parts])
        return SiteCache(
            np.concatenate([c.packed for c in parts], axis=1),
            first.los,
            np.concatenate([c.degenerate for c in parts]),
            np.concatenate([c.far_field for c in parts]),
            np.concatenate([c.factor for c in parts]),
            first.los_factor,
            first.los_referenced,
            first.wavefront,
            present,
            first.los_present,
        )

    def subset(self, sites: IntArray) -> SiteCache:
        """The cache of the given sites only (ascending indices; a task's site block). Every
        per-site field is sliced here, so a sub-cache scores its layouts exactly as the full
        one does."""
        return SiteCache(
            self.packed[:, sites],
            self.los,
            self.degenerate[sites],
            self.far_field[sites],
            self.factor[sites],
            self.los_factor,
            self.los_referenced,
            self.wavefront,
            None if self.present is None else self.present[sites],
            self.los_present,
        )


def mask_absent(packed: FloatArray, present: NDArray[np.bool_]) -> None:
    """Zero the packed information [28, P] of the pairs whose path is absent ([P] mask)."""
    packed[:, ~present] = 0.0


def _present_pairs(
    visibility: Visibility | None, site: int, wavefront: Wavefront
) -> IntArray | None:
    """The pairs a site's path exists for, when some do not (``None``: evaluate every pair).
    The spherical expected Gram takes one product over the distinct UE positions, whose
    blocking depends on how many there are, so it always sees every pair."""
    if visibility is None or wavefront == "spherical":
        return None
    present = visibility.present[site]
    return None if bool(np.all(present)) else np.flatnonzero(present)


def build_site_cache(
    system: SystemParams,
    sites: list[Site],
    pairs: PairSet,
    progress: ProgressCallback = no_progress,
    visibility: Visibility | None = None,
    *,
    known: list[KnownPart] | tuple[KnownPart, ...] = (),
) -> SiteCache:
    """LOS once and every candidate RIS path once, each as packed 7×7 information per pair
    (on the coordinates ``compute_bounds`` uses for ``known``, see :class:`SiteCache`); with
    ``visibility`` absent paths carry zero information. One BLAS thread, as
    ``compute_bounds`` (:mod:`ris_planner.blas`)."""
    with one_blas_thread():
        return _build_site_cache(system, sites, pairs, progress, visibility, known)


def _build_site_cache(
    system: SystemParams,
    sites: list[Site],
    pairs: PairSet,
    progress: ProgressCallback,
    visibility: Visibility | None,
    known: list[KnownPart] | tuple[KnownPart, ...],
) -> SiteCache:
    radio = fim.Radio.from_system(system)
    g = system.transmissions
    ones = np.ones(g)  # Γ·G̃ = G: with Γ = 1 and G̃ = G the weights sum to the same G
    tx, rx = pairs.tx, pairs.rx
    los = los_factor = grad = None
    referenced = uses_los_reference(system.los, known)
    if system.los:
        los_info = los_path_information(tx, rx, radio, float(g))
        grad = los_gradient(los_info).copy()
        los_states = los_referenced([los_info])[0][0] if referenced else los_info
        los, los_factor = pack(los_states.state_information()), los_states.factor()
        if visibility is not None and visibility.los is not None:
            mask_absent(los, visibility.los)
            los_factor[~visibility.los] = 0.0
    packed = np.empty((N_PACKED, len(sites), pairs.size))
    m = 7 if system.wavefront == "spherical" else 3
    factor = np.empty((len(sites), pairs.size, m, N_STATES))
    degenerate = np.zeros((len(sites), pairs.size), dtype=bool)
    far = np.zeros((len(sites), pairs.size), dtype=bool)
    for s, site in enumerate(sites):
        bad = ue_on_ris(tx, rx, site.ris.position)
        t, r = stand_ins(tx, rx, bad)  # as compute_bounds: bounds of these pairs become inf
        # an absent path carries exactly zero information: evaluate the present pairs only
        # (every per-pair quantity is computed pair by pair, so the values are the same)
        sel = _present_pairs(visibility, s, system.wavefront)
        if sel is not None:
            t, r = t[sel], r[sel]
            packed[:, s] = 0.0
            factor[s] = 0.0
            far[s] = True  # an absent path has no near-field issue
        if t.shape[0]:
            # the gain carries the pattern factor (bounds.ris_path_gain), as in compute_bounds
            info, far_s = ris_path_information(
                site.ris, t, r, radio, None, 1, ones, wavefront=system.wavefront
            )
            if referenced:
                assert grad is not None
                info = to_los_reference(info, grad if sel is None else grad[sel])
            if sel is None:
                packed[:, s] = pack(info.state_information())
                factor[s] = info.factor()
                far[s] = far_s
            else:
                packed[:, s, sel] = pack(info.state_information())
                factor[s, sel] = info.factor()
                far[s, sel] = far_s
        if visibility is not None and sel is None and not np.all(visibility.present[s]):
            # (spherical: every pair evaluated, the absent ones zeroed)
            mask_absent(packed[:, s], visibility.present[s])
            factor[s][~visibility.present[s]] = 0.0
            far[s] |= ~visibility.present[s]
        degenerate[s] = bad
        far[s] &= ~bad
        progress((s + 1) / len(sites), f"site {s + 1}/{len(sites)}")
    present = None if visibility is None else visibility.present
    los_present = None if visibility is None else visibility.los
    return SiteCache(
        packed,
        los,
        degenerate,
        far,
        factor,
        los_factor,
        referenced,
        system.wavefront,
        present,
        los_present,
    )
