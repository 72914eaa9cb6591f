"""Sparse information of a district plan: one 7×7 matrix (on the kept states) per (pair,
serving site), the LOS once per pair, and a layout's metric from it (docs/concepts/district.md).

A sidelink pair sees only the few candidates that serve both of its UEs, so the information is
held sparsely (:class:`DistrictProblem`). A layout's metric for pair p sums the LOS and the
matrices of its serving sites in the layout (eq. FIM_measurement, summed over paths) and
inverts once (:func:`ris_planner.inversion.crb.crb_diagonal`, the bounds' hybrid route); a pair
whose present paths give fewer geometric channel parameters than unknown states is ``inf``
(the counting rule of ``compute_bounds``). :class:`LayoutState` keeps one layout's per-pair
information up to date site by site (only the pairs a site serves change);
:class:`SparseScorer` is what a plan's result reads of it
(:class:`~ris_planner.planning.scoring.layout_scorer.LayoutScorer`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import (
    kept_states,
    los_gradient,
    los_path_information,
    n_observations,
    ris_path_gain,
    ris_path_information,
    stand_ins,
    to_los_reference,
    ue_on_ris,
    uses_los_reference,
)
from ris_planner.core.errors import RisPlannerError
from ris_planner.inversion.crb import (
    JIT_MIN_MATRICES,
    Engine,
    crb_diagonal,
    summed_crb_diagonal,
)
from ris_planner.inversion.ldl import pack, packed_slots
from ris_planner.model.objectives.protocol import objective_kind
from ris_planner.model.scenario import RIS
from ris_planner.physics import fim, geometry
from ris_planner.physics.separable import SeparableBlock
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.scoring.site_beams import beams_per_block, design_site
from ris_planner.planning.scoring.visibility import pair_visibility
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class Codebooks:
    """The codebook each site's information was computed with: ``kind`` (``expected_random``
    or a designed one), Γ ``blocks`` (1 for expected_random: its information does not depend on
    Γ), and for designed codebooks each site's beams – the spatial frequencies ξ₀, ζ₀ [S, G̃]
    of its slots, the slots' beam types and powers [G̃] (the same for every site)
    (:mod:`ris_planner.planning.scoring.site_beams`)."""

    kind: str
    blocks: int
    xi: FloatArray
    zeta: FloatArray
    beam_types: IntArray
    powers: FloatArray

    @property
    def designed(self) -> bool:
        return self.kind != "expected_random"


@dataclass(frozen=True)
class DistrictProblem:
    """The sparse information of a plan's pairs and candidate sites.

    entry_pair, entry_site : [E] the (pair, serving site) entries, pair-major; pair_start [P+1]
    their offsets per pair (CSR); info [E, k(k+1)/2] each entry's packed information on the k
    kept states, factor [E, m, k] its square-root rows; los [k(k+1)/2, P] and los_factor
    [P, 1, k] the LOS path's (zero where absent); los_present [P]; weights [P] (sum 1);
    threshold θ [m] of the coverage objective; n_obs_los [P] the LOS path's channel parameters
    (1 or 0); n_kept k; metric "rx", "tx" or "max"; rows_t, rows_r the kept states' indices of
    p_T and p_R; by_site [E] the entries in site order and site_start [S+1] their offsets.
    """

    n_sites: int
    entry_pair: IntArray
    entry_site: IntArray
    pair_start: IntArray
    info: FloatArray
    factor: FloatArray
    los: FloatArray
    los_factor: FloatArray
    los_present: BoolArray
    weights: FloatArray
    threshold: float
    n_kept: int
    counting: bool
    metric: str
    rows_t: IntArray
    rows_r: IntArray
    by_site: IntArray
    site_start: IntArray
    far: BoolArray
    codebooks: Codebooks
    visible: tuple[IntArray, IntArray]
    """(pair, site) of every RIS path that exists (visibility): another RIS size's problem
    starts from them."""
    audible: BoolArray
    """[E] whether the entry's path is audible at its pair (:func:`audible`): profile colours
    separate audible paths only."""

    @property
    def n_pairs(self) -> int:
        return int(self.weights.size)

    @property
    def n_entries(self) -> int:
        return int(self.entry_pair.size)

    def sites_of(self, p: int) -> IntArray:
        return self.entry_site[self.pair_start[p] : self.pair_start[p + 1]]

    def pairs_of(self, site: int) -> IntArray:
        """The pairs ``site`` serves (increasing)."""
        return self.entry_pair[self.by_site[self.site_start[site] : self.site_start[site + 1]]]

    @property
    def metric_rows(self) -> IntArray:
        """The kept states whose CRB diagonal the metric sums (both for ``max``)."""
        if self.metric == "rx":
            return self.rows_r
        if self.metric == "tx":
            return self.rows_t
        return np.union1d(self.rows_t, self.rows_r)

    def strength(self) -> FloatArray:
        """[E] each entry's information on the metric's position: the trace of its metric
        rows' block (the diagonal of the packed information)."""
        slots = packed_slots(self.n_kept)
        diag = [slots[(int(i), int(i))] for i in self.metric_rows]
        return np.asarray(self.info[:, diag].sum(axis=1))

    def strongest(self, per_pair: int) -> DistrictProblem:
        """The same problem with each pair's ``per_pair`` strongest serving sites only
        (:meth:`strength`; all of them where it has no more): what the search sees
        (:data:`SEARCH_SITES`). Itself when no pair has more."""
        n_serving = np.diff(self.pair_start)
        if n_serving.max(initial=0) <= per_pair:
            return self
        key = self.strength()
        # rank of each entry within its pair by decreasing strength (pairs stay contiguous)
        order = np.lexsort((-key, self.entry_pair))
        rank = np.empty(self.n_entries, dtype=np.int64)
        rank[order] = np.arange(self.n_entries) - self.pair_start[self.entry_pair[order]]
        return self.kept(np.flatnonzero(rank < per_pair))

    def audible_only(self) -> DistrictProblem:
        """The same problem with the audible entries only (:data:`AUDIBLE_SNR_DB`): a layout's
        coverage on it counts no RIS path below the noise over the whole pilot
        (docs/concepts/district-physics.md, "Audible paths")."""
        return self.kept(np.flatnonzero(self.audible))

    def kept(self, keep: IntArray) -> DistrictProblem:
        """The same problem with the entries ``keep`` only (ascending: pairs stay
        contiguous)."""
        entry_pair, entry_site = self.entry_pair[keep], self.entry_site[keep]
        by_site = np.argsort(entry_site, kind="stable")
        return replace(
            self,
            entry_pair=entry_pair,
            entry_site=entry_site,
            pair_start=np.searchsorted(entry_pair, np.arange(self.n_pairs + 1)),
            info=self.info[keep],
            factor=self.factor[keep],
            far=self.far[keep],
            audible=self.audible[keep],
            by_site=by_site,
            site_start=np.searchsorted(entry_site[by_site], np.arange(self.n_sites + 1)),
        )


AUDIBLE_SNR_DB = 0.0
"""A RIS path is audible at a pair when its integrated SNR over the whole pilot – K
subcarriers × G transmissions with random phases, P·K·G·N·|ρ|²/σ² – is at least this
(docs/concepts/district-physics.md, "Audible paths"). Two RISs need different profile columns
only where a pair hears both audibly: an inaudible path sharing a column is below the noise
over the whole pilot, and its interference is neglected (its information is counted, as
``compute_bounds`` counts every path; the benchmark measures what it adds)."""


def audible(
    sites: list[Any], pairs: Any, visible: tuple[IntArray, IntArray], system: Any
) -> BoolArray:
    """[V] whether each visible (pair, site) path is audible (:data:`AUDIBLE_SNR_DB`), by its
    gain from the path geometry (:func:`~ris_planner.bounds.compute.ris_path_gain`)."""
    entry_pair, entry_site = visible
    out = np.zeros(entry_pair.size, dtype=bool)
    floor = 10 ** (AUDIBLE_SNR_DB / 10)
    base = system.tx_power_w * system.subcarriers * system.transmissions / system.noise_variance_w
    order = np.argsort(entry_site, kind="stable")
    start = np.searchsorted(entry_site[order], np.arange(len(sites) + 1))
    for s, site in enumerate(sites):
        idx = order[start[s] : start[s + 1]]
        if idx.size == 0:
            continue
        p = entry_pair[idx]
        ris = site.ris
        geo = geometry.ris_path_geometry(pairs.tx[p], pairs.rx[p], ris.position, ris.orientation)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            gain = ris_path_gain(ris, geo, pairs.tx[p], pairs.rx[p], system.wavelength)
            out[idx] = ~(base * ris.elements * gain**2 < floor)  # a UE on the RIS: audible
    return out


def build_problem(
    inputs: PlanInputs,
    progress: ProgressCallback = no_progress,
    like: DistrictProblem | None = None,
    blocks: int = 1,
) -> DistrictProblem:
    """The :class:`DistrictProblem` of a prepared plan: visibility per (map point, site), the
    serving sites of each pair from it, and each entry's information, site by site over that
    site's pairs only, with the document's codebook – ``expected_random`` (whatever Γ), or
    each site's designed block of G/Γ beams for ``blocks`` = Γ time-orthogonal blocks
    (:mod:`ris_planner.planning.scoring.site_beams`). ``like``: a problem of the same sites
    and pairs (another RIS size) whose visibility is taken instead of walked again."""
    doc = inputs.document
    spec = doc.objective
    kind = objective_kind(spec.kind)
    level = kind.screen_level(spec)
    if not kind.higher_is_better or level is None:
        raise RisPlannerError(
            f"search.method 'district' plans a coverage objective (a fraction of pairs within"
            f" a threshold); objective {spec.kind!r} is searched by 'auto', 'exhaustive' or"
            " 'greedy'"
        )
    if inputs.directions != "single":
        raise RisPlannerError(
            "search.method 'district' takes sampled or 'all' pairs; 'unordered' pairs are"
            ' counted in both directions: use "pairs": {"sample": N, "max_separation_m": D}'
        )
    system, pairs, sites = doc.system, inputs.pairs, inputs.sites
    known = tuple(doc.known)
    kept = kept_states(known)
    k = len(kept)
    with one_blas_thread():
        if like is None:
            # per distinct map point and site, then gathered per pair (the site cache's rule)
            vis = pair_visibility(inputs.scene, sites, pairs, system.los)
            heard_pair, heard_site = np.nonzero(vis.present.T)  # pair-major
            visible: tuple[IntArray, IntArray] = (heard_pair, heard_site)
            los_clear_pairs = vis.los
            del vis
        else:
            visible = like.visible
            los_clear_pairs = like.los_present
        progress(0.3, "visibility")
        entry_pair, entry_site = visible
        loud = audible(sites, pairs, visible, system)
        pair_start = np.searchsorted(entry_pair, np.arange(pairs.size + 1))
        radio = fim.Radio.from_system(system)
        g = system.transmissions
        referenced = uses_los_reference(system.los, known)
        los_present = np.zeros(pairs.size, dtype=bool)
        los = np.zeros((k * (k + 1) // 2, pairs.size))
        los_factor = np.zeros((pairs.size, 1, k))
        grad = None
        if system.los:
            assert los_clear_pairs is not None
            los_present = los_clear_pairs
            info = los_path_information(pairs.tx, pairs.rx, radio, float(g))
            grad = los_gradient(info).copy()
            if referenced:
                info = to_los_reference(info, grad)
            st = info.state_information()[:, kept][:, :, kept]
            los = pack(st) * los_present
            los_factor = info.factor()[:, :, kept] * los_present[:, None, None]
        e = entry_pair.size
        packed = np.empty((k * (k + 1) // 2, e))
        spherical = system.wavefront == "spherical"
        # square-root rows per entry: 3 for the planar path (ξ, ζ, cτ), 7 for a spherical one
        factor = np.zeros((e, 7 if spherical else 3, k))
        degenerate = np.zeros(e, dtype=bool)
        far = np.ones(e, dtype=bool)
        by_site = np.argsort(entry_site, kind="stable")
        site_start = np.searchsorted(entry_site[by_site], np.arange(len(sites) + 1))
        ones = np.ones(g)
        cb_spec = doc.codebook
        designed = cb_spec.kind != "expected_random"
        g_tilde = beams_per_block(g, blocks, cb_spec.kind) if designed else g
        beam_xi = np.zeros((len(sites), g_tilde if designed else 0))
        beam_zeta = np.zeros_like(beam_xi)
        types = np.zeros(0, dtype=int)
        powers = ones
        for s, site in enumerate(sites):
            idx = by_site[site_start[s] : site_start[s + 1]]
            if idx.size == 0:
                continue
            p = entry_pair[idx]
            bad = ue_on_ris(pairs.tx[p], pairs.rx[p], site.ris.position)
            t, r = stand_ins(pairs.tx[p], pairs.rx[p], bad)
            block = None
            if designed and np.any(~bad):
                rng = np.random.default_rng([cb_spec.seed or 0, s])
                w = np.where(bad, 0.0, pairs.weights[p])
                beams = design_site(site.ris, t, r, w, cb_spec, g_tilde, radio.wavelength, rng)
                beam_xi[s], beam_zeta[s] = beams.xi, beams.zeta
                types, powers, block = beams.block.beam_types, beams.powers, beams.block
            rows = site_information(
                site.ris,
                t,
                r,
                radio,
                kept,
                None if grad is None or not referenced else grad[p],
                SiteCodebook(block, blocks, powers) if block is not None else None,
                spherical,
            )
            packed[:, idx], factor[idx], far[idx] = rows
            degenerate[idx] = bad
            progress(0.3 + 0.7 * (s + 1) / len(sites), f"information: site {s + 1}/{len(sites)}")
        # a UE on a RIS leaves that pair blind in every layout of the site: no information
        packed[:, degenerate] = 0.0
        factor[degenerate] = 0.0
    rows_t = np.flatnonzero(kept < 3)
    rows_r = np.flatnonzero((kept >= 3) & (kept < 6))
    return DistrictProblem(
        len(sites),
        entry_pair,
        entry_site,
        pair_start,
        np.ascontiguousarray(packed.T),
        factor,
        los,
        los_factor,
        los_present,
        pairs.weights,
        float(level),
        k,
        n_observations(1, False, system.wavefront) is not None,
        spec.metric,
        rows_t,
        rows_r,
        by_site,
        site_start,
        far,
        Codebooks(cb_spec.kind, blocks if designed else 1, beam_xi, beam_zeta, types, powers),
        visible,
        loud,
    )


@dataclass(frozen=True)
class SiteCodebook:
    """A site's designed first block as :func:`site_information` applies it: its factors, Γ
    and the slots' powers."""

    block: SeparableBlock
    blocks: int
    powers: FloatArray


def site_information(
    ris: RIS,
    tx: FloatArray,
    rx: FloatArray,
    radio: fim.Radio,
    kept: IntArray,
    los_grad: FloatArray | None,
    codebook: SiteCodebook | None,
    spherical: bool,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """One site's (packed information [k(k+1)/2, n], square-root rows [n, 3 or 7, k], far-field
    flags [n]) on the kept states for its pairs (tx, rx [n, 3], stand-ins where a UE sits on
    it): the expected-random FIM without ``codebook``, else its designed block's; referred to
    the LOS delay with the pairs' LOS gradients ``los_grad`` when the clock is; with
    ``spherical`` the pairs inside the Fraunhofer distance get the exact per-element response
    (:func:`ris_planner.bounds.compute.ris_path_information`), with a designed block's dense
    profiles [G̃, N] (its planar O(columns + rows) products rest on the far-field
    factorisation)."""
    ones = np.ones(radio.transmissions)  # the expected-random FIM: Σ_g δ_g² = G
    if codebook is None:
        info, far = ris_path_information(ris, tx, rx, radio, None, 1, ones)
    else:
        info, far = ris_path_information(
            ris,
            tx,
            rx,
            radio,
            None,
            codebook.blocks,
            codebook.powers,
            separable=codebook.block,
        )
    if los_grad is not None:
        info = to_los_reference(info, los_grad)
    k = kept.size
    packed = pack(info.state_information()[:, kept][:, :, kept])
    factor = np.zeros((tx.shape[0], 7 if spherical else 3, k))
    factor[:, :3] = info.factor()[:, :, kept]
    near = np.flatnonzero(~far) if spherical else np.zeros(0, dtype=int)
    if near.size:  # inside the Fraunhofer distance: the exact per-element response
        if codebook is None:
            sph, _ = ris_path_information(
                ris, tx[near], rx[near], radio, None, 1, ones, wavefront="spherical"
            )
        else:  # the designed block's dense profiles [G̃, N], element by element
            sph, _ = ris_path_information(
                ris,
                tx[near],
                rx[near],
                radio,
                codebook.block.profiles(),
                codebook.blocks,
                codebook.powers,
                wavefront="spherical",
            )
        if los_grad is not None:
            sph = to_los_reference(sph, los_grad[near])
        packed[:, near] = pack(sph.state_information()[:, kept][:, :, kept])
        factor[near] = sph.factor()[:, :, kept]
    return packed, factor, far


def entry_metric(
    problem: DistrictProblem,
    packed: FloatArray,
    rows: Callable[[IntArray], FloatArray],
    n_obs: IntArray,
) -> FloatArray:
    """The metric (PEB_R, PEB_T or their max) of the information ``packed`` [n, k(k+1)/2];
    ``rows(i)`` the stacked square-root rows of items i (for the few the LDLᵀ does not settle).
    Items whose channel parameters ``n_obs`` [n] are fewer than the states are ``inf`` without
    an inversion (the counting rule)."""
    live = _live(problem, n_obs)
    if live.size == 0:
        return np.full(len(n_obs), np.inf)
    f = np.ascontiguousarray(packed[live].T)
    diag, _ = crb_diagonal(f, problem.n_kept, lambda i: rows(live[i]))
    return _metric_of(problem, diag, live, len(n_obs))


def summed_entry_metric(
    problem: DistrictProblem,
    base: FloatArray,
    base_idx: IntArray,
    entries: IntArray,
    rows: Callable[[IntArray], FloatArray],
    n_obs: IntArray,
) -> FloatArray:
    """:func:`entry_metric` of the information ``base[base_idx[i]] + info[entries[i]]`` (a
    layout's information per pair and one more entry's), without forming the sums
    (:func:`ris_planner.inversion.crb.summed_crb_diagonal`: the same bits)."""
    live = _live(problem, n_obs)
    if live.size == 0:
        return np.full(len(n_obs), np.inf)
    # a district's steps are many small batches: compiled from the problem's size on, not
    # the batch's (crb.JIT_MIN_MATRICES)
    engine: Engine = "numba" if problem.n_entries >= JIT_MIN_MATRICES else "auto"
    diag, _ = summed_crb_diagonal(
        base,
        problem.info,
        base_idx[live],
        entries[live],
        problem.n_kept,
        lambda i: rows(live[i]),
        engine,
    )
    return _metric_of(problem, diag, live, len(n_obs))


def _live(problem: DistrictProblem, n_obs: IntArray) -> IntArray:
    """The items the counting rule leaves to invert (all of them without it)."""
    return np.flatnonzero(n_obs >= problem.n_kept) if problem.counting else np.arange(len(n_obs))


def _metric_of(problem: DistrictProblem, diag: FloatArray, live: IntArray, n: int) -> FloatArray:
    """[n] the metric from the CRB diagonal [k, len(live)] of the live items (``inf`` for the
    others and where undefined)."""
    metric = np.full(n, np.inf)
    with np.errstate(invalid="ignore", over="ignore"):
        peb_r = np.sqrt(diag[problem.rows_r].sum(axis=0))
        peb_t = np.sqrt(diag[problem.rows_t].sum(axis=0)) if problem.rows_t.size else peb_r
    m = {"rx": peb_r, "tx": peb_t, "max": np.maximum(peb_r, peb_t)}[problem.metric]
    metric[live] = np.where(np.isnan(m), np.inf, m)
    return metric


def pair_entries(problem: DistrictProblem, pairs: IntArray) -> tuple[IntArray, IntArray]:
    """(item, entry) of every entry of the given pairs: item i is ``pairs[i]``."""
    lo = problem.pair_start[pairs]
    n = problem.pair_start[pairs + 1] - lo
    item = np.repeat(np.arange(len(pairs)), n)
    first = np.repeat(lo - (np.cumsum(n) - n), n)
    return item, first + np.arange(int(n.sum()))


def _sum_by_item(
    info: FloatArray, item: IntArray, entry: IntArray, per_item: IntArray
) -> FloatArray:
    """[n, K] Σ info[entry] per item, each item's entries added one after another in entry
    order (``item`` sorted, ``per_item`` its counts): the n-th entries of all items in one
    vectorised step, so the sums are those of a sequential loop (and of a sparse gather)."""
    out = np.zeros((per_item.size, info.shape[1]))
    if item.size == 0:
        return out
    rank = _rank_in_item(item, per_item.size)
    order = np.argsort(rank, kind="stable")
    size = np.bincount(rank)
    ends = np.cumsum(size)
    for lo, hi in zip(ends - size, ends, strict=True):
        at = order[lo:hi]
        out[item[at]] += info[entry[at]]
    return out


def _rank_in_item(item: IntArray, n: int) -> IntArray:
    """The rank of each entry within its item (``item`` sorted, items 0..n−1)."""
    return np.arange(item.size) - np.searchsorted(item, np.arange(n))[item]


class LayoutState:
    """A layout's per-pair information, channel-parameter count and metric, updated site by
    site (only the pairs a site serves change)."""

    def __init__(self, problem: DistrictProblem, sites: list[int] | tuple[int, ...] = ()) -> None:
        self.problem = problem
        self.member = np.zeros(problem.n_sites, dtype=bool)
        self.member[list(sites)] = True
        self.info = problem.los.T.copy()  # [P, k(k+1)/2]
        self.count = problem.los_present.astype(int)  # channel parameters
        self.metric = np.full(problem.n_pairs, np.inf)
        self._refresh(np.arange(problem.n_pairs))

    def rows(self, pairs: IntArray, extra: IntArray | None = None) -> FloatArray:
        """[n, 1 + 3·w, k] square-root rows of the given pairs' layouts (plus the entry
        ``extra[i]`` for item i): the LOS rows, then each layout site's rows, zero rows
        padding the items with fewer sites (a zero row adds no information)."""
        pr = self.problem
        item, entry = pair_entries(pr, pairs)
        keep = self.member[pr.entry_site[entry]]
        if extra is not None:
            keep |= entry == extra[item]
        item, entry = item[keep], entry[keep]
        rank = _rank_in_item(item, len(pairs))  # items are contiguous and increasing
        width = int(rank.max(initial=-1)) + 1
        f = np.zeros((len(pairs), width, pr.factor.shape[1], pr.n_kept))
        f[item, rank] = pr.factor[entry]
        return np.concatenate([pr.los_factor[pairs], f.reshape(len(pairs), -1, pr.n_kept)], 1)

    def _refresh(self, pairs: IntArray) -> None:
        pr = self.problem
        item, entry = pair_entries(pr, pairs)
        keep = self.member[pr.entry_site[entry]]
        item, entry = item[keep], entry[keep]
        per_item = np.bincount(item, minlength=len(pairs))
        info = pr.los.T[pairs] + _sum_by_item(pr.info, item, entry, per_item)
        count = pr.los_present[pairs] + 3 * per_item
        self.info[pairs] = info
        self.count[pairs] = count
        self.metric[pairs] = entry_metric(pr, info, lambda i: self.rows(pairs[i]), count)

    def set(self, site: int, member: bool) -> IntArray:
        """Put ``site`` in the layout or take it out; the pairs it serves (whose metric
        changed)."""
        self.member[site] = member
        pairs = self.problem.pairs_of(site)
        self._refresh(pairs)
        return pairs

    def coverage(self) -> float:
        return float(self.problem.weights[self.metric <= self.problem.threshold].sum())


def exact_coverage(problem: DistrictProblem, layout: tuple[int, ...] | list[int]) -> float:
    """A layout's coverage with every serving site's information (the search may see only the
    strongest: :data:`SEARCH_SITES`)."""
    return LayoutState(problem, list(layout)).coverage()


def servable_pairs(problem: DistrictProblem) -> BoolArray:
    """[P] the pairs some layout can serve: with every candidate in place their paths give
    at least as many channel parameters as unknown states (the planar counting rule; the
    spherical model: a finite bound with every candidate). Whatever the RIS size."""
    if problem.counting:
        n_obs = problem.los_present + 3 * np.diff(problem.pair_start)
        return np.asarray(n_obs >= problem.n_kept)
    full = LayoutState(problem, list(range(problem.n_sites)))
    return np.asarray(np.isfinite(full.metric))


@dataclass(frozen=True)
class SparseScorer:
    """What a district plan's result reads of its scoring
    (:class:`~ris_planner.planning.scoring.layout_scorer.LayoutScorer`): a layout's metric per
    pair, its far-field flags, the sites that serve no pair, the storage."""

    problem: DistrictProblem
    mirror: bool = False

    @property
    def metric_weights(self) -> FloatArray:
        return self.problem.weights

    def exact_metric(self, layouts: IntArray) -> FloatArray:
        """[B, P] the metric of each layout [B, L] with every serving site's information."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int64))
        out = np.empty((layouts.shape[0], self.problem.n_pairs))
        for b, lay in enumerate(layouts):
            out[b] = LayoutState(self.problem, [int(s) for s in lay]).metric
        return out

    def far_field_of(self, layout: Sequence[int]) -> BoolArray:
        """[P] whether every site of ``layout`` that serves the pair has it in its far field."""
        pr = self.problem
        member = np.zeros(pr.n_sites, dtype=bool)
        member[list(layout)] = True
        near = member[pr.entry_site] & ~pr.far
        out = np.ones(pr.n_pairs, dtype=bool)
        out[pr.entry_pair[near]] = False
        return out

    def near_field_by_site(self, weights: FloatArray) -> FloatArray:
        """[S] per site the weight of the pairs it serves in its near field."""
        pr = self.problem
        near = ~pr.far
        w = weights[pr.entry_pair[near]]
        return np.asarray(np.bincount(pr.entry_site[near], w, minlength=pr.n_sites), float)

    def serves(self, layout: Sequence[int]) -> BoolArray:
        """[L, P] whether each site of ``layout`` serves each pair (has an entry)."""
        pr = self.problem
        out = np.zeros((len(layout), pr.n_pairs), dtype=bool)
        for j, s in enumerate(layout):
            out[j, pr.pairs_of(int(s))] = True
        return out

    def idle_sites(self) -> IntArray:
        """The sites that serve no pair."""
        return np.flatnonzero(np.diff(self.problem.site_start) == 0)

    def servable(self) -> BoolArray:
        """[P] :func:`servable_pairs`."""
        return servable_pairs(self.problem)

    def storage_json(self) -> dict[str, Any]:
        pr = self.problem
        return {
            "storage": "sparse",
            "entries": pr.n_entries,
            "rows_stored": True,
            "bytes": int(pr.info.nbytes + pr.factor.nbytes),
        }


def layout_information(
    problem: DistrictProblem,
    inputs: PlanInputs,
    blocks: dict[int, SeparableBlock],
    gamma: int,
    powers: FloatArray,
) -> DistrictProblem:
    """``problem`` restricted to the entries of the sites in ``blocks``, their information
    computed anew with each site's block at the slot powers ``powers`` [G̃] in ``gamma`` = Γ
    blocks (:func:`site_information`): a layout scored with other beams or powers than the
    search's (the power allocation of its beams). A layout's metric needs only its own sites'
    entries and the LOS."""
    doc = inputs.document
    pairs = inputs.pairs
    radio = fim.Radio.from_system(doc.system)
    kept = kept_states(tuple(doc.known))
    grad = None
    if doc.system.los and uses_los_reference(True, tuple(doc.known)):
        grad = los_gradient(los_path_information(pairs.tx, pairs.rx, radio, radio.transmissions))
    keep = np.flatnonzero(np.isin(problem.entry_site, list(blocks)))
    info = problem.info[keep].copy()
    factor = problem.factor[keep].copy()
    for site, block in blocks.items():
        mine = np.flatnonzero(problem.entry_site[keep] == site)
        p = problem.entry_pair[keep[mine]]
        ris = inputs.sites[site].ris
        bad = ue_on_ris(pairs.tx[p], pairs.rx[p], ris.position)
        t, r = stand_ins(pairs.tx[p], pairs.rx[p], bad)
        packed, rows, _ = site_information(
            ris,
            t,
            r,
            radio,
            kept,
            None if grad is None else grad[p],
            SiteCodebook(block, gamma, powers),
            factor.shape[1] == 7,
        )
        packed[:, bad] = 0.0
        rows[bad] = 0.0
        info[mine] = packed.T
        factor[mine] = rows
    entry_pair, entry_site = problem.entry_pair[keep], problem.entry_site[keep]
    by_site = np.argsort(entry_site, kind="stable")
    return replace(
        problem,
        entry_pair=entry_pair,
        entry_site=entry_site,
        pair_start=np.searchsorted(entry_pair, np.arange(problem.n_pairs + 1)),
        info=info,
        factor=factor,
        by_site=by_site,
        site_start=np.searchsorted(entry_site[by_site], np.arange(problem.n_sites + 1)),
        far=problem.far[keep],
        audible=problem.audible[keep],
    )
