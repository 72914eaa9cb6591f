"""The district certificate (docs/concepts/district.md, "The certificate") against brute force
on the suite's street site: no non-cover cut cuts off a covering layout, the Lagrangian bound
holds for any multipliers and equals the relaxation's value at its own, the persistent model
answers as a rebuilt one, and the sizing's lower count never exceeds the true minimum."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from district_site import every_layout, street_doc
from tolerance import assert_close

from ris_planner.planning.certify import district_cuts as cuts
from ris_planner.planning.certify import district_lp as lp
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.scoring import sparse


@pytest.fixture(scope="module", params=[0.5, 2.0])
def truth(request: pytest.FixtureRequest):
    """The street site's problem, its needs and, per layout of every size, each pair's
    coverage (all 2^14 layouts: the brute-force truth)."""
    problem = sparse.build_problem(prepare_plan(street_doc(threshold_m=request.param)))
    needs = lp.sites_needed(problem)
    layouts, covered = every_layout(problem)
    return problem, needs, layouts, covered


def best_by_count(problem, layouts, covered) -> dict[int, float]:
    cov = covered @ problem.weights
    out: dict[int, float] = {}
    for lay, c in zip(layouts, cov, strict=True):
        out[len(lay)] = max(out.get(len(lay), 0.0), float(c))
    return out


def test_no_cut_cuts_off_a_covering_layout(truth) -> None:
    """Every static cut (and every counting row) holds at y = 1 for every layout that covers
    its pair: the cuts only remove fractional points."""
    problem, needs, layouts, covered = truth
    static = cuts.static_cuts(problem, needs.need)
    assert static.rows.n_rows > 0
    assert (static.rows.y_coef == 2).any() or (static.rows.y_coef == 1).all()
    for rows in (static.rows, cuts.counting_rows(problem, needs.need)):
        for lay, cov in zip(layouts, covered, strict=True):
            z = np.zeros(problem.n_sites)
            z[list(lay)] = 1.0
            assert not cuts.violated(rows, cov.astype(float), z).any(), lay


def test_the_strong_set_is_all_a_covering_layout_needs_one_of(truth) -> None:
    """A pair's strong set (the complement of its longest non-covering prefix) meets every
    layout that covers it, and the prefix itself leaves it uncovered."""
    problem, needs, layouts, covered = truth
    static = cuts.static_cuts(problem, needs.need)
    rows = static.rows
    for r in range(rows.n_rows):
        p = int(rows.pair[r])
        strong = set(rows.site[rows.start[r] : rows.start[r + 1]].tolist())
        assert len(strong) == static.strong[p]
        weak = sorted(set(problem.sites_of(p).tolist()) - strong)
        assert not sparse.LayoutState(problem, weak).metric[p] <= problem.threshold
        for lay, cov in zip(layouts, covered, strict=True):
            if cov[p]:
                assert strong & set(lay), (p, lay)


def test_the_bound_holds_for_every_count_and_any_multipliers(truth) -> None:
    """The Lagrangian bound of the model's own multipliers is at least the exhaustive optimum
    of every count and within 1e-6 of the solver's value; random multipliers give valid,
    looser bounds."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    model = lp.build_relaxation(problem, needs)
    rng = np.random.default_rng(0)
    for count in range(1, problem.n_sites + 1):
        got = model.coverage(count)
        assert got.bound >= best[count] - 1e-12, count
        assert got.lp_value is not None
        assert got.bound <= got.lp_value + 1e-6 or got.bound >= min(1.0, model.coverable_weight)
        for _ in range(5):
            lam = rng.exponential(rng.choice([1e-3, 1e-1, 1.0]), size=model.a.shape[0])
            ub = lp.lagrangian_coverage(model.a, model.b, model.w, lam, problem.n_sites, count)
            assert ub >= best[count] - 1e-12
            assert ub >= got.lp_value - 1e-6  # no multipliers beat the relaxation's optimum


def test_the_persistent_model_answers_as_a_rebuilt_one(truth, monkeypatch) -> None:
    """Counts solved one after another in one model (and the sizing question between them)
    give the bounds of a model built for each; with separation, the persistent model keeps
    every earlier count's separated rows (its bound differs from a rebuilt model's, the rows
    depending on the points separated) and both stay at least the exhaustive optimum."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    for rounds in (0, lp.SEPARATION_ROUNDS):
        monkeypatch.setattr(lp, "SEPARATION_ROUNDS", rounds)
        model = lp.build_relaxation(problem, needs)
        goal = 0.5 * model.coverable_weight
        for count in (3, 1, 5, 2):
            again = model.coverage(count).bound
            model.lower_count(goal)
            fresh = lp.build_relaxation(problem, needs).coverage(count).bound
            if rounds == 0:
                assert again == pytest.approx(fresh, abs=1e-7)
            else:
                assert min(again, fresh) >= best[count] - 1e-12, count


def test_the_lower_count_never_exceeds_the_minimum(truth) -> None:
    """For goals across the coverable weight, the certified lower count is at most the
    fewest sites of any layout reaching the goal (brute force), and ``None`` exactly when no
    layout does."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    model = lp.build_relaxation(problem, needs)
    for share in (0.1, 0.3, 0.5, 0.7, 0.9, 1.0):
        goal = share * model.coverable_weight
        fewest = min(k for k, v in best.items() if v >= goal - 1e-12)
        lower = model.lower_count(goal)
        assert lower is not None and lower <= fewest, (share, lower, fewest)
    assert model.separated_rows > 0  # the sizing question's own separation rounds ran


def test_required_excluded_and_exclusive_sites_keep_the_bound(truth) -> None:
    """With a required site, an excluded one and two sites on one mounting point, the bound
    still holds over the layouts that honour them."""
    problem, needs, layouts, covered = truth
    conflict = np.zeros((problem.n_sites, problem.n_sites), dtype=bool)
    conflict[2, 3] = conflict[3, 2] = True
    model = lp.build_relaxation(problem, needs, (0,), (1,), conflict)
    assert model.size["exclusive_rows"] == 1
    cov = covered @ problem.weights
    for count in range(1, 6):
        ok = [
            c
            for lay, c in zip(layouts, cov, strict=True)
            if len(lay) == count and 0 in lay and 1 not in lay and not {2, 3} <= set(lay)
        ]
        assert model.coverage(count).bound >= max(ok) - 1e-12


def test_exclusive_groups_hold_every_conflict() -> None:
    conflict = np.zeros((6, 6), dtype=bool)
    for a, b in [(0, 1), (1, 2), (0, 2), (4, 5)]:
        conflict[a, b] = conflict[b, a] = True
    groups = lp.exclusive_groups(conflict)
    assert sorted(map(sorted, groups)) == [[0, 1, 2], [4, 5]]


def test_counts_round_up_without_crossing_an_integer() -> None:
    assert lp.certified_count(3.0000000001) == 3
    assert lp.certified_count(2.9999999) == 3
    assert lp.certified_count(3.01) == 4
    assert lp.certified_count(-0.5) == 0


def small_site_problems(n: int):
    """The first ``n`` random small sites of the search-quality suite (tests/search_quality.py)
    as coverage plans for the district search (PEB_R ≤ 0.3 m; their own candidates, pairs,
    LOS and known parts)."""
    from search_quality import quality_instance

    for seed in range(n):
        doc = quality_instance(seed)
        doc["objective"] = {"kind": "coverage", "metric": "rx", "threshold_m": 0.3}
        doc["search"] = {"method": "district"}
        yield seed, sparse.build_problem(prepare_plan(doc))


def test_random_small_sites_bound_size_and_search_against_exhaustive_truth() -> None:
    """On random small sites, every count 2–4: the certified bound (with separated cuts) is at
    least the exhaustive optimum and the lower count for half the coverable weight at most the
    true minimum (always); the district search's layout is within 1 % of the optimum in at
    least 95 % of the counts."""
    from ris_planner.planning.search import district as search

    within = total = separated = 0
    for seed, problem in small_site_problems(6):
        needs = lp.sites_needed(problem)
        model = lp.build_relaxation(problem, needs)
        every = [
            (k, sparse.exact_coverage(problem, c))
            for k in range(1, 5)
            for c in itertools.combinations(range(problem.n_sites), k)
        ]
        best = {k: max(v for kk, v in every if kk == k) for k in range(1, 5)}
        path = search.greedy_path(problem, 4)
        for count in (2, 3, 4):
            assert model.coverage(count).bound >= best[count] - 1e-12, (seed, count)
            step = next((p for p in path if len(p.sites) == count), None)
            found = 0.0 if step is None else search.improve(problem, step.sites)[1]
            total += 1
            within += found >= best[count] - 0.01 * best[count]
        goal = 0.5 * model.coverable_weight
        reach = [k for k, v in best.items() if v >= goal - 1e-12]
        if goal > 0 and reach:
            lower = model.lower_count(goal)
            assert lower is not None and lower <= min(reach), seed
        separated += model.separated_rows
    assert within >= 0.95 * total, (within, total)
    assert separated > 0


def test_a_large_model_bounds_every_count_from_a_few_solves(truth, monkeypatch) -> None:
    """Above the simplex size only the first counts are solved: every other count's bound and
    the lower count come from their multipliers, and still hold against brute force."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    monkeypatch.setattr(lp, "SIMPLEX_MAX_NONZEROS", 0)
    model = lp.build_relaxation(problem, needs)
    assert model.large
    solved = [model.coverage(c) for c in (3, 5)]
    assert all(r.lp_value is not None for r in solved)
    for count in range(1, problem.n_sites + 1):
        got = model.coverage(count)
        assert got.lp_value is None and got.bound >= best[count] - 1e-12
    for share in (0.3, 0.6, 0.9):
        goal = share * model.coverable_weight
        fewest = min(k for k, v in best.items() if v >= goal - 1e-12)
        lower = model.lower_count(goal)
        assert lower is not None and lower <= fewest


@pytest.mark.parametrize("wavefront", ["planar", "spherical"])
def test_prefix_bounds_by_the_square_root_rows_are_the_layouts(
    wavefront: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cuts' prefix bounds where the LDLᵀ does not settle a matrix (every matrix here:
    the square-root rows of the prefix, 3 per entry planar and 7 spherical) equal the bound
    of the layout of the prefix's sites – a spherical district's cuts broke on the row count
    before (benchmark district, 20 000 pairs)."""
    from ris_planner.inversion import crb

    doc = street_doc(threshold_m=1.0)
    doc["system"] = {**doc.get("system", {}), "wavefront": wavefront}
    problem = sparse.build_problem(prepare_plan(doc))
    monkeypatch.setattr(crb, "FAST_TRACE_LIMIT", -1.0)  # every matrix by its rows
    pairs = np.flatnonzero(np.diff(problem.pair_start) >= 2)[:20]
    order = np.arange(problem.n_entries)
    pre = cuts._Prefixes(problem, pairs, order)
    j = np.minimum(pre.n, 2)
    got = pre.metric(np.arange(pairs.size), j)
    for a, p in enumerate(pairs.tolist()):
        sites = problem.entry_site[problem.pair_start[p] : problem.pair_start[p] + j[a]]
        want = sparse.LayoutState(problem, sorted(sites.tolist())).metric[p]
        if np.isinf(want):
            assert np.isinf(got[a])
        else:
            assert_close(got[a], want)


def _dense(rows: cuts.CutRows, n_sites: int) -> np.ndarray:
    """[R, S] the rows' site coefficients."""
    m = np.zeros((rows.n_rows, n_sites))
    r = np.repeat(np.arange(rows.n_rows), np.diff(rows.start))
    np.add.at(m, (r, rows.site), rows.coef)
    return m


def test_no_separated_cut_cuts_off_a_covering_layout(truth, monkeypatch) -> None:
    """The cuts separated at the relaxation's points of every count and at random points (many
    different non-covering sets U) hold at y = 1 for every layout that covers their pair
    (all 2^14 layouts), and U itself (a few per point) leaves its pair uncovered."""
    problem, needs, layouts, covered = truth
    monkeypatch.setattr(lp, "SEPARATION_ROUNDS", 0)
    model = lp.build_relaxation(problem, needs)
    live = model.live
    found = []
    for count in range(1, problem.n_sites + 1):
        model.coverage(count)
        h = model._model()
        x = np.asarray(h.getSolution().col_value)
        y = model._pairs_of(x)
        found.append(cuts.separated_cuts(problem, live, y, x[: problem.n_sites], 10**6).rows)
    rng = np.random.default_rng(1)
    for _ in range(10):
        z = rng.random(problem.n_sites) * rng.choice([0.1, 0.5, 1.0])
        y = np.ones(problem.n_pairs)
        found.append(cuts.separated_cuts(problem, live, y, z, 10**6).rows)
    assert sum(r.n_rows for r in found) > 50
    z_all = np.zeros((len(layouts), problem.n_sites))
    for i, lay in enumerate(layouts):
        z_all[i, list(lay)] = 1.0
    for rows in found:
        rhs = z_all @ _dense(rows, problem.n_sites).T  # [layouts, rows]
        lhs = covered[:, rows.pair] * rows.y_coef
        assert (lhs <= rhs + 1e-12).all()
        for r in range(min(rows.n_rows, 4)):  # U = the pair's serving sites outside the row
            p = int(rows.pair[r])
            outside = set(rows.site[rows.start[r] : rows.start[r + 1]].tolist())
            u = sorted(set(problem.sites_of(p).tolist()) - outside)
            assert not sparse.LayoutState(problem, u).metric[p] <= problem.threshold


def test_separation_tightens_the_bound_and_keeps_it_valid(truth, monkeypatch) -> None:
    """On the street site, the bound with separated cuts is strictly below the static cuts'
    at one RIS and at least the exhaustive optimum at every count."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    monkeypatch.setattr(lp, "SEPARATION_ROUNDS", 0)
    static = [lp.build_relaxation(problem, needs).coverage(c).bound for c in (1, 3)]
    monkeypatch.setattr(lp, "SEPARATION_ROUNDS", 4)
    model = lp.build_relaxation(problem, needs)
    got = {c: model.coverage(c) for c in range(1, problem.n_sites + 1)}
    assert got[1].bound < static[0] - 1e-3
    assert got[3].bound <= static[1] + 1e-9
    assert any(r.cut_rounds > 0 for r in got.values()) and model.separated_rows > 0
    for c, r in got.items():
        assert r.bound >= best[c] - 1e-12, c


def test_a_large_model_starts_by_interior_point(truth, monkeypatch) -> None:
    """A large model's first solve runs interior point (crossed over to a basis), the next
    the parallel dual simplex from that basis; both bounds equal the small model's simplex
    bounds (the LP optimum: HiGHS' optimality tolerances are 1e-7) and stay above brute force.
    Its sizing question after two counts starts again by interior point (a new objective), after
    one from that count's basis, and both give the small model's lower count."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    monkeypatch.setattr(lp, "SEPARATION_ROUNDS", 0)  # the same rows in both models
    small = lp.build_relaxation(problem, needs)
    assert not small.large
    want = [small.coverage(c).bound for c in (2, 3)]
    monkeypatch.setattr(lp, "SIMPLEX_MAX_NONZEROS", 0)
    large = lp.build_relaxation(problem, needs)
    assert large.large
    got, ipm = [], []
    for c in (2, 3):
        got.append(large.coverage(c))
        ipm.append(large.highs.getInfo().ipm_iteration_count)
    assert ipm[0] > 0 and ipm[1] == 0
    assert all(r.status == lp.OPTIMAL for r in got)
    assert_close([r.bound for r in got], want, accuracy=1e-6)
    for c, r in zip((2, 3), got, strict=True):
        assert r.bound >= best[c] - 1e-12
    for h, strategy in ((small.highs, 1), (large.highs, 2)):
        assert h.getOptionValue("simplex_strategy")[1] == strategy
        assert h.getOptionValue("threads")[1] == lp.LP_THREADS
    goal = 0.6 * large.coverable_weight
    lower = large.lower_count(goal)
    assert large.highs.getInfo().ipm_iteration_count > 0  # after two counts: from nothing
    assert lower == small.lower_count(goal)
    one = lp.build_relaxation(problem, needs)
    one.coverage(2)
    assert one.lower_count(goal) == lower
    assert one.highs.getInfo().ipm_iteration_count == 0  # after one: from its basis
    assert lower is not None and lower <= min(k for k, v in best.items() if v >= goal - 1e-12)


def test_a_large_model_takes_its_fixed_rounds_whatever_the_clock(truth, monkeypatch) -> None:
    """A large model separates up to its :attr:`rounds` per solved count and sizing question
    (:data:`SEPARATION_NONZEROS` over its nonzeros, at least one) – a number, not a time
    budget, so a plan's certificate is the same every run: with a clock that jumps a minute at
    every look the rounds, bounds and lower count stay those of a model on the real clock, and
    the bounds stay above brute force."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    monkeypatch.setattr(lp, "SIMPLEX_MAX_NONZEROS", 0)
    nonzeros = lp.build_relaxation(problem, needs).base_nonzeros
    for budget, want in ((0, 1), (2 * nonzeros, 2), (100 * nonzeros, lp.SEPARATION_ROUNDS)):
        monkeypatch.setattr(lp, "SEPARATION_NONZEROS", budget)
        assert lp.build_relaxation(problem, needs).rounds == want
    monkeypatch.setattr(lp, "SEPARATION_NONZEROS", 2 * nonzeros)
    runs = []
    for slow in (False, True):
        if slow:
            ticks = itertools.count()
            monkeypatch.setattr(lp.time, "perf_counter", lambda t=ticks: 60.0 * next(t))
        model = lp.build_relaxation(problem, needs)
        got = [model.coverage(c) for c in (1, 2)]
        lower = model.lower_count(0.6 * model.coverable_weight)
        runs.append(([r.cut_rounds for r in got], [r.bound for r in got], lower))
    assert max(runs[0][0]) >= 1 and max(runs[0][0]) <= 2
    assert runs[0][0] == runs[1][0] and runs[0][2] == runs[1][2]
    assert_close(runs[0][1], runs[1][1], accuracy=1e-9)
    for c, bound in zip((1, 2), runs[1][1], strict=True):
        assert bound >= best[c] - 1e-12


def test_no_separation_after_a_solve_stopped_early(truth, monkeypatch) -> None:
    """A solve that did not finish (its time limit) is not separated from and not solved
    again – its point is no guide and a re-solve would take the limit again – for a count
    and for the sizing question; its multipliers still give a valid bound."""
    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    model = lp.build_relaxation(problem, needs)
    solve = model._solve
    solves = []

    def stopped() -> tuple:
        status, *rest = solve()
        assert status == lp.OPTIMAL  # the street site's model solves: the status is the mock's
        solves.append(status)
        return ("Time limit reached", *rest)

    monkeypatch.setattr(model, "_solve", stopped)
    got = model.coverage(2)
    assert got.cut_rounds == 0 and model.separated_rows == 0 and len(solves) == 1
    assert got.status == "Time limit reached" and got.bound >= best[2] - 1e-12
    goal = 0.5 * best[3]
    lower = model.lower_count(goal)
    assert len(solves) == 2 and model.separated_rows == 0
    assert lower is not None and lower <= 3


def test_a_pickled_model_keeps_its_separated_rows(truth) -> None:
    """A model pickled after separation (a plan's result travels to the figures' process) is
    built again with the separated rows after the count and goal rows; its bounds keep the
    earlier multipliers (never above the bounds before) and stay above brute force."""
    import pickle

    problem, needs, layouts, covered = truth
    best = best_by_count(problem, layouts, covered)
    model = lp.build_relaxation(problem, needs)
    before = [model.coverage(c).bound for c in (2, 3)]
    assert model.separated_rows > 0
    again = pickle.loads(pickle.dumps(model))
    assert again.highs is None and again.a.shape == model.a.shape
    after = [again.coverage(c).bound for c in (2, 3)]
    for c, b, a in zip((2, 3), before, after, strict=True):
        assert best[c] - 1e-12 <= a <= b + 1e-12
