"""Per-site information cache: each candidate RIS path's 7×7 information on [p_T, p_R, B]
for every pair, computed once (docs/concepts/scoring.md).

With the ``expected_random`` codebook a RIS path's equivalent FIM after eliminating its gain
(α, β) by a Schur complement is E[Q]-based with Σ_g δ_g² = Γ·G̃ = G (the core's
:func:`ris_planner.bounds.compute.ris_path_information` weights it by ``block_count *
weights.sum()``),
so it does not depend on how many RISs share the time-orthogonal blocks: the cached matrix of a
site is exactly the contribution :func:`ris_planner.bounds.compute.compute_bounds` adds for that
RIS in
any layout, and a layout's state FIM is the LOS matrix plus the sum of its sites' matrices.

With an environment (:mod:`ris_planner.planning.scoring.visibility`) a site's matrix is zero for the
pairs it cannot serve and the LOS matrix zero where the LOS leg is blocked – adding an exact
zero is removing the path – and ``present`` / ``los_present`` let the scorer count each pair's
geometric channel parameters per layout (concepts/numerics.md: fewer than the states is ``inf``).
The RIS pattern factor (cos θ_T cos θ_R)^q is in the path gain
(:func:`ris_planner.bounds.compute.ris_path_gain`).
Storage (the memory budget): the site information is held once, in the pair blocks the compiled
scorer reads (no per-process re-layout). The square-root rows (:func:`ris_planner.inversion.crb.
path_factor`) from which the scorer recomputes the few ill-conditioned (layout, pair)
combinations (:func:`ris_planner.inversion.crb.crb_diagonal`) are stored while they fit the cache
budget
(:func:`ris_planner.model.limits.cache_layout`); above it :class:`SiteSource` recomputes them for
just
those pairs (planar), with the same bits, and further above the blocks are float32, whose
finalists the plan re-scores exactly on a float64 cache of just their sites.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import (
    los_gradient,
    los_path_information,
    los_referenced,
    ris_path_information,
    stand_ins,
    to_los_reference,
    ue_on_ris,
    uses_los_reference,
)
from ris_planner.inversion.ldl import pack
from ris_planner.model.limits import CacheLayout
from ris_planner.model.scenario import KnownPart, SystemParams, Wavefront
from ris_planner.physics import fim
from ris_planner.planning.inputs.sites import Site
from ris_planner.planning.inputs.ue_maps import PairSet
from ris_planner.planning.scoring.visibility import Visibility
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

N_STATES = 7
N_PACKED = N_STATES * (N_STATES + 1) // 2

FULL = CacheLayout("float64", rows=True)
"""The default layout: float64 blocks and the square-root rows stored."""


CHUNK = 64
"""Pairs per storage block (the compiled kernel's chunk,
:data:`ris_planner.inversion._crb_jit.CHUNK`)."""

Storage = Literal["float64", "float32"]


def n_blocks(n_pairs: int) -> int:
    """Pair blocks ⌈P / CHUNK⌉ of the storage."""
    return -(-n_pairs // CHUNK)


def to_block_layout(packed: FloatArray) -> FloatArray:
    """[E, P] packed entries of one site → [⌈P/CHUNK⌉, E, CHUNK] (zeros past P)."""
    e_n, p = packed.shape
    out = np.zeros((e_n, n_blocks(p) * CHUNK), dtype=packed.dtype)
    out[:, :p] = packed
    return np.ascontiguousarray(out.reshape(e_n, -1, CHUNK).transpose(1, 0, 2))


@dataclass(frozen=True)
class SiteSource:
    """The inputs a cache was built from, to recompute parts of it in float64: a planar site's
    square-root rows for chosen pairs (instead of storing 21 float64 per site-pair that only
    the few ill-conditioned combinations read), and the exact float64 cache of a few sites
    (:meth:`rebuild`, the finalists of a float32 cache). Both are the same calls as the build
    on fewer pairs or sites, so they give the same bits: every per-pair quantity is computed
    pair by pair and every site on its own (tested).

    grad : [P, 6] the LOS gradient when the cache is LOS-referenced, else ``None``."""

    system: SystemParams
    sites: tuple[Site, ...]
    pairs: PairSet
    known: tuple[KnownPart, ...]
    visibility: Visibility | None
    grad: FloatArray | None

    def rows(self, site: int, pairs: IntArray) -> FloatArray:
        """[len(pairs), 3, 7] square-root rows of one site's planar RIS path (zero where the
        path is absent), as :func:`build_site_cache` computes them."""
        ris = self.sites[site].ris
        t, r = self.pairs.tx[pairs], self.pairs.rx[pairs]
        t, r = stand_ins(t, r, ue_on_ris(t, r, ris.position))
        radio = fim.Radio.from_system(self.system)
        ones = np.ones(self.system.transmissions)
        info, _ = ris_path_information(ris, t, r, radio, None, 1, ones, wavefront="planar")
        if self.grad is not None:
            info = to_los_reference(info, self.grad[pairs])
        out = info.factor()
        if self.visibility is not None:
            out[~self.visibility.present[site, pairs]] = 0.0
        return out

    def subset(self, sites: IntArray) -> SiteSource:
        """The source of the given sites only (as :meth:`SiteCache.subset`)."""
        vis = self.visibility
        if vis is not None:
            vis = Visibility(vis.present[sites], vis.los)
        return replace(self, sites=tuple(self.sites[int(s)] for s in sites), visibility=vis)

    def rebuild(self, sites: IntArray) -> SiteCache:
        """The float64 cache of the given sites (ascending), built as the full one was."""
        sub = self.subset(sites)
        return build_site_cache(
            self.system, list(sub.sites), self.pairs, visibility=sub.visibility, known=self.known
        )


@dataclass(frozen=True)
class SiteCache:
    """blocks : [⌈P/CHUNK⌉, S, 28, CHUNK] packed 7×7 state information of each site's RIS
    path, in the pair blocks the compiled scorer reads (:func:`ris_planner.inversion._crb_jit.
    score_layouts`: one block holds every site's entries of CHUNK pairs contiguously; zeros
    past P), float64 or float32 (:data:`storage`); the only copy (:meth:`information` gives
    float64 slices in the [E, S, P] layout);
    los : [28, P] the LOS path's (``None`` when the LOS is blocked);
    degenerate : [S, P] a UE within 1 mm of the site (the pair is a blind spot there);
    far_field : [S, P] d_T d_R/(d_T + d_R) ≥ 2D²/λ for the site (footnote 3), or the path
    is absent;
    factor : [S, P, m, 7] square-root rows of each site's RIS path (F_site = factorᵀ factor;
    m = 3 planar, 7 spherical), zero where the path is absent; always stored for the
    spherical wavefront (its expected Gram takes a product over all UE positions, so a subset
    of pairs would not give the same bits); ``None``: planar above the budget's first tier,
    :attr:`source` recomputes them (:meth:`factor_rows`);
    los_factor : [P, 1, 7] the LOS path's (``None`` when the system has no LOS);
    los_referenced : the states are [p_T, p_R, B + d_TR] (:func:`ris_planner.bounds.compute.
    los_referenced`, used with the LOS and an unknown clock, as ``compute_bounds`` does);
    present : [S, P] the site's RIS path exists (``None``: every path does);
    los_present : [P] the LOS path exists (``None``: every pair's does, or no LOS)."""

    blocks: NDArray[np.floating]
    n_pairs: int
    los: FloatArray | None
    degenerate: NDArray[np.bool_]
    far_field: NDArray[np.bool_]
    factor: FloatArray | None
    source: SiteSource
    los_factor: FloatArray | None
    los_referenced: bool = False
    wavefront: Wavefront = "planar"
    present: NDArray[np.bool_] | None = None
    los_present: NDArray[np.bool_] | None = None

    @property
    def n_sites(self) -> int:
        return int(self.blocks.shape[1])

    @property
    def nbytes(self) -> int:
        """Bytes of the block storage and the stored rows."""
        return int(self.blocks.nbytes + (0 if self.factor is None else self.factor.nbytes))

    @property
    def storage(self) -> Storage:
        """The storage precision of :attr:`blocks`."""
        return "float32" if self.blocks.dtype == np.float32 else "float64"

    def information(
        self,
        entries: IntArray | None = None,
        sites: IntArray | None = None,
        pairs: slice = slice(None),
    ) -> FloatArray:
        """[E, F, b] float64 packed entries (all 28 by default) of the sites (all by default)
        on a contiguous run of pairs – a copy in the layout of the numpy readers
        (certificates, branch-and-bound, site strengths)."""
        p0, p1, _ = pairs.indices(self.n_pairs)
        c0, c1 = p0 // CHUNK, n_blocks(p1)
        blk = self.blocks[c0:c1]
        if sites is not None:
            blk = blk[:, sites]
        if entries is not None:
            blk = blk[:, :, entries]
        n_c, n_s, e_n, _ = blk.shape
        out = np.ascontiguousarray(blk.transpose(2, 1, 0, 3), dtype=np.float64)
        flat = out.reshape(e_n, n_s, n_c * CHUNK)
        return flat[:, :, p0 - c0 * CHUNK : p1 - c0 * CHUNK]

    @property
    def packed(self) -> FloatArray:
        """[28, S, P] float64 copy of every site's packed information (:meth:`information`)."""
        return self.information()

    def factor_rows(self, sites: IntArray, pairs: IntArray) -> FloatArray:
        """[N, m, 7] square-root rows of site sites[i] on pair pairs[i] (stored or recomputed
        by :attr:`source`, one call per distinct site)."""
        if self.factor is not None:
            return self.factor[sites, pairs]
        key = sites.astype(np.int64) * self.n_pairs + pairs
        uniq, inverse = np.unique(key, return_inverse=True)
        u_site, u_pair = np.divmod(uniq, self.n_pairs)
        rows = np.empty((uniq.size, 3, N_STATES))
        bounds = np.flatnonzero(np.diff(u_site)) + 1
        for run in np.split(np.arange(uniq.size), bounds):
            if run.size:
                rows[run] = self.source.rows(int(u_site[run[0]]), u_pair[run])
        return rows[inverse.reshape(-1)]

    @staticmethod
    def concat(parts: list[SiteCache], picks: list[IntArray] | None = None) -> SiteCache:
        """The sites of several sub-caches of one cache, in order (the inverse of
        :meth:`subset` over consecutive blocks); with ``picks``, only those sites of each part
        (ascending local indices). The block storage is written once, a site at a time (no
        gathered temporary: a cluster task's ~70 sites × 50 000 pairs are ~400 MB)."""
        chosen = picks if picks is not None else [np.arange(c.n_sites) for c in parts]
        kept = [(c, k) for c, k in zip(parts, chosen, strict=True) if k.size]
        first = kept[0][0]
        n_c, _, e_n, width = first.blocks.shape
        blocks = np.empty((n_c, sum(k.size for _, k in kept), e_n, width), first.blocks.dtype)
        j = 0
        for c, k in kept:
            for site in k:
                blocks[:, j] = c.blocks[:, site]
                j += 1

        def cat(field: str) -> Any:
            return np.concatenate([getattr(c, field)[k] for c, k in kept])

        present = None if first.present is None else cat("present")
        vis = first.source.visibility
        if vis is not None:  # the cache's masks are the visibility's
            assert present is not None
            vis = Visibility(present, vis.los)
        sites = tuple(c.source.sites[int(i)] for c, k in kept for i in k)
        return SiteCache(
            blocks,
            first.n_pairs,
            first.los,
            cat("degenerate"),
            cat("far_field"),
            None if first.factor is None else cat("factor"),
            replace(first.source, sites=sites, visibility=vis),
            first.los_factor,
            first.los_referenced,
            first.wavefront,
            present,
            first.los_present,
        )

    @property
    def counts_paths(self) -> bool:
        """Whether a pair's present paths must be counted (``objectives.underdetermined``):
        some RIS or LOS path is absent somewhere (planar; the spherical model has no counting
        rule). Where every path exists the layout-wide count says the same."""
        if self.present is None or self.wavefront == "spherical":
            return False
        los_all = self.los_present is None or bool(np.all(self.los_present))
        return not (los_all and bool(np.all(self.present)))

    def subset(self, sites: IntArray) -> SiteCache:
        """The cache of the given sites only (ascending indices; a task's site block). Every
        per-site field is sliced here, so a sub-cache scores its layouts exactly as the full
        one does."""
        return SiteCache(
            np.ascontiguousarray(self.blocks[:, sites]),
            self.n_pairs,
            self.los,
            self.degenerate[sites],
            self.far_field[sites],
            None if self.factor is None else self.factor[sites],
            self.source.subset(sites),
            self.los_factor,
            self.los_referenced,
            self.wavefront,
            None if self.present is None else self.present[sites],
            self.los_present,
        )


@dataclass(frozen=True)
class KeptInformation:
    """The site information on the kept states (entries ``src`` of the packed 28, in
    :func:`ris_planner.inversion.ldl.packed_index` order) as the numpy readers take it – the sites'
    [E, F, P] or a run of pairs of many sites – read from the block storage as float64 when
    asked (a full [E, S, P] float64 copy would double the cache)."""

    cache: SiteCache
    src: IntArray

    @property
    def shape(self) -> tuple[int, int, int]:
        """(E, S, P)."""
        return int(self.src.size), self.cache.n_sites, self.cache.n_pairs

    def sites(self, idx: IntArray | list[int]) -> FloatArray:
        """[E, len(idx), P] of the given sites."""
        return self.cache.information(self.src, np.asarray(idx, dtype=np.int64))

    def slab(self, sites: IntArray, p0: int, p1: int) -> FloatArray:
        """[E, len(sites), p1 − p0] of the given sites on pairs p0 … p1 − 1."""
        return self.cache.information(self.src, sites, slice(p0, p1))


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
    layout: CacheLayout = FULL,
) -> SiteCache:
    """LOS once and every candidate RIS path once, each as packed 7×7 information per pair
    (on the coordinates ``compute_bounds`` uses for ``known``, see :class:`SiteCache`); with
    ``visibility`` absent paths carry zero information. ``layout`` : the precision of the
    stored site information (float32 halves it; the values are float64 rounded once, the
    LOS stays float64) and whether the square-root rows are stored (planar; spherical ones
    always are). One BLAS thread, as ``compute_bounds``
    (:mod:`ris_planner.runtime.blas`)."""
    with one_blas_thread():
        return _build_site_cache(system, sites, pairs, progress, visibility, known, layout)


def _build_site_cache(
    system: SystemParams,
    sites: list[Site],
    pairs: PairSet,
    progress: ProgressCallback,
    visibility: Visibility | None,
    known: list[KnownPart] | tuple[KnownPart, ...],
    layout: CacheLayout,
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
    spherical = system.wavefront == "spherical"
    blocks = np.empty((n_blocks(pairs.size), len(sites), N_PACKED, CHUNK), dtype=layout.storage)
    m = N_STATES if spherical else 3
    keep_rows = spherical or layout.rows
    factor = np.empty((len(sites), pairs.size, m, N_STATES)) if keep_rows else None
    degenerate = np.zeros((len(sites), pairs.size), dtype=bool)
    far = np.zeros((len(sites), pairs.size), dtype=bool)
    packed = np.empty((N_PACKED, pairs.size))  # one site's, reused
    for s, site in enumerate(sites):
        bad = ue_on_ris(tx, rx, site.ris.position)
        t, r = stand_ins(tx, rx, bad)  # as compute_bounds: bounds of these pairs become inf
        # an absent path carries exactly zero information: evaluate the present pairs only
        # (every per-pair quantity is computed pair by pair, so the values are the same)
        sel = _present_pairs(visibility, s, system.wavefront)
        if sel is not None:
            t, r = t[sel], r[sel]
            packed[:] = 0.0
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
                packed[:] = pack(info.state_information())
                far[s] = far_s
            else:
                packed[:, sel] = pack(info.state_information())
                far[s, sel] = far_s
            if factor is not None and sel is None:
                factor[s] = info.factor()
            elif factor is not None:
                factor[s] = 0.0
                factor[s, sel] = info.factor()
        elif factor is not None:
            factor[s] = 0.0
        if visibility is not None and sel is None and not np.all(visibility.present[s]):
            # (spherical: every pair evaluated, the absent ones zeroed)
            mask_absent(packed, visibility.present[s])
            if factor is not None:
                factor[s][~visibility.present[s]] = 0.0
            far[s] |= ~visibility.present[s]
        blocks[:, s] = to_block_layout(packed)
        degenerate[s] = bad
        far[s] &= ~bad
        progress((s + 1) / len(sites), f"site {s + 1}/{len(sites)}")
    present = None if visibility is None else visibility.present
    los_present = None if visibility is None else visibility.los
    source = SiteSource(
        system, tuple(sites), pairs, tuple(known), visibility, grad if referenced else None
    )
    return SiteCache(
        blocks,
        pairs.size,
        los,
        degenerate,
        far,
        factor,
        source,
        los_factor,
        referenced,
        system.wavefront,
        present,
        los_present,
    )
