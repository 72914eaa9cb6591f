"""District-scale placement search: tens of RISs from hundreds or thousands of candidates, by
locality (docs/concepts/district.md, "Search").

* :func:`greedy_path`: forward selection on coverage, each step the site with the largest gain
  in covered weight, ties (and the first steps, where no single site covers a pair) broken by a
  surrogate that rewards progress towards a finite, then a small bound. Adding a site changes
  only its own pairs, so only the entries of those pairs are evaluated again (incremental
  scoring: one batched inversion over a handful of matrices per step).
* :func:`improve`: a swap pass on the true coverage (and pair swaps on small layouts).
* :func:`rounded_layout`, :func:`lp_layouts`: layouts from a relaxation's site weights (top-L
  and randomized roundings).

The information is the sparse one of :mod:`ris_planner.planning.scoring.sparse`; the search
sees each pair's :data:`SEARCH_SITES` strongest serving sites
(:meth:`~ris_planner.planning.scoring.sparse.DistrictProblem.strongest`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.model.search_methods import MAX_DISTRICT_RIS
from ris_planner.planning.scoring.sparse import (
    DistrictProblem,
    LayoutState,
    exact_coverage,
    pair_entries,
    summed_entry_metric,
)
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

SURROGATE_FINITE = 0.5
"""Surrogate of a pair with a finite bound above the threshold θ: 0.5 + 0.5·θ/bound ∈ (0.5, 1);
an ``inf`` pair scores 0.5 · (its channel parameters / unknown states) < 0.5, a covered pair 1."""

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


def entry_gains(state: LayoutState, entries: IntArray) -> tuple[FloatArray, FloatArray]:
    """(covered-weight gain, surrogate gain) [len(entries)] of adding each entry's site to
    its pair, the rest of the layout as it is (0 for a site already in it, and for a pair
    already covered: more information never raises its bound)."""
    pr = state.problem
    cov = np.zeros(len(entries))
    sur = np.zeros(len(entries))
    thr, k = pr.threshold, pr.n_kept
    open_ = np.flatnonzero(
        (state.metric[pr.entry_pair[entries]] > thr) & ~state.member[pr.entry_site[entries]]
    )
    e = entries[open_]
    p = pr.entry_pair[e]
    count = state.count[p] + 3
    new = summed_entry_metric(pr, state.info, p, e, lambda i: state.rows(p[i], e[i]), count)
    old = state.metric[p]
    w = pr.weights[p]
    cov[open_] = w * (new <= thr)
    sur[open_] = w * (surrogate(new, count, thr, k) - surrogate(old, state.count[p], thr, k))
    return cov, sur


class GainBook:
    """Every entry's gain (:func:`entry_gains`) and their sums per site, kept up
    to date by re-evaluating only the entries of the pairs whose layout changed."""

    def __init__(self, state: LayoutState) -> None:
        self.state = state
        pr = state.problem
        every = np.arange(pr.n_entries)
        self.cov, self.sur = entry_gains(state, every)
        self.gain_c = _site_sums(pr, every, self.cov)
        self.gain_s = _site_sums(pr, every, self.sur)
        self.floor = LOOKAHEAD_BELOW * float(pr.weights.max(initial=0.0))

    def set(self, site: int, member: bool) -> None:
        """Change the layout (:meth:`LayoutState.set`) and the gains it changes."""
        pr = self.state.problem
        changed = self.state.set(site, member)
        _, entries = pair_entries(pr, changed)
        self.gain_c -= _site_sums(pr, entries, self.cov[entries])
        self.gain_s -= _site_sums(pr, entries, self.sur[entries])
        self.cov[entries], self.sur[entries] = entry_gains(self.state, entries)
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


SIZING_PROBES = 5
"""The most counts :func:`fewer_sites` tries below the greedy path's answer (each a swap pass
on a layout of that count: about 7 s at 170 RISs on the benchmark district)."""

SIZING_SWAP_REACH = 0.02
""":func:`fewer_sites` tries no count whose greedy-path coverage is further below the goal than
this or the largest step of the path's second half (up to its answer), whichever is larger:
one swap pass raised a path layout's coverage by at most 0.009 near the answer on the
benchmark district (docs/validation/benchmarks.md)."""


def fewer_sites(
    problem: DistrictProblem,
    seen: DistrictProblem,
    path: list[PathStep],
    goal: float,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    conflict: BoolArray | None = None,
) -> list[tuple[tuple[int, ...], float]]:
    """Layouts of fewer sites than the greedy path's first step that reaches ``goal``: the
    path's layouts improved by one swap pass (:func:`improve`, on ``seen``) and re-scored on
    ``problem``, in bisection between that step's count and the largest count whose path
    coverage is below the goal by more than :data:`SIZING_SWAP_REACH` and the largest step of
    the path's second half; at most :data:`SIZING_PROBES` counts. The
    layouts tried, in order, each with its coverage on ``problem`` (none when the path never
    reaches the goal or no count lies between)."""
    steps = {len(p.sites): p for p in path}
    hi = next((len(p.sites) for p in path if p.coverage >= goal - GAIN_TIE), None)
    if hi is None:
        return []
    gains = np.diff([0.0, *(p.coverage for p in path)])
    late = [g for p, g in zip(path, gains, strict=True) if hi // 2 < len(p.sites) <= hi]
    reach = max([SIZING_SWAP_REACH, *late])
    far = [c for c, p in steps.items() if c < hi and p.coverage < goal - reach]
    lo = max([min(steps) - 1, *far])
    tried: list[tuple[tuple[int, ...], float]] = []
    for _ in range(SIZING_PROBES):
        mid = (lo + hi) // 2
        if hi - lo <= 1 or mid not in steps:
            break
        layout, cov = improve(seen, steps[mid].sites, required, excluded, 1, conflict)
        if seen is not problem:
            cov = exact_coverage(problem, layout)
        tried.append((layout, cov))
        if cov >= goal - GAIN_TIE:
            hi = mid
        else:
            lo = mid
    return tried


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


LP_ROUNDINGS = 4
"""Randomized roundings of the relaxation's site weights tried per count besides the top-L
one (:func:`lp_layouts`)."""

LP_ROUNDING_SEED = 0
"""Seed of :func:`lp_layouts`' randomized roundings (a plan is reproducible)."""


def lp_layouts(
    z: FloatArray,
    count: int,
    required: tuple[int, ...],
    excluded: tuple[int, ...],
    conflict: BoolArray | None,
    tries: int = LP_ROUNDINGS,
    seed: int = LP_ROUNDING_SEED,
) -> list[tuple[tuple[int, ...], str]]:
    """Layouts of ``count`` sites from a relaxation's site weights ``z``, each with how it was
    rounded: the top-L one (:func:`rounded_layout`), then ``tries`` randomized ones – sites
    drawn without replacement with probability ∝ z (Gumbel keys on log z, fixed seed), the
    conflicts honoured as in :func:`rounded_layout`. Repeated layouts and layouts short of
    ``count`` sites are left out."""
    out = [(rounded_layout(z, count, required, excluded, conflict), "LP rounding")]
    rng = np.random.default_rng(seed)
    logz = np.log(np.maximum(z, 1e-12))
    for _ in range(tries):
        key = logz + rng.gumbel(size=z.size)
        out.append(
            (rounded_layout(key, count, required, excluded, conflict), "randomized LP rounding")
        )
    seen: set[tuple[int, ...]] = set()
    kept = []
    for lay, how in out:
        if len(lay) == count and lay not in seen:
            seen.add(lay)
            kept.append((lay, how))
    return kept


def most_ris(transmissions: int) -> int:
    """The most RISs a target or sizing path may place: :data:`MAX_DISTRICT_RIS`, and one fewer
    than the pilot transmissions (a layout of L RISs needs L + 1 time-orthogonal
    transmissions)."""
    return int(min(MAX_DISTRICT_RIS, transmissions - 1))
