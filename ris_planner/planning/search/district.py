"""District-scale placement: tens of RISs from hundreds or thousands of candidates, by locality
(docs/concepts/district.md).

A sidelink pair sees only the few candidates that serve both of its UEs, so the information is
held sparsely: one 7×7 matrix (on the kept states) per (pair, serving site), LOS once per pair
(:class:`DistrictProblem`). A layout's metric for pair p sums the LOS and the matrices of its
serving sites in the layout (eq. FIM_measurement, summed over paths) and inverts once
(:func:`ris_planner.inversion.crb.crb_diagonal`, the bounds' hybrid route); a pair whose present
paths give fewer geometric channel parameters than unknown states is ``inf`` (the counting
rule of ``compute_bounds``).

* **Search** (:func:`greedy_path`): forward selection on coverage, each step the site with the
  largest gain in covered weight, ties (and the first steps, where no single site covers a
  pair) broken by a surrogate that rewards progress towards a finite, then a small bound. Adding
  a site changes only its own pairs, so only the entries of those pairs are evaluated again
  (incremental scoring: one batched inversion over a handful of matrices per step), then a
  swap pass (:func:`improve`) on the true coverage.
* **Certificate** (:func:`coverage_upper_bound`): a pair covered by a layout C needs at least
  m_p of its serving sites in C (m_p from the counting rule and, where few enough, from every
  m-subset of its sites: :func:`sites_needed`), and none when even all its sites leave it above
  the threshold. So with z_s = 1[s ∈ C], y_p = 1[p covered]: y_p ≤ Σ_{s∈S_p} z_s / m_p and
  Σ z = L. The linear relaxation (0 ≤ y, z ≤ 1, HiGHS) bounds the best coverage of any L-site
  layout from above; the gap is that bound minus the coverage found.
* **Sizing** (:func:`size_district`): the smallest count whose greedy path reaches the target,
  and a certified lower bound on every count that could (the relaxation's smallest Σ z with
  Σ w_p y_p ≥ target, rounded up).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog
from scipy.sparse import csr_matrix, vstack

from ris_planner.bounds.compute import (
    kept_states,
    los_gradient,
    los_path_information,
    n_observations,
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
from ris_planner.model.plan import MAX_DISTRICT_RIS
from ris_planner.physics import fim
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.scoring.visibility import pair_visibility
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

MAX_SUBSETS = 4096
"""Per pair, the most m-subsets of its serving sites evaluated (:func:`sites_needed`): all
pairs of up to 91 serving sites; a pair with more keeps the counting rule's m_p and no cover
sets (still valid, looser)."""

MAX_SUBSET_EVALUATIONS = 2_000_000
"""In all, the most (pair, m-subset) combinations :func:`sites_needed` evaluates (about 2 µs
each): the pairs with the fewest subsets first; the others keep the counting rule's m_p and no
cover sets (still valid, looser). Forty serving sites per pair and m = 2 over 20 000 pairs
would otherwise be 15.6 million evaluations."""

SUBSET_BATCH = 200_000
"""(pair, subset) combinations evaluated per batch by :func:`sites_needed` (memory: about
300 bytes each)."""

SURROGATE_FINITE = 0.5
"""Surrogate of a pair with a finite bound above the threshold θ: 0.5 + 0.5·θ/bound ∈ (0.5, 1);
an ``inf`` pair scores 0.5 · (its channel parameters / unknown states) < 0.5, a covered pair 1."""

LP_PAD = 1e-7
"""HiGHS' primal feasibility tolerance: the coverage bound is padded by it and the sizing
target lowered by it, so a relaxation solved to that tolerance still bounds."""

GAIN_TIE = 1e-12
"""Covered-weight gains within this of the best are equal; the surrogate decides among them."""

LOOKAHEAD = 8
"""First sites of a greedy step tried with their best partner (:meth:`GainBook.best_step`)."""

LOOKAHEAD_ALL = 64
"""Up to this many candidates a greedy step tries every site as the first of a pair."""

PAIR_SWAP_TRIALS = 512
"""The swap pass also exchanges two layout sites for the best pair while that takes at most
this many first-site trials (small layouts; a district's tens of RISs skip it)."""

LOOKAHEAD_BELOW = 2.5
"""A greedy step tries pairs of sites only while the best single site covers less than this
many pairs' weight (the heaviest pair's): while coverage needs sites placed together."""

SMALL_DISTRICT_SITES = 500
"""Up to this many candidates each count's layout is also searched from the relaxation's own
layout (:func:`rounded_layout`) and swapped for up to three rounds; above it, one round of
swaps from the greedy layout (each round re-scores every pair of every layout site: on
thousands of candidates the rounds, not the greedy path, would hold most of the time)."""

SEARCH_SITES = 96
"""Per pair, the serving sites the search sees (:meth:`DistrictProblem.strongest`): the
strongest by their information on the metric's position. Coverage only rises with more
information, so a layout's coverage seen by the search is a lower bound on its exact coverage,
which every reported layout gets (:func:`exact_coverage`); the certificate uses every site."""


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
        keep = np.flatnonzero(rank < per_pair)
        entry_pair, entry_site = self.entry_pair[keep], self.entry_site[keep]
        by_site = np.argsort(entry_site, kind="stable")
        return replace(
            self,
            entry_pair=entry_pair,
            entry_site=entry_site,
            pair_start=np.searchsorted(entry_pair, np.arange(self.n_pairs + 1)),
            info=self.info[keep],
            factor=self.factor[keep],
            by_site=by_site,
            site_start=np.searchsorted(entry_site[by_site], np.arange(self.n_sites + 1)),
        )


def build_problem(
    inputs: PlanInputs,
    progress: ProgressCallback = no_progress,
    like: DistrictProblem | None = None,
) -> DistrictProblem:
    """The :class:`DistrictProblem` of a prepared plan: visibility per (map point, site), the
    serving sites of each pair from it, and each entry's information, site by site over that
    site's pairs only. ``like``: a problem of the same sites and pairs (another RIS size)
    whose visibility is taken instead of walked again."""
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
            entry_pair, entry_site = np.nonzero(vis.present.T)  # pair-major
            los_clear_pairs = vis.los
            del vis
        else:
            entry_pair, entry_site = like.entry_pair, like.entry_site
            los_clear_pairs = like.los_present
        progress(0.3, "visibility")
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
        factor = np.empty((e, 3, k))
        degenerate = np.zeros(e, dtype=bool)
        by_site = np.argsort(entry_site, kind="stable")
        site_start = np.searchsorted(entry_site[by_site], np.arange(len(sites) + 1))
        ones = np.ones(g)
        for s, site in enumerate(sites):
            idx = by_site[site_start[s] : site_start[s + 1]]
            if idx.size == 0:
                continue
            p = entry_pair[idx]
            bad = ue_on_ris(pairs.tx[p], pairs.rx[p], site.ris.position)
            t, r = stand_ins(pairs.tx[p], pairs.rx[p], bad)
            info, _ = ris_path_information(
                site.ris, t, r, radio, None, 1, ones, wavefront=system.wavefront
            )
            if referenced:
                assert grad is not None
                info = to_los_reference(info, grad[p])
            st = info.state_information()[:, kept][:, :, kept]
            packed[:, idx] = pack(st)
            f = info.factor()[:, :, kept]
            if f.shape[1] != 3:
                raise RisPlannerError("search.method 'district' needs the planar wavefront")
            factor[idx] = f
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
    )


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


def _pair_entries(problem: DistrictProblem, pairs: IntArray) -> tuple[IntArray, IntArray]:
    """(item, entry) of every entry of the given pairs: item i is ``pairs[i]``."""
    lo = problem.pair_start[pairs]
    n = problem.pair_start[pairs + 1] - lo
    item = np.repeat(np.arange(len(pairs)), n)
    first = np.repeat(lo - (np.cumsum(n) - n), n)
    return item, first + np.arange(int(n.sum()))


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
        item, entry = _pair_entries(pr, pairs)
        keep = self.member[pr.entry_site[entry]]
        if extra is not None:
            keep |= entry == extra[item]
        item, entry = item[keep], entry[keep]
        # the rank of each kept entry within its item (items are contiguous and increasing)
        start = np.searchsorted(item, np.arange(len(pairs)))
        rank = np.arange(item.size) - start[item]
        width = int(rank.max(initial=-1)) + 1
        f = np.zeros((len(pairs), width, 3, pr.n_kept))
        f[item, rank] = pr.factor[entry]
        return np.concatenate([pr.los_factor[pairs], f.reshape(len(pairs), -1, pr.n_kept)], 1)

    def _refresh(self, pairs: IntArray) -> None:
        pr = self.problem
        item, entry = _pair_entries(pr, pairs)
        keep = self.member[pr.entry_site[entry]]
        item, entry = item[keep], entry[keep]
        gather = csr_matrix((np.ones(entry.size), (item, entry)), shape=(len(pairs), pr.n_entries))
        info = pr.los.T[pairs] + gather @ pr.info
        count = pr.los_present[pairs] + 3 * np.bincount(item, minlength=len(pairs))
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

    def entry_gains(self, entries: IntArray) -> tuple[FloatArray, FloatArray]:
        """(covered-weight gain, surrogate gain) [len(entries)] of adding each entry's site to
        its pair, the rest of the layout as it is (0 for a site already in it, and for a pair
        already covered: more information never raises its bound)."""
        pr = self.problem
        cov = np.zeros(len(entries))
        sur = np.zeros(len(entries))
        thr, k = pr.threshold, pr.n_kept
        open_ = np.flatnonzero(
            (self.metric[pr.entry_pair[entries]] > thr) & ~self.member[pr.entry_site[entries]]
        )
        e = entries[open_]
        p = pr.entry_pair[e]
        count = self.count[p] + 3
        new = summed_entry_metric(pr, self.info, p, e, lambda i: self.rows(p[i], e[i]), count)
        old = self.metric[p]
        w = pr.weights[p]
        cov[open_] = w * (new <= thr)
        sur[open_] = w * (surrogate(new, count, thr, k) - surrogate(old, self.count[p], thr, k))
        return cov, sur


def exact_coverage(problem: DistrictProblem, layout: tuple[int, ...] | list[int]) -> float:
    """A layout's coverage with every serving site's information (the search may see only the
    strongest: :data:`SEARCH_SITES`)."""
    return LayoutState(problem, list(layout)).coverage()


class GainBook:
    """Every entry's gain (:meth:`LayoutState.entry_gains`) and their sums per site, kept up
    to date by re-evaluating only the entries of the pairs whose layout changed."""

    def __init__(self, state: LayoutState) -> None:
        self.state = state
        pr = state.problem
        every = np.arange(pr.n_entries)
        self.cov, self.sur = state.entry_gains(every)
        self.gain_c = _site_sums(pr, every, self.cov)
        self.gain_s = _site_sums(pr, every, self.sur)
        self.floor = LOOKAHEAD_BELOW * float(pr.weights.max(initial=0.0))

    def set(self, site: int, member: bool) -> None:
        """Change the layout (:meth:`LayoutState.set`) and the gains it changes."""
        pr = self.state.problem
        changed = self.state.set(site, member)
        _, entries = _pair_entries(pr, changed)
        self.gain_c -= _site_sums(pr, entries, self.cov[entries])
        self.gain_s -= _site_sums(pr, entries, self.sur[entries])
        self.cov[entries], self.sur[entries] = self.state.entry_gains(entries)
        self.gain_c += _site_sums(pr, entries, self.cov[entries])
        self.gain_s += _site_sums(pr, entries, self.sur[entries])

    def best(self, allowed: BoolArray) -> int:
        """The allowed site with the largest covered-weight gain; ties by the surrogate, then
        the lower index."""
        gc = np.where(allowed, self.gain_c, -np.inf)
        tied = allowed & (self.gain_c >= gc.max() - GAIN_TIE)
        return int(np.flatnonzero(tied)[np.argmax(self.gain_s[tied])])

    def best_pair(
        self, allowed: BoolArray, conflict: BoolArray | None, width: int
    ) -> tuple[list[int], float]:
        """The best two sites to add together and their covered-weight gain: each of the
        ``width`` allowed sites with the largest gains (then surrogates) as the first, with its
        best partner given it. A trial changes only the first site's pairs, so it re-evaluates
        only their entries, and is undone after."""
        best: list[int] = []
        best_gain = -np.inf
        key = np.where(allowed, self.gain_c + GAIN_TIE * self.gain_s, -np.inf)
        firsts = np.argsort(-key, kind="stable")[:width]
        for s1 in firsts[np.isfinite(key[firsts])].tolist():
            base = self.state.coverage()
            self.set(s1, True)
            rest = allowed.copy()
            rest[s1] = False
            if conflict is not None:
                rest &= ~conflict[s1]
            if np.any(rest):
                s2 = self.best(rest)
                gain = self.state.coverage() - base + float(self.gain_c[s2])
                if gain > best_gain + GAIN_TIE:
                    best_gain, best = gain, [int(s1), s2]
            self.set(s1, False)
        return best, best_gain

    def best_step(self, allowed: BoolArray, conflict: BoolArray | None, width: int) -> list[int]:
        """The next one or two sites: the best single site (:meth:`best`), or – when that
        covers less than :data:`LOOKAHEAD_BELOW` pairs and a pair of sites does better per
        site – the best pair (:meth:`best_pair`: coverage that needs two sites at once, which
        no single site's gain shows)."""
        one = self.best(allowed)
        if float(self.gain_c[one]) > self.floor:
            return [one]  # a single site covers enough: no pair of sites is tried
        two, gain = self.best_pair(allowed, conflict, width)
        return two if two and gain / 2 > float(self.gain_c[one]) + GAIN_TIE else [one]


def surrogate(metric: FloatArray, count: IntArray, threshold: float, n_kept: int) -> FloatArray:
    """Per pair: 1 covered, 0.5 + 0.5·θ/bound finite above θ, else 0.5·min(1, count/k)
    (:data:`SURROGATE_FINITE`)."""
    with np.errstate(divide="ignore"):
        finite = SURROGATE_FINITE + (1 - SURROGATE_FINITE) * threshold / metric
    blind = SURROGATE_FINITE * np.minimum(1.0, count / n_kept)
    return np.where(metric <= threshold, 1.0, np.where(np.isfinite(metric), finite, blind))


def _site_sums(problem: DistrictProblem, entries: IntArray, values: FloatArray) -> FloatArray:
    sums = np.bincount(problem.entry_site[entries], weights=values, minlength=problem.n_sites)
    return np.asarray(sums, dtype=np.float64)


@dataclass(frozen=True)
class PathStep:
    """One step of the greedy path: the layout after it and its coverage."""

    sites: tuple[int, ...]
    coverage: float


def greedy_path(
    problem: DistrictProblem,
    max_count: int,
    target: float | None = None,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    progress: ProgressCallback = no_progress,
    min_count: int = 0,
    conflict: BoolArray | None = None,
    lookahead: int = LOOKAHEAD,
) -> list[PathStep]:
    """Forward selection up to ``max_count`` sites (or, from ``min_count`` sites on, until
    coverage ≥ ``target``): each step adds the site with the largest covered-weight gain, ties
    by the surrogate gain, then by the lower site index – or two sites at once where a pair of
    them gains more per site (:meth:`GainBook.best_step`, ``lookahead`` first sites tried).
    ``conflict`` [S, S]: sites that may not be chosen together (one mounting point). Only the
    entries of the pairs an added site serves are evaluated again."""
    book = GainBook(LayoutState(problem, list(required)))
    allowed = np.ones(problem.n_sites, dtype=bool)
    allowed[list(excluded)] = False
    allowed[list(required)] = False
    for r in required:
        if conflict is not None:
            allowed &= ~conflict[r]
    layout = list(required)
    path = [PathStep(tuple(sorted(layout)), book.state.coverage())] if layout else []
    while len(layout) < max_count and np.any(allowed):
        if target is not None and path and path[-1].coverage >= target and len(layout) >= min_count:
            break
        width = problem.n_sites if problem.n_sites <= LOOKAHEAD_ALL else lookahead
        step = book.best_step(allowed, conflict, width)
        if len(step) == 1 and not (book.gain_c[step[0]] > GAIN_TIE or book.gain_s[step[0]] > 0):
            break  # no site adds information to any pair
        for s in step[: max_count - len(layout)]:
            book.set(s, True)
            layout.append(s)
            allowed[s] = False
            if conflict is not None:
                allowed &= ~conflict[s]
            path.append(PathStep(tuple(sorted(layout)), book.state.coverage()))
        progress(
            len(layout) / max_count, f"path: {len(layout)} RISs, coverage {path[-1].coverage:.3f}"
        )
    return path


def improve(
    problem: DistrictProblem,
    layout: tuple[int, ...],
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    max_rounds: int = 3,
    conflict: BoolArray | None = None,
) -> tuple[tuple[int, ...], float]:
    """First-improvement swaps on the true coverage: each site of the layout (not required) is
    taken out and the best site for its place put in (none in ``conflict`` with the rest of
    the layout), kept when the coverage rises."""
    book = GainBook(LayoutState(problem, list(layout)))
    state = book.state
    best = state.coverage()
    fixed = set(required)
    banned = np.zeros(problem.n_sites, dtype=bool)
    banned[list(excluded)] = True
    for _ in range(max_rounds):
        better = False
        for out in sorted(set(np.flatnonzero(state.member).tolist()) - fixed):
            book.set(out, False)
            base = state.coverage()
            gain = book.gain_c.copy()
            gain[state.member | banned] = -np.inf
            gain[out] = -np.inf
            if conflict is not None:
                gain[conflict[:, state.member].any(axis=1)] = -np.inf
            s = int(np.argmax(gain))
            if np.isfinite(gain[s]) and base + gain[s] > best + GAIN_TIE:
                book.set(s, True)
                best = state.coverage()
                better = True
            else:
                book.set(out, True)
        if not better and not _pair_swaps(book, fixed, banned, conflict, best):
            break
        best = state.coverage()
    return tuple(int(s) for s in np.flatnonzero(state.member)), best


def _pair_swaps(
    book: GainBook, fixed: set[int], banned: BoolArray, conflict: BoolArray | None, best: float
) -> bool:
    """Two sites of the layout out and the best pair in (:meth:`GainBook.best_pair`), for at
    most :data:`PAIR_SWAP_TRIALS` first-site trials in all; the first swap that raises the
    coverage is kept. Whether one was."""
    state = book.state
    problem = state.problem
    width = problem.n_sites if problem.n_sites <= LOOKAHEAD_ALL else LOOKAHEAD
    members = sorted(set(np.flatnonzero(state.member).tolist()) - fixed)
    outs = list(itertools.combinations(members, 2))
    if len(outs) * width > PAIR_SWAP_TRIALS:
        return False
    for a, b in outs:
        book.set(a, False)
        book.set(b, False)
        allowed = ~(state.member | banned)
        allowed[[a, b]] = False
        if conflict is not None:
            allowed &= ~conflict[:, state.member].any(axis=1)
        two, gain = book.best_pair(allowed, conflict, width)
        if two and state.coverage() + gain > best + GAIN_TIE:
            book.set(two[0], True)
            book.set(two[1], True)
            return True
        book.set(a, True)
        book.set(b, True)
    return False


@dataclass(frozen=True)
class Needs:
    """What covering a pair takes (:func:`sites_needed`).

    need [P]: a lower bound m_p on the serving sites a layout needs for pair p to be covered
    (0: never covered); complete [P]: every m_p-subset of the pair's sites was tried and some
    covers it; cover_pair, cover_site [U]: for the complete pairs, each site that belongs to a
    covering m_p-subset (the union of the pair's cover sets), as (pair, site) in pair order."""

    need: IntArray
    complete: BoolArray
    cover_pair: IntArray
    cover_site: IntArray


def sites_needed(problem: DistrictProblem) -> Needs:
    """m_p and the cover sets' sites (:class:`Needs`).

    The counting rule gives m ≥ ⌈(k − LOS)/3⌉. Where a pair has at most :data:`MAX_SUBSETS`
    m-subsets they are all evaluated (in batches of at most :data:`SUBSET_BATCH`): the sites
    of the covering ones are recorded, and when none covers, m_p is raised by one and the
    (m+1)-subsets are tried the same way (a larger layout contains some m-subset, and adding
    information never raises a bound, so needing more than m is exact). At most
    :data:`MAX_SUBSET_EVALUATIONS` (pair, subset) combinations are evaluated in all, the pairs
    with the fewest subsets first. A pair that even all its serving sites leave above the
    threshold has m_p = 0."""
    pr = problem
    n_serving = np.diff(pr.pair_start)
    full = LayoutState(pr, list(range(pr.n_sites)))
    coverable = full.metric <= pr.threshold
    need = np.maximum(1, -(-(pr.n_kept - pr.los_present.astype(int)) // 3))
    if not pr.counting:
        need = np.ones(pr.n_pairs, dtype=int)
    need = np.where(coverable, need, 0)
    complete = np.zeros(pr.n_pairs, dtype=bool)
    used = np.zeros(pr.n_entries, dtype=bool)  # entries in some covering m_p-subset
    budget = MAX_SUBSET_EVALUATIONS
    for _ in range(2):  # m, then m + 1 for the pairs no m-subset covers
        tried = np.zeros(pr.n_pairs, dtype=bool)
        found = np.zeros(pr.n_pairs, dtype=bool)
        # the pairs with the fewest subsets first, within the budget left
        open_ = np.flatnonzero(coverable & ~complete & (need <= n_serving))
        n_subsets = np.array(
            [math.comb(int(n), int(m)) for n, m in zip(n_serving[open_], need[open_], strict=True)],
            dtype=float,
        )
        order = np.argsort(n_subsets, kind="stable")
        within = np.cumsum(n_subsets[order]) <= budget
        chosen = np.zeros(pr.n_pairs, dtype=bool)
        chosen[open_[order[within]]] = True
        chosen[open_[n_subsets > MAX_SUBSETS]] = False
        budget -= int(n_subsets[chosen[open_]].sum())
        for n in np.unique(n_serving[chosen]):
            for m in np.unique(need[chosen & (n_serving == n)]):
                group = np.flatnonzero(chosen & (n_serving == n) & (need == m))
                subsets = np.array(list(itertools.combinations(range(int(n)), int(m))))
                step = max(1, SUBSET_BATCH // len(subsets))
                for g0 in range(0, group.size, step):
                    part = group[g0 : g0 + step]
                    covers = _covering_subsets(pr, part, subsets)  # [G, C]
                    tried[part] = True
                    found[part] = covers.any(axis=1)
                    g, c = np.nonzero(covers)
                    used[pr.pair_start[part[g]][:, None] + subsets[c]] = True
        complete |= tried & found
        need = np.where(tried & ~found, need + 1, need)
    used &= complete[pr.entry_pair]
    return Needs(np.asarray(need), complete, pr.entry_pair[used], pr.entry_site[used])


def _covering_subsets(problem: DistrictProblem, group: IntArray, subsets: IntArray) -> BoolArray:
    """[G, C] whether each subset [C, m] (positions among a pair's serving sites) of each
    pair of the group covers it."""
    pr = problem
    m = subsets.shape[1]
    # [G, C, m] entries of every subset of every pair of the group
    entries = pr.pair_start[group][:, None, None] + subsets[None]
    info = pr.los.T[group][:, None] + pr.info[entries].sum(axis=2)
    flat_p = np.repeat(group, len(subsets))
    flat_e = entries.reshape(-1, m)
    count = pr.los_present[flat_p].astype(int) + 3 * m

    def rows(i: IntArray) -> FloatArray:
        f = pr.factor[flat_e[i]].reshape(len(i), -1, pr.n_kept)
        return np.concatenate([pr.los_factor[flat_p[i]], f], axis=1)

    metric = entry_metric(pr, info.reshape(-1, info.shape[-1]), rows, count)
    return np.asarray((metric <= pr.threshold).reshape(len(group), -1))


def _relaxation(problem: DistrictProblem, needs: Needs) -> tuple[csr_matrix, int, IntArray]:
    """The relaxation's constraints A v ≤ 0 over v = [z (S), y (live pairs), u (complete
    pairs)], the number of variables, and the live pairs (m_p > 0):

    * every live pair: y_p ≤ Σ_{s∈S_p} z_s / m_p (a covering layout holds m_p of its sites);
    * a pair with cover sets also: y_p ≤ Σ_{s∈U_p} z_s / m_p + u_p with U_p the sites of its
      covering m_p-subsets, and u_p ≤ Σ_{s∈S_p} z_s / (m_p + 1): a covering layout holds a
      covering m_p-subset (m_p sites of U_p) or at least m_p + 1 of its serving sites."""
    pr, need = problem, needs.need
    live = np.flatnonzero(need > 0)
    y_of = np.full(pr.n_pairs, -1)
    y_of[live] = pr.n_sites + np.arange(live.size)
    comp = np.flatnonzero(needs.complete & (need > 0))
    u_of = np.full(pr.n_pairs, -1)
    u_of[comp] = pr.n_sites + live.size + np.arange(comp.size)
    n_var = pr.n_sites + live.size + comp.size
    open_ = np.setdiff1d(live, comp)
    # rows: the open pairs' y, the complete pairs' y, the complete pairs' u
    row_y = np.full(pr.n_pairs, -1)
    row_y[open_] = np.arange(open_.size)
    row_y[comp] = open_.size + np.arange(comp.size)
    row_u = np.full(pr.n_pairs, -1)
    row_u[comp] = open_.size + comp.size + np.arange(comp.size)
    e_open = np.flatnonzero(np.isin(pr.entry_pair, open_))
    e_comp = np.flatnonzero(np.isin(pr.entry_pair, comp))
    rows = np.concatenate(
        [
            row_y[live],
            row_y[pr.entry_pair[e_open]],
            row_y[needs.cover_pair],
            row_y[comp],
            row_u[comp],
            row_u[pr.entry_pair[e_comp]],
        ]
    )
    cols = np.concatenate(
        [
            y_of[live],
            pr.entry_site[e_open],
            needs.cover_site,
            u_of[comp],
            u_of[comp],
            pr.entry_site[e_comp],
        ]
    )
    vals = np.concatenate(
        [
            np.ones(live.size),
            -1.0 / need[pr.entry_pair[e_open]],
            -1.0 / need[needs.cover_pair],
            -np.ones(comp.size),
            np.ones(comp.size),
            -1.0 / (need[pr.entry_pair[e_comp]] + 1),
        ]
    )
    n_rows = open_.size + 2 * comp.size
    # a complete pair's counting row too: a covering layout holds m_p of its sites (the cover
    # form alone is looser where the cover sets' sites are most of the pair's)
    row_c = np.full(pr.n_pairs, -1)
    row_c[comp] = n_rows + np.arange(comp.size)
    rows = np.concatenate([rows, row_c[comp], row_c[pr.entry_pair[e_comp]]])
    cols = np.concatenate([cols, y_of[comp], pr.entry_site[e_comp]])
    vals = np.concatenate([vals, np.ones(comp.size), -1.0 / need[pr.entry_pair[e_comp]]])
    n_rows += comp.size
    return csr_matrix((vals, (rows, cols)), shape=(n_rows, n_var)), n_var, live


def _bounds(
    problem: DistrictProblem, n_var: int, fixed: tuple[int, ...], excluded: tuple[int, ...]
) -> list[tuple[float, float]]:
    z = [(0.0, 1.0)] * problem.n_sites
    for s in fixed:
        z[s] = (1.0, 1.0)
    for s in excluded:
        z[s] = (0.0, 0.0)
    return z + [(0.0, 1.0)] * (n_var - problem.n_sites)


def _objective_y(problem: DistrictProblem, n_var: int, live: IntArray) -> FloatArray:
    """The vector w·y over the relaxation's variables (the live pairs' weights on y)."""
    c = np.zeros(n_var)
    c[problem.n_sites : problem.n_sites + live.size] = problem.weights[live]
    return c


def coverage_upper_bound(
    problem: DistrictProblem,
    count: int,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """An upper bound on the coverage of every layout of ``count`` sites (the relaxation of
    :func:`_relaxation`; ``needs`` from :func:`sites_needed`)."""
    return relaxed_coverage(problem, count, needs, required, excluded)[0]


def relaxed_coverage(
    problem: DistrictProblem,
    count: int,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> tuple[float, FloatArray]:
    """(:func:`coverage_upper_bound`, the relaxation's site weights z [S])."""
    a, n_var, live = _relaxation(problem, needs)
    if live.size == 0:
        return 0.0, np.zeros(problem.n_sites)
    eq = np.zeros(n_var)
    eq[: problem.n_sites] = 1.0
    res = linprog(
        -_objective_y(problem, n_var, live),
        A_ub=a,
        b_ub=np.zeros(a.shape[0]),
        A_eq=csr_matrix(eq[None]),
        b_eq=[float(count)],
        bounds=_bounds(problem, n_var, required, excluded),
        method="highs",
    )
    if res.status != 0:
        raise RisPlannerError(f"coverage relaxation failed: {res.message}")
    # HiGHS' optimum to its feasibility tolerance: pad by it so the bound stays a bound
    return float(min(1.0, -res.fun + LP_PAD)), np.asarray(res.x[: problem.n_sites])


def rounded_layout(
    z: FloatArray,
    count: int,
    required: tuple[int, ...],
    excluded: tuple[int, ...],
    conflict: BoolArray | None,
) -> tuple[int, ...]:
    """The relaxation's layout: the required sites, then the sites of largest z that conflict
    with none taken, up to ``count`` (fewer when the allowed sites run out)."""
    taken = list(required)
    banned = np.zeros(z.size, dtype=bool)
    banned[list(excluded)] = True
    banned[taken] = True
    for r in taken:
        if conflict is not None:
            banned |= conflict[r]
    for s in np.argsort(-z, kind="stable").tolist():
        if len(taken) >= count:
            break
        if banned[s]:
            continue
        taken.append(s)
        banned[s] = True
        if conflict is not None:
            banned |= conflict[s]
    return tuple(sorted(taken))


def count_lower_bound(
    problem: DistrictProblem,
    target: float,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> int | None:
    """The fewest sites any layout reaching coverage ``target`` can have (relaxation: the
    smallest Σ z with Σ w_p y_p ≥ target, rounded up); ``None`` when no layout reaches it
    (the pairs some layout covers weigh less than the target: known before any LP)."""
    if float(problem.weights[needs.need > 0].sum()) < target - 1e-12:
        return None
    a, n_var, live = _relaxation(problem, needs)
    c = np.zeros(n_var)
    c[: problem.n_sites] = 1.0
    cover = -_objective_y(problem, n_var, live)
    res = linprog(
        c,
        A_ub=vstack([a, csr_matrix(cover[None])]).tocsr(),
        b_ub=np.concatenate([np.zeros(a.shape[0]), [-(target - LP_PAD)]]),
        bounds=_bounds(problem, n_var, required, excluded),
        method="highs",
    )
    if res.status != 0:
        return None
    return max(len(required), math.ceil(res.fun - 1e-6))


def servable_pairs(problem: DistrictProblem) -> BoolArray:
    """[P] the pairs some layout can serve: with every candidate in place their paths give
    at least as many channel parameters as unknown states (the planar counting rule; the
    spherical model: a finite bound with every candidate). Whatever the RIS size."""
    if problem.counting:
        n_obs = problem.los_present + 3 * np.diff(problem.pair_start)
        return np.asarray(n_obs >= problem.n_kept)
    full = LayoutState(problem, list(range(problem.n_sites)))
    return np.asarray(np.isfinite(full.metric))


def summary(problem: DistrictProblem, needs: Needs) -> dict[str, Any]:
    """What the site can give at all: the pairs no candidate layout can serve (too few paths
    with every candidate: blind whatever the layout), those every candidate together still
    leaves blind numerically or above the threshold, and the coverable weight."""
    need = needs.need
    served = servable_pairs(problem)
    blind = ~served
    w = problem.weights
    short = (need == 0) & served
    return {
        "pairs": problem.n_pairs,
        "blind_everywhere": {"pairs": int(blind.sum()), "weight": float(w[blind].sum())},
        "above_threshold_everywhere": {"pairs": int(short.sum()), "weight": float(w[short].sum())},
        "coverable_weight": float(w[need > 0].sum()),
        "entries": problem.n_entries,
        "serving_sites_per_pair": float(np.diff(problem.pair_start).mean()),
        "pairs_with_cover_sets": int(needs.complete.sum()),
    }


def plan_district(inputs: PlanInputs, progress: ProgressCallback = no_progress) -> dict[str, Any]:
    """plan.json of a district plan (docs/concepts/district.md): per RIS count the layout of the
    greedy path improved by swaps, its coverage, the certified upper bound on any layout of that
    count and the gap; with ``sizing`` (or ``mode: target``) the smallest count whose layout
    reaches the target over the pairs some layout can cover, and the certified lower bound on
    that count."""
    doc = inputs.document
    feas = inputs.feasibility
    required = tuple(int(s) for s in feas.required)
    excluded = tuple(int(s) for s in np.flatnonzero(~feas.allowed))
    if feas.budget is not None:
        raise RisPlannerError(
            "search.method 'district' takes required, excluded and conflicting sites (spacing,"
            " one mounting point); a cost budget needs 'auto', 'exhaustive' or 'greedy'"
        )
    conflict = feas.conflict if feas.conflict.any() else None
    progress(0.0, "information")
    problem = build_problem(inputs, lambda f, m: progress(0.4 * f, m))
    search = problem.strongest(SEARCH_SITES)
    needs = sites_needed(problem)
    site_summary = summary(problem, needs)
    coverable = site_summary["coverable_weight"]
    target = _target(doc)
    counts = [c for c in inputs.counts if c <= problem.n_sites]
    # target mode: the counts up to the first that covers the target share of the coverable
    goal = target * coverable if target is not None and doc.target_mode else None
    servable = float(problem.weights[servable_pairs(problem)].sum())
    sizing_goal = target * servable if target is not None and doc.sizing is not None else None
    if goal is None and sizing_goal is not None:
        goal = sizing_goal  # the sizing question at the document's size: the same path
    # the relaxations run on a thread beside the search (HiGHS releases the GIL): their
    # layouts are needed only to start small problems' swaps
    lp = ThreadPoolExecutor(max_workers=1, thread_name_prefix="district-relaxation")
    try:
        relaxed = {
            c: lp.submit(relaxed_coverage, problem, c, needs, required, excluded) for c in counts
        }
        own_lower = (
            None
            if sizing_goal is None
            else lp.submit(count_lower_bound, problem, sizing_goal, needs, required, excluded)
        )
        # the sizing's other RIS sizes: their information now, their lower bounds queued
        # behind the relaxations, so the thread beside never waits for the search
        others = {
            size: _other_size(inputs, size, problem, sizing_goal, (required, excluded), lp)
            for size in doc.sizing_ris_sizes()
            if sizing_goal is not None and size != (doc.ris.rows, doc.ris.cols)
        }
        progress(0.5, "greedy path")
        longest = max(counts) if goal is None else max(max(counts), most_ris(doc))
        path = greedy_path(
            search,
            min(longest, problem.n_sites),
            goal,
            required,
            excluded,
            min_count=max(counts),
            conflict=conflict,
        )
        progress(0.7, "swaps")
        by_count = []
        names = [s.name for s in inputs.sites]
        small = problem.n_sites <= SMALL_DISTRICT_SITES
        rounds = 3 if small else 1
        for c in counts:
            step = next((p for p in path if len(p.sites) == c), None)
            if step is None:
                continue  # the path stopped: no site adds information
            layout, cov = improve(search, step.sites, required, excluded, rounds, conflict)
            ub, z = relaxed[c].result()
            rounded = rounded_layout(z, c, required, excluded, conflict)
            if small and len(rounded) == c:  # the relaxation's own layout, improved likewise
                other, other_cov = improve(search, rounded, required, excluded, rounds, conflict)
                if other_cov > cov + GAIN_TIE:
                    layout, cov = other, other_cov
            if search is not problem:
                cov = exact_coverage(problem, layout)
            by_count.append(
                {
                    "ris_count": c,
                    "sites": [names[s] for s in layout],
                    "site_indices": list(layout),
                    "objective": cov,
                    "objective_of_coverable": cov / coverable if coverable > 0 else None,
                    "upper_bound": max(ub, cov),
                    "gap": max(0.0, ub - cov),
                    "method": "district",
                }
            )
            if doc.target_mode and goal is not None and cov >= goal:
                break  # target mode: the smallest count that reaches the target
        progress(0.9, "certificate")
        plan: dict[str, Any] = {
            "method": "district",
            "objective": doc.objective.model_dump(exclude_none=True),
            "pairs_summary": site_summary,
            "by_count": by_count,
            "path": [{"ris_count": len(p.sites), "coverage": p.coverage} for p in path],
            "search_sites_per_pair": SEARCH_SITES,
        }
        if target is not None:
            plan["sizing"] = _sizing(
                inputs,
                (problem, search),
                needs,
                path,
                target,
                (required, excluded, conflict),
                progress,
                None if own_lower is None else own_lower.result,
                others,
            )
    finally:
        lp.shutdown(wait=False, cancel_futures=True)
    progress(1.0, "done")
    return plan


def most_ris(doc: Any) -> int:
    """The most RISs a target or sizing path may place: :data:`MAX_DISTRICT_RIS`, and one fewer
    than the pilot transmissions (a layout of L RISs needs L + 1 time-orthogonal
    transmissions)."""
    return int(min(MAX_DISTRICT_RIS, doc.system.transmissions - 1))


def _target(doc: Any) -> float | None:
    """The coverage to reach, as a fraction of the pairs some layout can cover: the sizing
    question's target (:meth:`PlanDocument.sizing_target`) with ``sizing``, else
    ``objective.target``; ``None`` without either."""
    target = doc.sizing_target() if doc.sizing is not None else doc.objective.target
    return None if target is None or target.min is None else float(target.min)


def _sizing(
    inputs: PlanInputs,
    problems: tuple[DistrictProblem, DistrictProblem],
    needs: Needs,
    path: list[PathStep],
    target: float,
    constraints: tuple[tuple[int, ...], tuple[int, ...], BoolArray | None],
    progress: ProgressCallback,
    own_lower: Callable[[], int | None] | None = None,
    others: dict[tuple[int, int], OtherSize] | None = None,
) -> dict[str, Any]:
    """The smallest RIS size × count whose greedy layout covers ``target`` of the servable
    pairs (those some layout gives a finite bound), over the document's RIS size and
    ``sizing.ris_sizes`` in ascending element count, each with the relaxation's lower bound on
    the count; a size whose lower bound already needs more elements than the answer so far is
    skipped, and one that cannot reach the target with every candidate says so. ``problems``:
    the document's size's problem and what its search sees (:meth:`DistrictProblem.strongest`);
    ``own_lower``: its lower bound when already under way; ``others``: the other sizes'
    information and lower bounds already under way (:func:`_other_size`), else each is built
    here."""
    problem, search = problems
    required, excluded, conflict = constraints
    doc = inputs.document
    servable = float(problem.weights[servable_pairs(problem)].sum())
    goal = target * servable
    own_size = (doc.ris.rows, doc.ris.cols)
    ladder = doc.sizing_ris_sizes()
    rows: list[dict[str, Any]] = []
    answer: dict[str, Any] | None = None
    for k, (r, c) in enumerate(sorted(ladder, key=lambda rc: (rc[0] * rc[1], rc))):
        progress(0.9 + 0.1 * k / len(ladder), f"sizing: {r}×{c}")
        lower_of: Callable[[], int | None] | None = None
        if (r, c) == own_size:
            pr, seen, nd, steps = problem, search, needs, path
            lower_of = own_lower  # solved beside the search
        else:
            other = (others or {}).get((r, c)) or _other_size(
                inputs, (r, c), problem, goal, (required, excluded), None
            )
            pr, seen, nd, lower_of, steps = other.problem, other.seen, other.needs, other.lower, []
        row: dict[str, Any] = {"ris_size": [r, c]}
        if lower_of is not None:
            lower = lower_of()
        else:
            lower = count_lower_bound(pr, goal, nd, required, excluded)
        row["lower_bound"] = lower
        if lower is None:
            row["count"] = None
            row["note"] = "not reachable: every candidate together covers less"
            rows.append(row)
            continue
        if answer is not None and lower * r * c >= answer["elements"]:
            row["count"] = None
            row["note"] = f"skipped: at least {lower} RISs, not fewer elements than the answer"
            rows.append(row)
            continue
        if not steps or steps[-1].coverage < goal:
            steps = greedy_path(
                seen,
                min(most_ris(doc), pr.n_sites),
                goal,
                required,
                excluded,
                conflict=conflict,
            )
        # the search's coverage is a lower bound on the exact one
        found = next((p for p in steps if p.coverage >= goal - 1e-12), None)
        row["count"] = None if found is None else len(found.sites)
        if found is None:
            row["note"] = f"the greedy path stops at {len(steps)} RISs below the target"
        else:
            row["coverage"] = exact_coverage(pr, found.sites) if seen is not pr else found.coverage
            row["gap"] = len(found.sites) - lower
            elements = r * c * len(found.sites)
            if answer is None or elements < answer["elements"]:
                answer = {"ris_size": [r, c], "count": len(found.sites), "elements": elements}
                answer.update(lower_bound=lower, gap=len(found.sites) - lower)
        rows.append(row)
    out: dict[str, Any] = {
        "target": target,
        "of": "servable pairs",
        "servable_weight": servable,
        "sizes": rows,
        "method": "district",
    }
    if answer is None:
        out.update(ris_size=None, count=None, lower_bound=None, gap=None)
        out["message"] = (
            f"no RIS size of the ladder reaches {target:g} × the servable {servable:.3f}"
            " with the district search (each size's reason in 'sizes')"
        )
    else:
        out.update(answer)
        out["message"] = (
            f"{answer['count']} RISs of {answer['ris_size'][0]}×{answer['ris_size'][1]} reach"
            f" {target:g} × the servable {servable:.3f}; no layout of that size with fewer than"
            f" {answer['lower_bound']} RISs can (gap {answer['gap']} RISs)"
        )
    return out


@dataclass(frozen=True)
class OtherSize:
    """Another RIS size of the sizing question: its information, what its search sees, its
    cover sets, and its lower bound (a call that waits for it; ``None`` when the target is out
    of reach with every candidate)."""

    problem: DistrictProblem
    seen: DistrictProblem
    needs: Needs
    lower: Callable[[], int | None]


def _other_size(
    inputs: PlanInputs,
    size: tuple[int, int],
    like: DistrictProblem,
    goal: float | None,
    constraints: tuple[tuple[int, ...], tuple[int, ...]],
    beside: ThreadPoolExecutor | None,
) -> OtherSize:
    """The :class:`OtherSize` of ``size`` (its visibility shared with ``like``); its lower bound
    on the thread ``beside`` when given, else when asked."""
    pr = build_problem(_resized(inputs, *size), like=like)
    nd = sites_needed(pr)
    lower: Callable[[], int | None]
    if goal is None:
        lower = lambda: None  # noqa: E731
    elif beside is not None:
        lower = beside.submit(count_lower_bound, pr, goal, nd, *constraints).result
    else:
        lower = partial(count_lower_bound, pr, goal, nd, *constraints)
    return OtherSize(pr, pr.strongest(SEARCH_SITES), nd, lower)


def _resized(inputs: PlanInputs, rows: int, cols: int) -> PlanInputs:
    """The same plan with every candidate a ``rows`` × ``cols`` RIS."""
    ris = inputs.document.ris.model_copy(update={"rows": rows, "cols": cols})
    sites = [
        replace(s, ris=s.ris.model_copy(update={"rows": rows, "cols": cols})) for s in inputs.sites
    ]
    return replace(inputs, sites=sites, document=inputs.document.model_copy(update={"ris": ris}))
