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
from dataclasses import dataclass
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
from ris_planner.inversion.crb import crb_diagonal
from ris_planner.inversion.ldl import pack
from ris_planner.model.objectives.protocol import objective_kind
from ris_planner.model.plan import MAX_DISTRICT_RIS
from ris_planner.physics import fim
from ris_planner.planning.inputs import PlanInputs
from ris_planner.planning.visibility import serve_matrix
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

MAX_SUBSETS = 64
"""Per pair, the most m-subsets of its serving sites evaluated to raise m_p above the counting
rule (:func:`sites_needed`); a pair with more keeps the counting rule's m_p (still valid)."""

SURROGATE_FINITE = 0.5
"""Surrogate of a pair with a finite bound above the threshold θ: 0.5 + 0.5·θ/bound ∈ (0.5, 1);
an ``inf`` pair scores 0.5 · (its channel parameters / unknown states) < 0.5, a covered pair 1."""

GAIN_TIE = 1e-12
"""Covered-weight gains within this of the best are equal; the surrogate decides among them."""


@dataclass(frozen=True)
class DistrictProblem:
    """The sparse information of a plan's pairs and candidate sites.

    entry_pair, entry_site : [E] the (pair, serving site) entries, pair-major; pair_start [P+1]
    their offsets per pair (CSR); info [E, k(k+1)/2] each entry's packed information on the k
    kept states, factor [E, m, k] its square-root rows; los [k(k+1)/2, P] and los_factor
    [P, 1, k] the LOS path's (zero where absent); los_present [P]; weights [P] (sum 1);
    threshold θ [m] of the coverage objective; n_obs_los [P] the LOS path's channel parameters
    (1 or 0); n_kept k; metric "rx", "tx" or "max"; rows_t, rows_r the kept states' indices of
    p_T and p_R.
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

    @property
    def n_pairs(self) -> int:
        return int(self.weights.size)

    @property
    def n_entries(self) -> int:
        return int(self.entry_pair.size)

    def sites_of(self, p: int) -> IntArray:
        return self.entry_site[self.pair_start[p] : self.pair_start[p + 1]]


def build_problem(inputs: PlanInputs, progress: ProgressCallback = no_progress) -> DistrictProblem:
    """The :class:`DistrictProblem` of a prepared plan: visibility per (map point, site), the
    serving sites of each pair from it, and each entry's information, site by site over that
    site's pairs only."""
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
        # [S, M] per distinct map point: the pairs' serving sites by two gathers
        serve_t = _serves(inputs, pairs.tx, pairs.tx_index)
        serve_r = _serves(inputs, pairs.rx, pairs.rx_index)
        present = serve_t & serve_r  # [P, S]
        progress(0.3, "visibility")
        entry_pair, entry_site = np.nonzero(present)
        pair_start = np.searchsorted(entry_pair, np.arange(pairs.size + 1))
        radio = fim.Radio.from_system(system)
        g = system.transmissions
        referenced = uses_los_reference(system.los, known)
        los_present = np.zeros(pairs.size, dtype=bool)
        los = np.zeros((k * (k + 1) // 2, pairs.size))
        los_factor = np.zeros((pairs.size, 1, k))
        grad = None
        if system.los:
            from ris_planner.bounds.paths import los_clear

            los_present = los_clear(inputs.scene, pairs.tx, pairs.rx)
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
            progress(0.3 + 0.7 * (s + 1) / len(sites), f"site {s + 1}/{len(sites)}")
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
    )


def _serves(inputs: PlanInputs, positions: FloatArray, index: IntArray) -> BoolArray:
    """[P, S] whether each site serves each pair's UE, evaluated once per distinct map point."""
    _, first, inverse = np.unique(index, return_index=True, return_inverse=True)
    return serve_matrix(inputs.scene, inputs.sites, positions[first]).T[inverse.ravel()]


def entry_metric(
    problem: DistrictProblem,
    pairs: IntArray,
    packed: FloatArray,
    rows: Callable[[IntArray], FloatArray],
    n_obs: IntArray,
) -> FloatArray:
    """The metric (PEB_R, PEB_T or their max) of the information ``packed`` [n, k(k+1)/2] of
    the given pairs; ``rows(i)`` the stacked square-root rows of item i (for the few the LDLᵀ
    does not settle); ``inf`` where the channel parameters ``n_obs`` [n] are fewer than the
    states."""
    diag, _ = crb_diagonal(np.ascontiguousarray(packed.T), problem.n_kept, rows)
    with np.errstate(invalid="ignore", over="ignore"):
        peb_r = np.sqrt(diag[problem.rows_r].sum(axis=0))
        peb_t = np.sqrt(diag[problem.rows_t].sum(axis=0)) if problem.rows_t.size else peb_r
    metric = {"rx": peb_r, "tx": peb_t, "max": np.maximum(peb_r, peb_t)}[problem.metric]
    metric = np.where(np.isnan(metric), np.inf, metric)
    if problem.counting:
        metric = np.where(n_obs < problem.n_kept, np.inf, metric)
    return np.asarray(metric)


class LayoutState:
    """A layout's per-pair information, metric and surrogate, updated site by site."""

    def __init__(self, problem: DistrictProblem, sites: list[int] | tuple[int, ...] = ()) -> None:
        self.problem = problem
        self.member = np.zeros(problem.n_sites, dtype=bool)
        self.info = problem.los.T.copy()  # [P, k(k+1)/2]
        self.count = problem.los_present.astype(int)  # channel parameters
        self.metric = np.full(problem.n_pairs, np.inf)
        for s in sites:
            self.member[s] = True
        self._refresh(np.arange(problem.n_pairs))

    def _rows(
        self, pairs: IntArray, extra: IntArray | None = None
    ) -> Callable[[IntArray], FloatArray]:
        """Square-root rows of the given pairs' layouts (plus the entry ``extra[i]``)."""
        pr = self.problem

        def rows(i: IntArray) -> FloatArray:
            out = []
            for j in i:
                p = int(pairs[j])
                lo, hi = pr.pair_start[p], pr.pair_start[p + 1]
                sel = lo + np.flatnonzero(self.member[pr.entry_site[lo:hi]])
                if extra is not None:
                    sel = np.union1d(sel, [extra[j]])
                stack = [pr.los_factor[p]] + [pr.factor[e] for e in sel]
                out.append(np.concatenate(stack))
            width = max(len(a) for a in out)
            return np.stack([np.pad(a, ((0, width - len(a)), (0, 0))) for a in out])

        return rows

    def _refresh(self, pairs: IntArray) -> None:
        pr = self.problem
        info = pr.los.T[pairs].copy()
        count = pr.los_present[pairs].astype(int)
        for j, p in enumerate(pairs):
            lo, hi = pr.pair_start[p], pr.pair_start[p + 1]
            sel = lo + np.flatnonzero(self.member[pr.entry_site[lo:hi]])
            if sel.size:
                info[j] += pr.info[sel].sum(axis=0)
                count[j] += 3 * sel.size
        self.info[pairs] = info
        self.count[pairs] = count
        self.metric[pairs] = entry_metric(pr, pairs, info, self._rows(pairs), count)

    def add(self, site: int) -> IntArray:
        """Put ``site`` in the layout; the pairs it serves (whose metric changed)."""
        self.member[site] = True
        pairs = self.problem.entry_pair[self.problem.entry_site == site]
        self._refresh(pairs)
        return pairs

    def remove(self, site: int) -> IntArray:
        self.member[site] = False
        pairs = self.problem.entry_pair[self.problem.entry_site == site]
        self._refresh(pairs)
        return pairs

    def coverage(self) -> float:
        return float(self.problem.weights[self.metric <= self.problem.threshold].sum())

    def surrogate(self, metric: FloatArray, count: IntArray) -> FloatArray:
        return surrogate(metric, count, self.problem.threshold, self.problem.n_kept)

    def entry_gains(self, entries: IntArray) -> tuple[FloatArray, FloatArray]:
        """(covered-weight gain, surrogate gain) [len(entries)] of adding each entry's site to
        its pair, the rest of the layout as it is."""
        pr = self.problem
        p = pr.entry_pair[entries]
        info = self.info[p] + pr.info[entries]
        count = self.count[p] + 3
        new = entry_metric(pr, p, info, self._rows(p, entries), count)
        old = self.metric[p]
        w = pr.weights[p]
        thr = pr.threshold
        cov = w * ((new <= thr).astype(float) - (old <= thr))
        sur = w * (self.surrogate(new, count) - self.surrogate(old, self.count[p]))
        fresh = ~self.member[pr.entry_site[entries]]
        return cov * fresh, sur * fresh


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
) -> list[PathStep]:
    """Forward selection up to ``max_count`` sites (or, from ``min_count`` sites on, until
    coverage ≥ ``target``): each step
    adds the site with the largest covered-weight gain, ties by the surrogate gain, then by the
    lower site index. Only the entries of the pairs the added site serves are evaluated again."""
    state = LayoutState(problem, list(required))
    allowed = np.ones(problem.n_sites, dtype=bool)
    allowed[list(excluded)] = False
    allowed[list(required)] = False
    all_entries = np.arange(problem.n_entries)
    cov_e, sur_e = state.entry_gains(all_entries)
    gain_c = _site_sums(problem, all_entries, cov_e)
    gain_s = _site_sums(problem, all_entries, sur_e)
    layout = list(required)
    path = [PathStep(tuple(sorted(layout)), state.coverage())] if layout else []
    while len(layout) < max_count and np.any(allowed):
        if target is not None and path and path[-1].coverage >= target and len(layout) >= min_count:
            break
        gc = np.where(allowed, gain_c, -np.inf)
        best = gc.max()
        tied = allowed & (gain_c >= best - GAIN_TIE)
        s = int(np.flatnonzero(tied)[np.argmax(gain_s[tied])])
        if not (gain_c[s] > GAIN_TIE or gain_s[s] > 0):
            break  # no site adds information to any pair
        changed = state.add(s)
        layout.append(s)
        allowed[s] = False
        path.append(PathStep(tuple(sorted(layout)), state.coverage()))
        # the entries of the changed pairs: their gains again
        hit = np.zeros(problem.n_pairs, dtype=bool)
        hit[changed] = True
        entries = np.flatnonzero(hit[problem.entry_pair])
        gain_c -= _site_sums(problem, entries, cov_e[entries])
        gain_s -= _site_sums(problem, entries, sur_e[entries])
        cov_e[entries], sur_e[entries] = state.entry_gains(entries)
        gain_c += _site_sums(problem, entries, cov_e[entries])
        gain_s += _site_sums(problem, entries, sur_e[entries])
        progress(len(layout) / max_count, f"{len(layout)} RISs: coverage {path[-1].coverage:.3f}")
    return path


def improve(
    problem: DistrictProblem,
    layout: tuple[int, ...],
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    max_rounds: int = 3,
) -> tuple[tuple[int, ...], float]:
    """First-improvement swaps on the true coverage: each site of the layout (not required) is
    taken out and the best site for its place put in, kept when the coverage rises."""
    state = LayoutState(problem, list(layout))
    best = state.coverage()
    fixed = set(required)
    banned = np.zeros(problem.n_sites, dtype=bool)
    banned[list(excluded)] = True
    for _ in range(max_rounds):
        better = False
        for out in sorted(set(state.member.nonzero()[0].tolist()) - fixed):
            state.remove(out)
            base = state.coverage()
            entries = np.flatnonzero(~state.member[problem.entry_site])
            cov, _ = state.entry_gains(entries)
            gain = _site_sums(problem, entries, cov)
            gain[state.member | banned] = -np.inf
            gain[out] = -np.inf
            s = int(np.argmax(gain))
            if np.isfinite(gain[s]) and base + gain[s] > best + GAIN_TIE:
                state.add(s)
                best = state.coverage()
                better = True
            else:
                state.add(out)
        if not better:
            break
    return tuple(int(s) for s in np.flatnonzero(state.member)), best


def sites_needed(problem: DistrictProblem) -> IntArray:
    """m_p [P]: a lower bound on the serving sites a layout needs for pair p to be covered;
    0 for a pair that even all its serving sites leave above the threshold (never covered).

    The counting rule gives m ≥ ⌈(k − LOS)/3⌉; where a pair has at most :data:`MAX_SUBSETS`
    m-subsets and none of them covers it, m_p is raised by one (a larger layout contains some
    m-subset, and adding information never raises a bound, so needing more than m is exact)."""
    pr = problem
    n_serving = np.diff(pr.pair_start)
    full = LayoutState(pr, list(range(pr.n_sites)))
    coverable = full.metric <= pr.threshold
    need = np.maximum(1, -(-(pr.n_kept - pr.los_present.astype(int)) // 3))
    if not pr.counting:
        need = np.ones(pr.n_pairs, dtype=int)
    need = np.where(coverable, need, 0)
    for n in np.unique(n_serving[coverable]):
        for m in np.unique(need[coverable & (n_serving == n)]):
            if m >= n or math.comb(int(n), int(m)) > MAX_SUBSETS:
                continue
            group = np.flatnonzero(coverable & (n_serving == n) & (need == m))
            subsets = np.array(list(itertools.combinations(range(int(n)), int(m))), dtype=int)
            # [G, C, m] entries of every subset of every pair of the group
            entries = pr.pair_start[group][:, None, None] + subsets[None]
            info = pr.los.T[group][:, None] + pr.info[entries].sum(axis=2)
            flat_p = np.repeat(group, len(subsets))
            flat_e = entries.reshape(-1, int(m))
            count = pr.los_present[flat_p].astype(int) + 3 * int(m)

            def rows(i: IntArray, fp: IntArray = flat_p, fe: IntArray = flat_e) -> FloatArray:
                return np.stack(
                    [np.concatenate([pr.los_factor[fp[j]], *pr.factor[fe[j]]]) for j in i]
                )

            metric = entry_metric(pr, flat_p, info.reshape(-1, info.shape[-1]), rows, count)
            none = ~np.any((metric <= pr.threshold).reshape(len(group), -1), axis=1)
            need[group[none]] = m + 1
    return np.asarray(need)


def _relaxation(
    problem: DistrictProblem, need: IntArray, fixed: tuple[int, ...], excluded: tuple[int, ...]
) -> tuple[csr_matrix, IntArray]:
    """The constraints y_p − Σ_{s∈S_p} z_s / m_p ≤ 0 of the pairs that can be covered
    (variables [z (S), y (those pairs)]), and those pairs."""
    pr = problem
    live = np.flatnonzero(need > 0)
    row_of = np.full(pr.n_pairs, -1)
    row_of[live] = np.arange(live.size)
    e = np.flatnonzero(need[pr.entry_pair] > 0)
    rows = np.concatenate([row_of[pr.entry_pair[e]], np.arange(live.size)])
    cols = np.concatenate([pr.entry_site[e], pr.n_sites + np.arange(live.size)])
    vals = np.concatenate([-1.0 / need[pr.entry_pair[e]], np.ones(live.size)])
    a = csr_matrix((vals, (rows, cols)), shape=(live.size, pr.n_sites + live.size))
    return a, live


def _bounds(
    problem: DistrictProblem, live: IntArray, fixed: tuple[int, ...], excluded: tuple[int, ...]
) -> list[tuple[float, float]]:
    z = [(0.0, 1.0)] * problem.n_sites
    for s in fixed:
        z[s] = (1.0, 1.0)
    for s in excluded:
        z[s] = (0.0, 0.0)
    return z + [(0.0, 1.0)] * live.size


def coverage_upper_bound(
    problem: DistrictProblem,
    count: int,
    need: IntArray,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """An upper bound on the coverage of every layout of ``count`` sites (the relaxation of the
    module docstring; ``need`` from :func:`sites_needed`)."""
    a, live = _relaxation(problem, need, required, excluded)
    if live.size == 0:
        return 0.0
    c = np.concatenate([np.zeros(problem.n_sites), -problem.weights[live]])
    eq = csr_matrix(np.concatenate([np.ones(problem.n_sites), np.zeros(live.size)])[None])
    res = linprog(
        c,
        A_ub=a,
        b_ub=np.zeros(live.size),
        A_eq=eq,
        b_eq=[float(count)],
        bounds=_bounds(problem, live, required, excluded),
        method="highs",
    )
    if res.status != 0:
        raise RisPlannerError(f"coverage relaxation failed: {res.message}")
    # HiGHS' optimum to its feasibility tolerance: pad by it so the bound stays a bound
    return float(min(1.0, -res.fun + 1e-7))


def count_lower_bound(
    problem: DistrictProblem,
    target: float,
    need: IntArray,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> int | None:
    """The fewest sites any layout reaching coverage ``target`` can have (relaxation: the
    smallest Σ z with Σ w_p y_p ≥ target, rounded up); ``None`` when no layout reaches it."""
    a, live = _relaxation(problem, need, required, excluded)
    reachable = float(problem.weights[live].sum()) if live.size else 0.0
    if reachable < target - 1e-12:
        return None
    c = np.concatenate([np.ones(problem.n_sites), np.zeros(live.size)])
    cover = np.concatenate([np.zeros(problem.n_sites), -problem.weights[live]])

    res = linprog(
        c,
        A_ub=vstack([a, csr_matrix(cover[None])]).tocsr(),
        b_ub=np.concatenate([np.zeros(live.size), [-target]]),
        bounds=_bounds(problem, live, required, excluded),
        method="highs",
    )
    if res.status != 0:
        return None
    return max(len(required), math.ceil(res.fun - 1e-6))


def summary(problem: DistrictProblem, need: IntArray) -> dict[str, Any]:
    """What the site can give at all: the pair weight no candidate serves (no layout gives a
    finite bound), and what even every candidate leaves above the threshold."""
    full = LayoutState(problem, list(range(problem.n_sites)))
    blind = ~np.isfinite(full.metric)
    w = problem.weights
    return {
        "pairs": problem.n_pairs,
        "blind_everywhere": {"pairs": int(blind.sum()), "weight": float(w[blind].sum())},
        "above_threshold_everywhere": {
            "pairs": int(((need == 0) & ~blind).sum()),
            "weight": float(w[(need == 0) & ~blind].sum()),
        },
        "coverable_weight": float(w[need > 0].sum()),
        "entries": problem.n_entries,
        "serving_sites_per_pair": float(np.diff(problem.pair_start).mean()),
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
    if feas.conflict.any() or feas.budget is not None:
        raise RisPlannerError(
            "search.method 'district' takes required and excluded sites only; spacing,"
            " exclusive mounting points and budgets need 'auto', 'exhaustive' or 'greedy'"
        )
    progress(0.0, "information")
    problem = build_problem(inputs, lambda f, m: progress(0.4 * f, m))
    need = sites_needed(problem)
    site_summary = summary(problem, need)
    coverable = site_summary["coverable_weight"]
    target = _target(doc)
    counts = [c for c in inputs.counts if c <= problem.n_sites]
    goal = None if target is None else target * coverable
    progress(0.5, "greedy path")
    # sizing follows the path until the target, whatever the listed counts
    longest = max(counts) if goal is None else max(max(counts), MAX_DISTRICT_RIS)
    path = greedy_path(
        problem, min(longest, problem.n_sites), goal, required, excluded, min_count=max(counts)
    )
    progress(0.7, "swaps")
    by_count = []
    names = [s.name for s in inputs.sites]
    for c in counts:
        step = next((p for p in path if len(p.sites) == c), None)
        if step is None:
            continue  # the path stopped: no site adds information
        layout, cov = improve(problem, step.sites, required, excluded)
        ub = coverage_upper_bound(problem, c, need, required, excluded)
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
    }
    if target is not None:
        plan["sizing"] = _sizing(problem, need, path, target, coverable, required, excluded)
    progress(1.0, "done")
    return plan


def _target(doc: Any) -> float | None:
    """The coverage to reach, as a fraction of the pairs some layout can cover: the sizing
    question's target (:meth:`PlanDocument.sizing_target`) with ``sizing``, else
    ``objective.target``; ``None`` without either."""
    target = doc.sizing_target() if doc.sizing is not None else doc.objective.target
    return None if target is None or target.min is None else float(target.min)


def _sizing(
    problem: DistrictProblem,
    need: IntArray,
    path: list[PathStep],
    target: float,
    coverable: float,
    required: tuple[int, ...],
    excluded: tuple[int, ...],
) -> dict[str, Any]:
    goal = target * coverable
    found = next((p for p in path if p.coverage >= goal - 1e-12), None)
    lower = count_lower_bound(problem, goal, need, required, excluded)
    out: dict[str, Any] = {
        "target": target,
        "of": "coverable pairs",
        "coverable_weight": coverable,
        "count": None if found is None else len(found.sites),
        "lower_bound": lower,
        "method": "district",
    }
    if found is None:
        best = path[-1].coverage if path else 0.0
        out["gap"] = None
        out["message"] = (
            f"the greedy path stops at {len(path)} RISs with coverage {best:.3f}, below the"
            f" target {goal:.3f}; at least {lower} RISs are needed"
        )
    else:
        out["gap"] = len(found.sites) - (lower or 0)
        out["message"] = (
            f"{len(found.sites)} RISs reach {found.coverage:.3f} ≥ {target:g} × the coverable"
            f" {coverable:.3f}; no layout of fewer than {lower} RISs can (gap"
            f" {out['gap']} RISs)"
        )
    return out
