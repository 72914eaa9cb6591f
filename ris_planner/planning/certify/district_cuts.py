"""Non-cover cuts of the district certificate (docs/concepts/district.md, "The certificate").

Coverage is monotone in the layout: adding a site only adds information, so it never raises a
pair's bound. Hence if a set U of a pair's serving sites does not cover the pair, every layout
that covers it holds a serving site outside U, and with z_s = 1[s in the layout],
y_p = 1[p covered]:

    y_p ≤ Σ_{s∈S_p∖U} z_s.

Where U plus any one further site still fails, a covering layout holds two sites outside U;
in general, with G the sites t outside U for which U ∪ {t} is not known to fail, a covering
layout holds a site of G or two sites of T∖G (T = S_p∖U):

    2·y_p ≤ 2·Σ_{s∈G} z_s + Σ_{s∈T∖G} z_s.

:func:`static_cuts` takes, per pair, U the longest prefix of its serving sites in increasing
strength (:meth:`~ris_planner.planning.scoring.sparse.DistrictProblem.strength`) that does not
cover it, found by bisection over the prefix length (about eight exact evaluations per pair),
then tests U ∪ {t} for every t outside. T is the pair's *strong set*: the only sites of which
a covering layout must hold one. A set is declared non-covering only when its exact bound
exceeds the threshold by :data:`NONCOVER_MARGIN` (relative, on the bound squared): a covering
set misjudged as non-covering would make the certificate invalid.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.planning.scoring.sparse import DistrictProblem, entry_metric

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]

NONCOVER_MARGIN = 1e-4
"""A set of sites is declared non-covering for a pair only when its bound squared (PEB², the
CRB trace) exceeds the threshold squared by this relative margin: a hundred times the bounds'
1e-6 accuracy contract and far above the rounding of summing the information in another
order, so no covering set is ever taken for a non-covering one."""

CHUNK_ENTRIES = 200_000
"""(pair, site) entries per block of :func:`longest_noncover_prefix` (its prefix sums: about
8·k(k+1)/2 bytes each)."""


@dataclass(frozen=True)
class CutRows:
    """Rows ``y_coef[r]·y_{pair[r]} − Σ_i coef[i]·z_{site[i]} ≤ 0`` (i over
    ``start[r]:start[r + 1]``)."""

    pair: IntArray
    y_coef: FloatArray
    start: IntArray
    site: IntArray
    coef: FloatArray

    @property
    def n_rows(self) -> int:
        return int(self.pair.size)

    @property
    def n_nonzeros(self) -> int:
        return int(self.site.size + self.pair.size)

    @staticmethod
    def empty() -> CutRows:
        z = np.zeros(0, dtype=np.int64)
        return CutRows(z, np.zeros(0), np.zeros(1, dtype=np.int64), z, np.zeros(0))


@dataclass(frozen=True)
class StaticCuts:
    """:func:`static_cuts`: the rows and, per pair, the size of its strong set (0 for the
    pairs without a cut: never coverable, or covered by any layout)."""

    rows: CutRows
    strong: IntArray
    tests: int


def noncovering(problem: DistrictProblem, metric: FloatArray) -> BoolArray:
    """Whether bounds ``metric`` are surely above the threshold (:data:`NONCOVER_MARGIN`)."""
    with np.errstate(invalid="ignore", over="ignore"):
        return np.asarray(metric**2 > problem.threshold**2 * (1.0 + NONCOVER_MARGIN))


def _blocks(problem: DistrictProblem, pairs: IntArray) -> Iterator[IntArray]:
    """Consecutive slices of ``pairs`` of about :data:`CHUNK_ENTRIES` entries each."""
    n = np.diff(problem.pair_start)[pairs]
    ends = np.cumsum(n)
    b = 0
    while b < pairs.size:
        before = int(ends[b - 1]) if b else 0
        e = max(b + 1, int(np.searchsorted(ends, before + CHUNK_ENTRIES, side="right")))
        yield np.arange(b, e)
        b = e


class _Prefixes:
    """One block of pairs, each with its serving entries in a given order: the information of
    any prefix (plus one more entry), summed entry by entry in that order."""

    def __init__(self, problem: DistrictProblem, pairs: IntArray, order: IntArray) -> None:
        pr = self.problem = problem
        self.pairs = pairs
        self.n = np.diff(pr.pair_start)[pairs]
        self.off = np.concatenate([[0], np.cumsum(self.n)[:-1]]).astype(np.int64)
        pos = np.concatenate(
            [np.arange(pr.pair_start[p], pr.pair_start[p + 1]) for p in pairs.tolist()]
        ).astype(np.int64)
        self.pos = pos
        self.entries = order[pos]
        # segmented prefix sums: position k of every pair in one step (exact running sums)
        cum = pr.info[self.entries].copy()
        for k in range(1, int(self.n.max(initial=0))):
            longer = np.flatnonzero(self.n > k)
            cum[self.off[longer] + k] += cum[self.off[longer] + k - 1]
        self.cum = cum

    def metric(self, i: IntArray, j: IntArray, extra: IntArray | None = None) -> FloatArray:
        """[len(i)] the bound of pair i's first j entries (and entry ``extra``)."""
        pr = self.problem
        p = self.pairs[i]
        info = pr.los.T[p].copy()
        has = j > 0
        info[has] += self.cum[self.off[i[has]] + j[has] - 1]
        count = pr.los_present[p].astype(np.int64) + 3 * j
        if extra is not None:
            info += pr.info[extra]
            count = count + 3

        per = pr.factor.shape[1]  # square-root rows per entry: 3 planar, 7 spherical

        def rows(k: IntArray) -> FloatArray:
            width = int(j[k].max(initial=0)) + (extra is not None)
            f = np.zeros((len(k), 1 + per * width, pr.n_kept))
            for a, kk in enumerate(k.tolist()):
                e = self.entries[self.off[i[kk]] : self.off[i[kk]] + j[kk]]
                if extra is not None:
                    e = np.append(e, extra[kk])
                f[a, 0] = pr.los_factor[p[kk], 0]
                f[a, 1 : 1 + per * e.size] = pr.factor[e].reshape(-1, pr.n_kept)
            return f

        return entry_metric(pr, info, rows, count)


def longest_noncover_prefix(
    problem: DistrictProblem, pairs: IntArray, order: IntArray
) -> tuple[IntArray, BoolArray, int]:
    """Per pair of ``pairs``: the length j of the longest prefix of its serving entries in
    ``order`` (a permutation of the entries that keeps each pair's entries in its own
    ``pair_start`` range) that is surely non-covering (-1: even no site may cover it), found by
    bisection (a longer prefix holds more information, so a covering prefix's extensions
    cover); and, over ``order``'s positions, whether each entry t after the prefix leaves the
    prefix plus t possibly covering (the set G of the module docstring). Also the number of
    exact evaluations made."""
    pr = problem
    length = np.zeros(pairs.size, dtype=np.int64)
    maybe = np.zeros(pr.n_entries, dtype=bool)
    tests = 0
    for block in _blocks(pr, pairs):
        pre = _Prefixes(pr, pairs[block], order)
        every = np.arange(block.size)
        lo = np.zeros(block.size, dtype=np.int64)  # surely non-covering
        lo[~noncovering(pr, pre.metric(every, lo))] = -1
        hi = pre.n.copy()  # not surely non-covering (every site: the pair is coverable)
        tests += block.size
        while True:
            o = np.flatnonzero(hi - lo > 1)
            if o.size == 0:
                break
            mid = (lo[o] + hi[o]) // 2
            non = noncovering(pr, pre.metric(o, mid))
            tests += o.size
            lo[o[non]] = mid[non]
            hi[o[~non]] = mid[~non]
        ok = np.flatnonzero(lo >= 0)
        rest = pre.n[ok] - lo[ok]
        item = np.repeat(ok, rest)
        j = np.repeat(lo[ok], rest)
        first = np.repeat(pre.off[ok] + lo[ok], rest)
        at = first + np.arange(int(rest.sum())) - np.repeat(np.cumsum(rest) - rest, rest)
        if item.size:
            non = noncovering(pr, pre.metric(item, j, pre.entries[at]))
            tests += item.size
            maybe[pre.pos[at[~non]]] = True
        length[block] = lo
    return length, maybe, tests


def static_cuts(problem: DistrictProblem, need: IntArray) -> StaticCuts:
    """One cut per coverable pair (``need`` > 0): U the longest non-covering prefix of its
    serving sites by increasing strength, the cut ``y ≤ Σ_T z`` or, where some t of T leaves
    U ∪ {t} surely non-covering, ``2y ≤ 2·Σ_G z + Σ_{T∖G} z`` (module docstring)."""
    pr = problem
    live = np.flatnonzero(need > 0)
    order = np.lexsort((pr.strength(), pr.entry_pair))
    length, maybe, tests = longest_noncover_prefix(pr, live, order)
    rows, strong = _prefix_rows(pr, live, order, length, maybe)
    return StaticCuts(rows, strong, tests)


def _prefix_rows(
    problem: DistrictProblem,
    pairs: IntArray,
    order: IntArray,
    length: IntArray,
    maybe: BoolArray,
) -> tuple[CutRows, IntArray]:
    """The cut of each pair of ``pairs`` with a non-covering prefix (``length`` ≥ 0) of its
    entries in ``order`` (:func:`longest_noncover_prefix`), and per pair [P] the size of T."""
    pr = problem
    strong = np.zeros(pr.n_pairs, dtype=np.int64)
    cut = length >= 0
    pairs = pairs[cut]
    rest = pr.pair_start[pairs + 1] - pr.pair_start[pairs] - length[cut]
    strong[pairs] = rest
    first = np.repeat(pr.pair_start[pairs] + length[cut], rest)
    at = first + np.arange(int(rest.sum())) - np.repeat(np.cumsum(rest) - rest, rest)
    g = maybe[at]
    starts = np.cumsum(rest) - rest
    all_g = (
        np.add.reduceat(g.astype(np.int64), starts) == rest
        if at.size
        else np.ones(pairs.size, dtype=bool)
    )
    all_g |= rest == 0
    two = ~all_g
    coef = np.where(np.repeat(two, rest), np.where(g, 2.0, 1.0), 1.0)
    rows = CutRows(
        pairs,
        np.where(two, 2.0, 1.0),
        np.concatenate([[0], np.cumsum(rest)]).astype(np.int64),
        pr.entry_site[order[at]],
        coef,
    )
    return rows, strong


def counting_rows(problem: DistrictProblem, need: IntArray) -> CutRows:
    """``m_p·y_p ≤ Σ_{s∈S_p} z_s`` for every coverable pair (a covering layout holds m_p of
    its serving sites: :func:`~ris_planner.planning.certify.district_lp.sites_needed`)."""
    pr = problem
    pairs = np.flatnonzero(need > 0)
    n = pr.pair_start[pairs + 1] - pr.pair_start[pairs]
    first = np.repeat(pr.pair_start[pairs], n)
    at = first + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    return CutRows(
        pairs,
        need[pairs].astype(float),
        np.concatenate([[0], np.cumsum(n)]).astype(np.int64),
        pr.entry_site[at],
        np.ones(at.size),
    )


def violated(rows: CutRows, y: FloatArray, z: FloatArray) -> BoolArray:
    """[rows] whether (y [P], z [S]) breaks each row (any amount): a test helper and the
    check that a covering layout meets every cut."""
    rhs = np.add.reduceat(rows.coef * z[rows.site], rows.start[:-1]) if rows.site.size else 0.0
    rhs = np.where(np.diff(rows.start) > 0, rhs, 0.0)
    return np.asarray(rows.y_coef * y[rows.pair] > rhs + 1e-12)


SEPARATION_EXTENSIONS = 2
""":func:`separated_cuts` grows each pair's non-covering set this many times past the first
site that would make it cover (each time one more bisection over the sites left)."""

VIOLATION_TOL = 1e-6
"""A separated cut is added only where the relaxation's point breaks it by more than this
(per unit of y: the row over its y coefficient)."""


def take(rows: CutRows, index: IntArray) -> CutRows:
    """The rows ``index`` of ``rows`` (in that order)."""
    per = np.diff(rows.start)[index]
    first = np.repeat(rows.start[:-1][index], per)
    at = first + np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per)
    return CutRows(
        rows.pair[index],
        rows.y_coef[index],
        np.concatenate([[0], np.cumsum(per)]).astype(np.int64),
        rows.site[at],
        rows.coef[at],
    )


def row_slack(rows: CutRows, y: FloatArray, z: FloatArray) -> FloatArray:
    """[rows] how far (y [P], z [S]) breaks each row, per unit of its y coefficient
    (positive: broken)."""
    per = np.diff(rows.start)
    rhs = np.zeros(rows.n_rows)
    if rows.site.size:
        sums = np.add.reduceat(rows.coef * z[rows.site], rows.start[:-1][per > 0])
        rhs[per > 0] = sums
    return np.asarray((rows.y_coef * y[rows.pair] - rhs) / rows.y_coef)


@dataclass(frozen=True)
class Separated:
    """:func:`separated_cuts`: the violated rows (most violated × weight first), how many
    pairs were tried and how many exact evaluations it took."""

    rows: CutRows
    tried: int
    tests: int


def separated_cuts(
    problem: DistrictProblem,
    pairs: IntArray,
    y: FloatArray,
    z: FloatArray,
    max_rows: int,
) -> Separated:
    """Non-cover cuts that the relaxation's point (y [P], z [S]) breaks, for the pairs
    ``pairs``: per pair, U a maximal non-covering set grown from the sites the point favours
    (largest z first, ties by increasing strength): the longest surely non-covering prefix in
    that order (bisection), then – :data:`SEPARATION_EXTENSIONS` times – the sites t with
    U ∪ {t} surely non-covering moved before the others and the longest prefix found again
    (it only grows: the old prefix is still one). The cut is the one of
    :func:`static_cuts` for that U (with its 2-cut form where some U ∪ {t} fails). Every
    row comes from the same exact, margined test (:func:`noncovering`), so each is valid for
    every covering layout whatever the point. At most ``max_rows`` rows: the largest
    violation × pair weight first."""
    pr = problem
    pairs = np.asarray(pairs, dtype=np.int64)
    if pairs.size == 0:
        return Separated(CutRows.empty(), 0, 0)
    zs = z[pr.entry_site]
    order = np.lexsort((pr.strength(), -zs, pr.entry_pair))
    length, maybe, tests = longest_noncover_prefix(pr, pairs, order)
    for _ in range(SEPARATION_EXTENSIONS):
        ok = length >= 0
        grow = pairs[ok]
        if grow.size == 0:
            break
        # positions of each pair: 0 in the prefix, 1 after it and surely failing with it, 2 else
        pos_pair = pr.entry_pair
        prefix_end = np.full(pr.n_pairs, -1, dtype=np.int64)
        prefix_end[grow] = pr.pair_start[grow] + length[ok]
        q = np.arange(pr.n_entries)
        group = np.where(q < prefix_end[pos_pair], 0, np.where(maybe, 2, 1))
        group[prefix_end[pos_pair] < 0] = 0  # other pairs keep their order
        order = order[np.lexsort((q, group, pos_pair))]
        new_length, maybe, more = longest_noncover_prefix(pr, grow, order)
        tests += more
        if np.array_equal(new_length, length[ok]):
            length[ok] = new_length
            break
        length[ok] = new_length
    rows, _ = _prefix_rows(pr, pairs, order, length, maybe)
    slack = row_slack(rows, y, z)
    broken = np.flatnonzero(slack > VIOLATION_TOL)
    score = slack[broken] * pr.weights[rows.pair[broken]]
    keep = broken[np.argsort(-score, kind="stable")[:max_rows]]
    return Separated(take(rows, keep), int(pairs.size), tests)
