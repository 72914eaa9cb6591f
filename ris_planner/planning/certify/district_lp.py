"""The district search's certificate (docs/concepts/district.md, "The certificate"): an upper
bound on the coverage of every layout of L sites and a lower bound on the count any layout
reaching a coverage needs, from a linear relaxation.

With z_s = 1[s ∈ C] and y_p = 1[p covered by layout C]:

* a pair covered needs at least m_p of its serving sites (m_p from the counting rule and,
  where few enough, from every m-subset of its sites: :func:`sites_needed`), and for the pairs
  whose m_p-subsets were all tried, a covering one (the cover-set form of :func:`_relaxation`);
* it needs a site of its strong set and, where the weak sites plus any one site still fail,
  two (the non-cover cuts of :mod:`ris_planner.planning.certify.district_cuts`);
* sites on one mounting point exclude each other (Σ z ≤ 1 per group), Σ z = L.

The relaxation (0 ≤ y, z ≤ 1) lives in one HiGHS model per district problem
(:class:`DistrictRelaxation`), re-solved per count and for the sizing question. Its bounds are
not the solver's objective but Lagrangian values of the solver's multipliers, evaluated
exactly in float64 (:func:`lagrangian_coverage`, :func:`lagrangian_count`): valid for any
non-negative multipliers, so they do not depend on the solver's tolerances.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix, vstack

from ris_planner.planning.certify.district_cuts import CutRows, separated_cuts, static_cuts
from ris_planner.planning.scoring.sparse import (
    DistrictProblem,
    LayoutState,
    entry_metric,
    servable_pairs,
)

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


def _relaxation(
    problem: DistrictProblem, needs: Needs, counting_sites: int | None = None
) -> tuple[csr_matrix, int, IntArray]:
    """The relaxation's constraints A v ≤ 0 over v = [z (S), y (live pairs), u (complete
    pairs)], the number of variables, and the live pairs (m_p > 0):

    * every live pair (with at most ``counting_sites`` serving sites, when given):
      y_p ≤ Σ_{s∈S_p} z_s / m_p (a covering layout holds m_p of its sites);
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
    if counting_sites is not None:  # the other pairs' rows hold all their sites: left out
        open_ = open_[np.diff(pr.pair_start)[open_] <= counting_sites]
    with_row = np.union1d(open_, comp)
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
            row_y[with_row],
            row_y[pr.entry_pair[e_open]],
            row_y[needs.cover_pair],
            row_y[comp],
            row_u[comp],
            row_u[pr.entry_pair[e_comp]],
        ]
    )
    cols = np.concatenate(
        [
            y_of[with_row],
            pr.entry_site[e_open],
            needs.cover_site,
            u_of[comp],
            u_of[comp],
            pr.entry_site[e_comp],
        ]
    )
    vals = np.concatenate(
        [
            np.ones(with_row.size),
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


@dataclass(frozen=True)
class Relaxed:
    """One count of :class:`DistrictRelaxation`: the certified value (the least Lagrangian
    bound of the solvers' multipliers), the solver's own objective (``None``: not solved for
    this count), its site weights z [S] (zero when not solved), its status and seconds."""

    bound: float
    lp_value: float | None
    z: FloatArray
    status: str
    seconds: float
    cut_rounds: int = 0
    """Rounds of separated non-cover cuts added and solved again (:meth:`DistrictRelaxation.
    separate`)."""
    separated_rows: int = 0
    """The rows those rounds added."""


class DistrictRelaxation:
    """The certificate's linear relaxation of one district problem, built once and solved
    again per count (module docstring): columns z [S], y [live pairs], u [complete pairs];
    rows: the cover-set form of :func:`_relaxation`, the non-cover cuts
    (:mod:`ris_planner.planning.certify.district_cuts`), one row Σ z ≤ 1 per group of
    mutually exclusive sites (one mounting point), the count row Σ z and the goal row
    Σ w_p y_p. One HiGHS model (``highspy``): a count changes the count row's bounds, the
    sizing question the objective and the goal row's bounds, and each solve starts from the
    last basis.

    The bound reported is not the solver's objective: it is the Lagrangian value of the
    solver's row multipliers clipped to their sign (:func:`lagrangian_coverage`,
    :func:`lagrangian_count`), evaluated in float64 with the required and excluded sites as
    they are, a valid bound for any multipliers – a solve stopped early or slightly infeasible
    only makes it looser."""

    def __init__(
        self,
        problem: DistrictProblem,
        needs: Needs,
        required: tuple[int, ...] = (),
        excluded: tuple[int, ...] = (),
        conflict: BoolArray | None = None,
        cuts: CutRows | None = None,
    ) -> None:
        pr = self.problem = problem
        self.required, self.excluded = tuple(required), tuple(excluded)
        # with the cuts, the counting rows of pairs seen by many sites (a district's millions
        # of nonzeros, and the weaker rows) are left out
        base, n_var, live = _relaxation(pr, needs, None if cuts is None else COUNTING_ROW_SITES)
        self.live = live
        self.coverable_weight = float(pr.weights[live].sum())
        self.n_var = n_var
        y_of = np.full(pr.n_pairs, -1, dtype=np.int64)
        y_of[live] = pr.n_sites + np.arange(live.size)
        blocks = [base.tocsr()]
        rhs = [np.zeros(base.shape[0])]
        if cuts is not None and cuts.n_rows:
            blocks.append(_cut_matrix(cuts, y_of, n_var))
            rhs.append(np.zeros(cuts.n_rows))
        groups = exclusive_groups(conflict) if conflict is not None else []
        if groups:
            gi = np.concatenate([np.full(len(g), k) for k, g in enumerate(groups)])
            gs = np.concatenate([np.asarray(g) for g in groups])
            blocks.append(csr_matrix((np.ones(gs.size), (gi, gs)), shape=(len(groups), n_var)))
            rhs.append(np.ones(len(groups)))
        self.a = vstack(blocks).tocsr() if len(blocks) > 1 else blocks[0]
        self.b = np.concatenate(rhs)
        self.w = np.zeros(n_var)
        self.w[pr.n_sites : pr.n_sites + live.size] = pr.weights[live]
        self.y_of = y_of
        self.cut_rows = 0 if cuts is None else cuts.n_rows
        self.separated_rows = 0
        self.conflict_rows = len(groups)
        # the solver's rows: a's first n_base rows, the count and goal rows, then the rows
        # separation appends to a (:meth:`add_cuts`)
        self.n_base = int(self.a.shape[0])
        self.base_nonzeros = int(self.a.nnz)
        self.count_row = self.n_base
        self.goal_row = self.count_row + 1
        self.highs: Any = None
        self.mode = ""
        self.multipliers: list[FloatArray] = []
        self.solved_counts = 0

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the solver's model (a plan's result travels to the figures'
        process): it is built again on the next solve."""
        return {**self.__dict__, "highs": None, "mode": ""}

    def _model(self) -> Any:
        """The HiGHS model, built on first use: the columns with their bounds, the rows, the
        count and goal rows (free until a solve sets them)."""
        import highspy

        if self.highs is not None:
            return self.highs
        pr, n_var, live = self.problem, self.n_var, self.live
        h = self.highs = highspy._core._Highs()  # the base class: no banner, no callbacks
        h.setOptionValue("output_flag", False)
        h.setOptionValue("solver", "simplex")
        # every model the same threads (HiGHS schedules its threads once per process); a large
        # one by the dual simplex's parallel variant: the search mostly waits for its bound
        h.setOptionValue("threads", LP_THREADS)
        h.setOptionValue("simplex_strategy", 2 if self.large else 1)
        h.setOptionValue("run_crossover", "on")  # a cold interior-point solve ends at a basis
        # a district's model is presolved first (its cold solve is minutes without); a small
        # one solves from the last basis
        h.setOptionValue("presolve", "on" if self.large else "off")
        lo = np.zeros(n_var)
        hi = np.ones(n_var)
        lo[list(self.required)] = 1.0
        hi[list(self.excluded)] = 0.0
        none = np.zeros(0, dtype=np.int32)
        h.addCols(n_var, np.zeros(n_var), lo, hi, 0, none, none, np.zeros(0))
        inf = highspy.kHighsInf
        _add_rows(h, self.a[: self.n_base], self.b[: self.n_base])
        sites = np.arange(pr.n_sites, dtype=np.int32)
        ys = np.arange(pr.n_sites, pr.n_sites + live.size, dtype=np.int32)
        h.addRows(
            2,
            np.array([-inf, -inf]),
            np.array([inf, inf]),
            sites.size + ys.size,
            np.array([0, sites.size], dtype=np.int32),
            np.concatenate([sites, ys]),
            np.concatenate([np.ones(sites.size), pr.weights[live]]),
        )
        if self.a.shape[0] > self.n_base:  # separated rows (a model built again)
            _add_rows(h, self.a[self.n_base :], self.b[self.n_base :])
        return h

    def add_cuts(self, cuts: CutRows) -> None:
        """Append non-cover cut rows to the relaxation (and to the solver's model, whose basis
        stays: the next solve starts from it). Earlier multipliers stay valid, with zero on
        the new rows."""
        if cuts.n_rows == 0:
            return
        m = _cut_matrix(cuts, self.y_of, self.n_var).tocsr()
        self.a = vstack([self.a, m]).tocsr()
        self.b = np.concatenate([self.b, np.zeros(cuts.n_rows)])
        self.cut_rows += cuts.n_rows
        self.separated_rows += cuts.n_rows
        if self.highs is not None:
            _add_rows(self.highs, m, np.zeros(cuts.n_rows))

    def _pairs_of(self, x: FloatArray) -> FloatArray:
        """[P] the y of a solution over every pair (zero for the pairs never covered)."""
        y = np.zeros(self.problem.n_pairs)
        n = self.problem.n_sites
        y[self.live] = x[n : n + self.live.size]
        return y

    def separate(self, x: FloatArray) -> CutRows:
        """One round of separation at the solution ``x``: the non-cover cuts it breaks
        (:func:`~ris_planner.planning.certify.district_cuts.separated_cuts`, at most
        :data:`CUTS_PER_ROUND`, over the pairs with y above :data:`SEPARATION_Y`), added."""
        y = self._pairs_of(x)
        pairs = self.live[y[self.live] > SEPARATION_Y]
        sep = separated_cuts(self.problem, pairs, y, x[: self.problem.n_sites], CUTS_PER_ROUND)
        self.add_cuts(sep.rows)
        return sep.rows

    @property
    def size(self) -> dict[str, int]:
        """The model's size: columns, rows (cuts and exclusive groups among them), nonzeros."""
        return {
            "columns": self.n_var,
            "rows": int(self.a.shape[0]) + 2,
            "cut_rows": self.cut_rows,
            "separated_rows": self.separated_rows,
            "exclusive_rows": self.conflict_rows,
            "nonzeros": int(self.a.nnz) + self.problem.n_sites + int(self.live.size),
        }

    def _solve(self) -> tuple[str, float, FloatArray, FloatArray, float]:
        h = self._model()
        t0 = time.perf_counter()
        # a large model without a basis (its first solve) by interior point, crossed over to a
        # basis; every later solve by the dual simplex from the last basis. The dual simplex
        # from nothing reached its time limit on the benchmark district's designed-beam model
        # (1.1 million nonzeros), which interior point solves in half a minute
        cold = self.large and not h.getBasis().valid
        h.setOptionValue("solver", "ipm" if cold else "simplex")
        # HiGHS' clock runs over the model's life: the limit is per solve
        h.setOptionValue("time_limit", float(h.getRunTime()) + LP_TIME_LIMIT_S)
        h.run()
        status = h.modelStatusToString(h.getModelStatus())
        sol = h.getSolution()
        x = np.asarray(sol.col_value, dtype=float)
        duals = np.asarray(sol.row_dual, dtype=float)
        if x.size != self.n_var or duals.size != self.a.shape[0] + 2:
            x, duals = np.zeros(self.n_var), np.zeros(self.a.shape[0] + 2)
        # in a's row order: the count and goal rows last
        nb = self.n_base
        duals = np.concatenate([duals[:nb], duals[nb + 2 :], duals[nb : nb + 2]])
        value = float(h.getInfo().objective_function_value)
        return status, value, x, duals, time.perf_counter() - t0

    @property
    def rounds(self) -> int:
        """Separation rounds per solved count and sizing question: :data:`SEPARATION_ROUNDS`,
        a large model's as many as :data:`SEPARATION_NONZEROS` over its nonzeros at build
        allow (at least one)."""
        return separation_rounds(self.base_nonzeros) if self.large else SEPARATION_ROUNDS

    @property
    def large(self) -> bool:
        """Whether the model is presolved and solved for a few counts only
        (:data:`SIMPLEX_MAX_NONZEROS`, :data:`LARGE_SOLVES`)."""
        return int(self.a.nnz) > SIMPLEX_MAX_NONZEROS

    def coverage(self, count: int) -> Relaxed:
        """An upper bound on the coverage of every layout of ``count`` sites: the least
        Lagrangian value at ``count`` over the multipliers of this solve and every earlier
        one (each is valid at any count). A large model solves only its first
        :data:`LARGE_SOLVES` counts."""
        import highspy

        n = self.problem.n_sites
        if self.live.size == 0:
            return Relaxed(0.0, 0.0, np.zeros(n), "no coverable pair", 0.0)
        status, z, seconds = "not solved: earlier multipliers", np.zeros(n), 0.0
        lp_value: float | None = None
        rounds = added = 0
        if not self.large or self.solved_counts < LARGE_SOLVES:
            h = self._model()
            if self.mode != "coverage":
                h.changeColsCost(self.n_var, np.arange(self.n_var, dtype=np.int32), -self.w)
                h.changeRowBounds(self.goal_row, -highspy.kHighsInf, highspy.kHighsInf)
                self.mode = "coverage"
            h.changeRowBounds(self.count_row, float(count), float(count))
            self.solved_counts += 1
            t0, before = time.perf_counter(), self.separated_rows
            # the last solve's status is the count's; each solve after the first is a round
            for rounds, (status, value, x, duals) in enumerate(self._solves()):  # noqa: B007
                self.multipliers.append(self._clipped(duals))
                lp_value, z = -value, x[:n]
            added = self.separated_rows - before
            seconds = time.perf_counter() - t0
        return Relaxed(self.bound_at(count), lp_value, z, status, seconds, rounds, added)

    def bound_at(self, count: int) -> float:
        """The least Lagrangian coverage bound at ``count`` over the stored multipliers
        (the coverable weight without any)."""
        bound = min(1.0, self.coverable_weight)
        for lam in self.multipliers:
            value = lagrangian_coverage(
                self.a,
                self.b,
                self.w,
                self._padded(lam),
                self.problem.n_sites,
                count,
                self.required,
                self.excluded,
            )
            bound = min(bound, value)
        return bound

    def _solves(
        self, rounds: int | None = None
    ) -> Iterator[tuple[str, float, FloatArray, FloatArray]]:
        """The model solved (status, objective, solution, row duals), then again after each
        round of separated cuts at the last solution (:meth:`separate`): ``rounds`` rounds
        (default :attr:`rounds`), fewer when no row is broken, and only from a solve that
        finished (:data:`OPTIMAL`: a solve stopped at its time limit leaves a point that is no
        guide, and solving again would take that limit again). A number fixed by the model,
        not a time budget: a plan's certificate is the same every run."""
        if rounds is None:
            rounds = self.rounds
        status, value, x, duals, _ = self._solve()
        yield status, value, x, duals
        for _ in range(rounds):
            if status != OPTIMAL:
                return
            if self.separate(x).n_rows == 0:
                return
            status, value, x, duals, _ = self._solve()
            yield status, value, x, duals

    def _clipped(self, duals: FloatArray) -> FloatArray:
        """The multipliers of a solve's row duals: a's rows, clipped to their sign."""
        return np.maximum(0.0, -duals[: self.a.shape[0]])

    def _padded(self, lam: FloatArray) -> FloatArray:
        """Multipliers of an earlier solve over today's rows (zero on the rows added since)."""
        return np.concatenate([lam, np.zeros(self.a.shape[0] - lam.size)])

    def count_from_bounds(self, goal: float) -> int:
        """The smallest count whose coverage bound (:meth:`bound_at`) reaches ``goal``: no
        layout of fewer sites reaches it, each smaller count's bound being below it."""
        n = self.problem.n_sites
        for count in range(len(set(self.required)), n + 1):
            if self.bound_at(count) >= goal:
                return count
        return n + 1

    def lower_count(self, goal: float) -> int | None:
        """The fewest sites any layout reaching coverage ``goal`` can have: the larger of the
        first count whose coverage bound reaches it (:meth:`count_from_bounds`) and the
        Lagrangian lower bound of min Σ z subject to the goal, solved with its own separation
        rounds (a large model too: on the benchmark district 81–83 against 74–76 from the
        bounds), rounded up by :func:`certified_count`; ``None`` when no layout reaches it (the
        coverable pairs weigh less)."""
        import highspy

        pr = self.problem
        if self.coverable_weight < goal - 1e-12:
            return None
        from_bounds = self.count_from_bounds(goal) if self.multipliers else len(self.required)
        h = self._model()
        if self.mode != "count":
            cost = np.zeros(self.n_var)
            cost[: pr.n_sites] = 1.0
            h.changeColsCost(self.n_var, np.arange(self.n_var, dtype=np.int32), cost)
            h.changeRowBounds(self.count_row, 0.0, highspy.kHighsInf)
            if self.large and self.mode == "coverage" and self.solved_counts > 1:
                # after two counts their basis is far from this objective's optimum: interior
                # point from nothing is faster than the simplex from it (after one, slower:
                # :data:`LP_THREADS`)
                h.clearSolver()
            self.mode = "count"
        h.changeRowBounds(self.goal_row, float(goal), highspy.kHighsInf)
        best = -math.inf
        for _, _, _, duals in self._solves():
            nu = max(0.0, float(duals[-1]))  # the goal row's
            value = lagrangian_count(
                self.a,
                self.b,
                self.w,
                self._clipped(duals),
                nu,
                goal,
                pr.n_sites,
                self.required,
                self.excluded,
            )
            best = max(best, value)
        return max(len(self.required), certified_count(best), from_bounds)


def _add_rows(h: Any, a: csr_matrix, b: FloatArray) -> None:
    """Rows ``a x ≤ b`` appended to the HiGHS model ``h``."""
    import highspy

    a = a.tocsr()
    h.addRows(
        a.shape[0],
        np.full(a.shape[0], -highspy.kHighsInf),
        b,
        a.nnz,
        a.indptr[:-1].astype(np.int32),
        a.indices.astype(np.int32),
        a.data,
    )


def _cut_matrix(cuts: CutRows, y_of: IntArray, n_var: int) -> csr_matrix:
    """The cut rows over the relaxation's variables."""
    r = cuts.n_rows
    per = np.diff(cuts.start)
    rows = np.concatenate([np.arange(r), np.repeat(np.arange(r), per)])
    cols = np.concatenate([y_of[cuts.pair], cuts.site])
    vals = np.concatenate([cuts.y_coef, -cuts.coef])
    return csr_matrix((vals, (rows, cols)), shape=(r, n_var))


def exclusive_groups(conflict: BoolArray) -> list[list[int]]:
    """Groups of mutually exclusive sites (cliques of ``conflict``) that hold every
    conflicting pair: each uncovered conflict grown greedily into a clique. Σ_{s∈group} z_s ≤ 1
    holds for every feasible layout."""
    left = np.triu(conflict, 1).copy()
    groups: list[list[int]] = []
    for a, b in zip(*np.nonzero(left), strict=True):
        if not left[a, b]:
            continue
        group = [int(a), int(b)]
        common = conflict[a] & conflict[b]
        for c in np.flatnonzero(common).tolist():
            if conflict[c, group].all():
                group.append(c)
        for i, j in itertools.combinations(sorted(group), 2):
            left[i, j] = False
        groups.append(sorted(group))
    return groups


def _pad(*terms: FloatArray) -> float:
    """An upper bound on the float64 rounding of summing ``terms``' entries and forming them
    (each a dot product of at most that many products): n·ε·Σ|term|."""
    n = sum(t.size for t in terms) + 1
    return float(n * np.finfo(float).eps * sum(np.abs(t).sum() for t in terms)) + 1e-300


def lagrangian_coverage(
    a: csr_matrix,
    b: FloatArray,
    w: FloatArray,
    lam: FloatArray,
    n_sites: int,
    count: int,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """An upper bound on max w·x over x ∈ [0, 1]ⁿ with A x ≤ b and exactly ``count`` of the
    first ``n_sites`` columns (the z) at one – required ones at one, excluded at zero – for
    any multipliers ``lam`` ≥ 0: the Lagrangian λ·b + Σ_j max(0, r_j) over the other columns
    plus the ``count`` best z terms r_s (r = w − Aᵀλ), which every feasible x stays below.
    Padded by its own rounding (:func:`_pad`); ``inf`` when no layout of that count exists."""
    lam = np.maximum(lam, 0.0)
    at_lam = a.T @ lam
    r = w - at_lam
    zr = r[:n_sites]
    fixed = np.zeros(n_sites, dtype=bool)
    fixed[list(required)] = True
    free = ~fixed
    free[list(excluded)] = False
    take = count - len(set(required))
    if take < 0 or take > int(free.sum()):
        return math.inf
    best = np.sort(zr[free])[::-1][:take]
    rest = np.maximum(r[n_sites:], 0.0)
    terms = (lam * b, rest, zr[fixed], best)
    value = float(sum(float(t.sum()) for t in terms))
    return value + _pad(*terms, w, at_lam)


def lagrangian_count(
    a: csr_matrix,
    b: FloatArray,
    w: FloatArray,
    lam: FloatArray,
    nu: float,
    goal: float,
    n_sites: int,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """A lower bound on min Σ z (the first ``n_sites`` columns) over x ∈ [0, 1]ⁿ with
    A x ≤ b and w·x ≥ ``goal`` – required z at one, excluded at zero – for any multipliers
    ``lam`` ≥ 0, ``nu`` ≥ 0: ν·goal − λ·b + Σ_j min(0, c_j + (Aᵀλ)_j − ν w_j) (c_j = 1 on the
    z, 0 else; required sites at their term, excluded ones out). Less its own rounding."""
    lam = np.maximum(lam, 0.0)
    nu = max(nu, 0.0)
    at_lam = a.T @ lam
    c = np.zeros(w.size)
    c[:n_sites] = 1.0
    r = c + at_lam - nu * w
    fixed = np.zeros(w.size, dtype=bool)
    fixed[list(required)] = True
    out = np.zeros(w.size, dtype=bool)
    out[list(excluded)] = True
    free = ~fixed & ~out
    terms = (np.array([nu * goal]), -lam * b, r[fixed], np.minimum(r[free], 0.0))
    value = float(sum(float(t.sum()) for t in terms))
    return value - _pad(*terms, at_lam, nu * w)


COUNT_ROUNDING = 1e-6
""":func:`certified_count` rounds a lower bound on a count up after taking this off: a value
within it above an integer is that integer (rounding noise), never the next one."""


def certified_count(value: float) -> int:
    """The smallest integer count ≥ a lower bound ``value`` on it: ⌈value − 1e-6⌉
    (:data:`COUNT_ROUNDING`), so a bound a rounding error above an integer is not lifted past
    it; 0 for a value at or below 0."""
    if not math.isfinite(value):
        return 0 if value < 0 else 10**9
    return max(0, math.ceil(value - COUNT_ROUNDING))


SIMPLEX_MAX_NONZEROS = 200_000
"""Up to this many nonzeros :class:`DistrictRelaxation` solves each count by dual simplex from
the last basis (warm starts across counts); above, it presolves first and solves only
:data:`LARGE_SOLVES` counts."""

COUNTING_ROW_SITES = 64
"""With the non-cover cuts, only pairs with at most this many serving sites keep their
counting row m_p·y_p ≤ Σ_{S_p} z (the others' rows, a district's millions of nonzeros, are
weaker than their cuts where the relaxation spreads z over their strong sets)."""

LARGE_SOLVES = 2
"""Above :data:`SIMPLEX_MAX_NONZEROS`, the coverage relaxation is solved for at most this many
counts; every other count's bound is the Lagrangian value of the multipliers of those solves
(valid at any count: :meth:`DistrictRelaxation.coverage`). The sizing question is solved as
well (:meth:`DistrictRelaxation.lower_count`)."""

SEPARATION_ROUNDS = 4
"""Per solved count (and per sizing question), the most rounds of separated non-cover cuts
(:meth:`DistrictRelaxation.separate`) added and solved again; each round's multipliers are
one more Lagrangian bound (the least is kept)."""

SEPARATION_NONZEROS = 1_600_000
"""A large model (:data:`SIMPLEX_MAX_NONZEROS`) separates as many rounds per solved count and
sizing question as this many nonzeros over its own at build allow, at least one and at most
:data:`SEPARATION_ROUNDS` (:attr:`DistrictRelaxation.rounds`): one on the benchmark district
(0.85–1.1 million nonzeros), where each re-solve takes 25–65 s and a second round at 40 RISs
brought the bound from 0.820 to 0.811 for about 30 s more; four on a district of 5 000 pairs. A
number fixed by the model, not a time budget: the budget of 20 s before it let the same
document get one round at 40 RISs in one run and two in the next (a lower count of 81 or 83);
now a plan's certificate is the same every run."""


def separation_rounds(nonzeros: int) -> int:
    """The separation rounds of a large model of ``nonzeros`` at build
    (:data:`SEPARATION_NONZEROS`): between one and :data:`SEPARATION_ROUNDS`."""
    return min(SEPARATION_ROUNDS, max(1, SEPARATION_NONZEROS // max(nonzeros, 1)))


OPTIMAL = "Optimal"
"""HiGHS' status string of a solve that finished (:meth:`DistrictRelaxation.coverage`
separates only at such a point)."""

CUTS_PER_ROUND = 4000
"""The most separated rows one round adds (the most violated × pair weight first)."""

SEPARATION_Y = 1e-6
"""Separation looks at the pairs whose y exceeds this in the relaxation's solution."""

LP_THREADS = 2
"""Threads of every district model's HiGHS solves. A large model (:data:`SIMPLEX_MAX_NONZEROS`)
re-solves by the parallel dual simplex (PAMI) on them: 19–21 % off the serial dual simplex on
the benchmark district's models. Its sizing question after two or more counts starts again by
interior point (24 s against 17 s + a slower round on the headline, 35 s against 65 s on the
designed-beam model); after one count it re-solves from that count's basis (6–24 s against
49–50 s from nothing) (docs/validation/benchmarks.md, "Faster LP solves")."""

LP_TIME_LIMIT_S = 120.0
"""Seconds one solve of :class:`DistrictRelaxation` may take; a solve stopped there still
gives a valid (looser) bound through its multipliers."""


def build_relaxation(
    problem: DistrictProblem,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    conflict: BoolArray | None = None,
) -> DistrictRelaxation:
    """The :class:`DistrictRelaxation` of a problem with its static non-cover cuts
    (:func:`~ris_planner.planning.certify.district_cuts.static_cuts`)."""
    cuts = static_cuts(problem, needs.need)
    return DistrictRelaxation(problem, needs, required, excluded, conflict, cuts.rows)


def coverage_upper_bound(
    problem: DistrictProblem,
    count: int,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> float:
    """An upper bound on the coverage of every layout of ``count`` sites (a model of its own:
    :class:`DistrictRelaxation`)."""
    return build_relaxation(problem, needs, required, excluded).coverage(count).bound


def count_lower_bound(
    problem: DistrictProblem,
    target: float,
    needs: Needs,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
) -> int | None:
    """The fewest sites any layout reaching coverage ``target`` can have (a model of its own:
    :meth:`DistrictRelaxation.lower_count`); ``None`` when no layout reaches it."""
    if float(problem.weights[needs.need > 0].sum()) < target - 1e-12:
        return None
    return build_relaxation(problem, needs, required, excluded).lower_count(target)


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
