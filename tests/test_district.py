"""The district search (docs/concepts/district.md): its coverage against exhaustive search and
against compute_bounds, its certificate against the exhaustive optimum, m_p against a
brute-force enumeration, sizing and the command line."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from district_site import every_layout, street_doc
from tolerance import BOUND_ACCURACY, assert_close
from waits import HANG_S

from ris_planner.bounds.compute import compute_bounds
from ris_planner.core.errors import RisPlannerError
from ris_planner.model.plan import PlanDocument
from ris_planner.planning import district_plan
from ris_planner.planning.beams import layout_scenario
from ris_planner.planning.certify import district_lp as lp
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.resources.admission import resolve_search, validate_plan
from ris_planner.planning.scoring import sparse
from ris_planner.planning.search import district as search


@pytest.fixture(scope="module", params=[0.5, 2.0])
def site(request: pytest.FixtureRequest) -> tuple[dict, sparse.DistrictProblem, lp.Needs]:
    doc = street_doc(threshold_m=request.param)
    inputs = prepare_plan(doc)
    problem = sparse.build_problem(inputs)
    return doc, problem, lp.sites_needed(problem)


def test_district_reaches_the_exhaustive_optimum_and_its_bound_holds(site) -> None:
    doc, problem, needs = site
    exact = run_plan({**doc, "search": {"method": "exhaustive"}})
    path = search.greedy_path(problem, 3)
    for cr in exact.counts:
        best = -cr.ranked[0][1]  # the search's loss is −coverage
        _, cov = search.improve(problem, path[cr.ris_count - 1].sites)
        assert cov >= best - 0.01  # within 1 % of the optimum
        assert cov <= best + BOUND_ACCURACY
        assert lp.coverage_upper_bound(problem, cr.ris_count, needs) >= best - 1e-9


def test_district_coverage_is_the_bounds_engines(site) -> None:
    """The coverage the district search reports for a layout equals the weighted fraction of
    compute_bounds' PEB_R within the threshold (the environment's paths from the scene)."""
    doc, problem, _ = site
    inputs = prepare_plan(doc)
    layout, cov = search.improve(problem, search.greedy_path(problem, 3)[-1].sites)
    d = inputs.document
    ris = [inputs.sites[s].ris for s in layout]
    scenario = layout_scenario(d.system, ris, list(d.known), d.environment)
    res = compute_bounds(scenario, inputs.pairs.tx, inputs.pairs.rx, profiles=None)
    state = sparse.LayoutState(problem, list(layout))
    fin = np.isfinite(res.peb_rx)
    assert np.array_equal(fin, np.isfinite(state.metric))
    assert_close(state.metric[fin], res.peb_rx[fin], accuracy=BOUND_ACCURACY)
    want = float(inputs.pairs.weights[res.peb_rx <= d.objective.threshold_m].sum())
    assert abs(cov - want) <= 2 / inputs.pairs.size  # a pair at the threshold within 1e-6


def test_sites_needed_is_a_valid_lower_bound(site) -> None:
    """No layout with fewer than m_p of a pair's serving sites covers it (every subset tried);
    a pair with m_p = 0 is above the threshold even with all of them."""
    _, problem, needs = site
    need = needs.need
    rng = np.random.default_rng(0)
    for p in rng.choice(problem.n_pairs, size=40, replace=False):
        sites = problem.sites_of(int(p)).tolist()
        # the pair's own entries only: its metric is the full problem's, the others stay blind
        alone = problem.kept(np.arange(problem.pair_start[p], problem.pair_start[p + 1]))
        every = sparse.LayoutState(alone, sites).metric[p]  # the same sums, one inversion
        assert_close(every, sparse.LayoutState(problem, sites).metric[p], accuracy=BOUND_ACCURACY)
        smaller = range(len(sites) + 1) if need[p] == 0 else range(int(need[p]))
        for m in smaller:
            for sub in itertools.combinations(sites, m):
                st = sparse.LayoutState(alone, list(sub))
                assert not st.metric[p] <= problem.threshold, (p, sub, need[p])


def test_the_subset_budget_keeps_the_bound_valid(site, monkeypatch: pytest.MonkeyPatch) -> None:
    """With a small budget of (pair, subset) evaluations only the pairs with the fewest subsets
    get their cover sets (the others keep the counting rule's m_p): m_p never rises above the
    full evaluation's, the cover sets are a subset of the full ones, and the relaxation still
    bounds the exhaustive optimum."""
    doc, problem, full = site
    n_serving = np.diff(problem.pair_start)
    monkeypatch.setattr(lp, "MAX_SUBSET_EVALUATIONS", int(n_serving.sum() // 4))
    few = lp.sites_needed(problem)
    assert 0 < few.complete.sum() < full.complete.sum()
    assert np.all(few.need <= full.need) and np.all(few.complete <= full.complete)
    # the pairs that got their subsets have no more serving sites than those that did not
    live = (full.need > 0) & (n_serving >= full.need)
    assert n_serving[few.complete].max() <= n_serving[live & ~few.complete].max()
    exact = run_plan({**doc, "search": {"method": "exhaustive"}})
    for cr in exact.counts:
        best = -cr.ranked[0][1]
        assert lp.coverage_upper_bound(problem, cr.ris_count, few) >= best - 1e-9


def test_sizing_answers_with_a_certified_count(site) -> None:
    _, problem, needs = site
    goal = 0.5 * float(problem.weights[needs.need > 0].sum())
    path = search.greedy_path(problem, problem.n_sites, target=goal)
    lower = lp.count_lower_bound(problem, goal, needs)
    assert lower is not None
    assert path[-1].coverage >= goal - 1e-12
    assert 1 <= lower <= len(path[-1].sites)
    # every count below the certified one: its upper bound is below the goal
    assert lp.coverage_upper_bound(problem, lower - 1, needs) < goal + 1e-6


def test_fewer_sites_never_claims_fewer_than_brute_force(site) -> None:
    """The sizing's descent below the greedy path's answer (:func:`search.fewer_sites`): every
    layout tried has the count it was tried at, fewer sites than the path's answer and its
    exact coverage (re-scored with every serving site, also when the search saw each pair's
    two strongest); one that reaches the goal never has fewer sites than the exhaustive
    minimum – and on this site the descent finds fewer than the path for some goals."""
    _, problem, _ = site
    layouts, covered = every_layout(problem)
    cov = covered @ problem.weights
    sizes = np.array([len(c) for c in layouts])
    fewer = 0
    for seen in (problem, problem.strongest(2)):
        for share in np.linspace(0.2, 0.95, 16):
            goal = share * float(cov.max())
            fewest = int(sizes[cov >= goal - 1e-12].min())
            path = search.greedy_path(seen, problem.n_sites, goal)
            hit = next((len(p.sites) for p in path if p.coverage >= goal - 1e-12), None)
            tried = search.fewer_sites(problem, seen, path, goal)
            assert len(tried) <= search.SIZING_PROBES
            assert hit is not None or not tried
            for lay, got in tried:
                assert hit is not None and len(set(lay)) == len(lay) < hit
                assert_close(got, sparse.LayoutState(problem, list(lay)).coverage())
                if got >= goal - 1e-12:
                    assert len(lay) >= fewest
                    fewer += 1
    assert fewer > 0


def test_a_layouts_information_is_its_entries_summed_in_order() -> None:
    """:class:`sparse.LayoutState`'s per-pair sum: each item's entries added one after another
    in entry order – the bits of the plain loop (the same additions in the same order), for
    items with none, one or many entries."""
    rng = np.random.default_rng(5)
    info = rng.standard_normal((40, 6)) * 10.0 ** rng.integers(-8, 8, (40, 1))
    per_item = rng.integers(0, 6, 9)
    per_item[3] = 0
    item = np.repeat(np.arange(9), per_item)
    entry = np.sort(rng.choice(40, item.size, replace=False))
    got = sparse._sum_by_item(info, item, entry, per_item)
    want = np.zeros((9, 6))
    for i, e in zip(item, entry, strict=True):
        want[i] = want[i] + info[e]
    assert np.array_equal(got, want)  # exact by construction: the same float additions
    empty = sparse._sum_by_item(info, item[:0], entry[:0], np.zeros(4, dtype=int))
    assert np.array_equal(empty, np.zeros((4, 6)))


def test_counts_above_sixteen_need_the_district_search() -> None:
    """The enumerating searches place at most sixteen RISs: named explicitly they are refused
    (naming the method and the count); under auto the district search takes the document."""
    doc = street_doc(counts=(20,), method="greedy")
    doc["candidates"] = doc["candidates"] * 2
    with pytest.raises(RisPlannerError, match=r"search method 'greedy' places at most 16"):
        validate_plan(doc)
    assert validate_plan({**doc, "search": {"method": "auto"}}).search.method == "district"


def test_district_refuses_what_it_does_not_plan() -> None:
    doc = street_doc()
    doc["objective"] = {"kind": "mean_capped", "metric": "rx", "cap_m": 5}
    with pytest.raises(RisPlannerError, match="plans coverage objectives"):
        prepare_plan(doc)


def test_command_line_district_plan_with_sizing(tmp_path: Path) -> None:
    doc = street_doc(counts=(2, 4))
    doc["sizing"] = {"target": {"objective": 0.5}}
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "ris_planner.cli", "plan", str(f), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    plan = json.loads((out / "plan.json").read_text())
    assert plan["search_method"]["used"] == "district"
    assert [e["ris_count"] for e in plan["by_count"]] == [2, 4]
    for e in plan["by_count"]:
        cert = e["certificate"]
        assert cert["objective_bound"] >= e["objective"] and cert["gap"] >= 0
    answer = plan["sizing"]["answer"]
    assert answer["count"] is not None and answer["lower_bound"] <= answer["count"]
    assert "certified" in run.stdout and "sizing:" in run.stdout
    assert (out / "district.png").stat().st_size > 10_000
    # a whole plan: the figures, the per-point GeoTIFF and CSV as every plan writes them
    for name in ("topview.png", "heatmap.png", "cdf.png", "heatmap.tif", "points.csv"):
        assert (out / name).stat().st_size > 0, name
    # the candidates as any plan.json lists them, and plan.geojson for a GIS: each count's
    # layout at its candidates' poses, every candidate, the buildings
    assert [c["name"] for c in plan["candidates"]] == [c["name"] for c in doc["candidates"]]
    # local metres: not a real site without buildings; the near field, as every plan says it
    assert [w.split(":")[0] for w in plan["warnings"]] == ["near field"]
    fc = json.loads((out / "plan.geojson").read_text())
    roles = [f["properties"]["role"] for f in fc["features"]]
    assert roles.count("candidate") == len(doc["candidates"])
    assert roles.count("obstacle") == len(doc["environment"]["obstacles"])
    for e in plan["by_count"]:
        placed = [
            f
            for f in fc["features"]
            if f["properties"]["role"] == "site" and f["properties"]["ris_count"] == e["ris_count"]
        ]
        assert sorted(f["properties"]["name"] for f in placed) == sorted(e["site_names"])
        for f in placed:
            cand = doc["candidates"][f["properties"]["candidate"]]
            assert f["geometry"]["coordinates"] == cand["position"][:2]


def test_progress_names_a_few_stages_whatever_the_candidate_count() -> None:
    """Every progress message is ``stage`` or ``stage: detail`` with one of a few stages, so
    the command line's bar, which redraws a stage at most every 0.1 s, draws a few lines, not
    one per candidate (thousands on a district)."""
    doc = street_doc(counts=(2, 3))
    doc["sizing"] = {"target": {"objective": 0.5}, "ris_sizes": [[48, 48]]}
    inputs = prepare_plan(doc)
    seen: list[tuple[float, str]] = []
    run_plan(doc, lambda f, m: seen.append((f, m)))
    stages = {m.split(":", 1)[0] for _, m in seen}
    assert stages <= {"plan", "fields", "report", "done"}, stages
    detail = {m.split(": ")[1].split()[0] for _, m in seen if m.count(": ") >= 1}
    assert detail <= {"information", "visibility", "path", "swaps", "done", "per-point", "sizing"}
    steps = [m for _, m in seen if "information: site" in m]
    assert len(steps) == len(inputs.sites) * 2  # the plan's and the sizing's other size
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0


def test_cover_sets_are_exactly_the_covering_subsets(site) -> None:
    """For the pairs whose m_p-subsets were all tried: the recorded sites are exactly those of
    the covering m_p-subsets (brute force over the subsets), and some subset covers."""
    _, problem, needs = site
    listed: dict[int, set[int]] = {}
    for p, st in zip(needs.cover_pair.tolist(), needs.cover_site.tolist(), strict=True):
        listed.setdefault(p, set()).add(st)
    pairs = np.flatnonzero(needs.complete)
    assert pairs.size > 0
    for p in np.random.default_rng(1).choice(pairs, size=min(30, pairs.size), replace=False):
        m = int(needs.need[p])
        union: set[int] = set()
        for sub in itertools.combinations(sorted(problem.sites_of(int(p)).tolist()), m):
            if sparse.LayoutState(problem, list(sub)).metric[p] <= problem.threshold:
                union |= set(sub)
        assert union and union == listed[int(p)], p


def test_auto_search_adapts_to_the_district_search_and_says_why() -> None:
    """A document whose enumerating searches exceed the layout limit: method 'auto' becomes
    'district' (the why names the limit); within the limit it stays 'auto'; an objective the
    district search does not plan is left to the refusal of the other searches."""
    small = PlanDocument.model_validate(street_doc(method="auto"))
    doc, choice, _ = resolve_search(small)
    assert doc.search.method == "auto" and choice.used == "auto"
    big = street_doc(method="auto", counts=(8,))
    big["search"] = {"method": "auto", "max_exhaustive": 1, "restarts": 1000, "max_rounds": 10000}
    doc, choice, _ = resolve_search(PlanDocument.model_validate(big))
    assert doc.search.method == "district" and "search limit" in choice.why
    assert validate_plan(big).search.method == "district"
    capped = {**big, "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 5}}
    _, choice, _ = resolve_search(PlanDocument.model_validate(capped))
    assert choice.used == "auto" and "coverage objectives" in choice.why


def test_sizing_ladder_answers_the_fewest_elements(tmp_path: Path) -> None:
    """Every reaching size's count is at least its certified lower bound, the answer is the
    reaching row with the fewest elements, and a size whose lower bound already needs more
    elements than the answer is skipped with that reason."""
    doc = street_doc(counts=(2,))
    doc["sizing"] = {"ris_sizes": [[16, 16], [32, 32], [48, 48]], "target": {"objective": 0.4}}
    plan = run_plan(doc).to_json()
    sizing = plan["sizing"]
    assert sizing["goal"]["min"] == pytest.approx(0.4 * sizing["servable_weight"], rel=1e-12)
    reached = [r for r in sizing["sizes"] if r["count"] is not None]
    assert reached, sizing
    for row in reached:
        assert row["lower_bound"] <= row["count"]
        assert row["objective"] >= sizing["goal"]["min"] - 1e-12
        # the greedy path's layout, then the counts the swaps tried below it; the row's count
        # is the fewest that reaches the goal
        tried = row["counts"]
        assert tried[0]["found_by"] == "greedy path"
        assert all(t["found_by"] == "greedy path and swaps" for t in tried[1:])
        assert all(t["count"] < tried[0]["count"] for t in tried[1:])
        for t in tried:
            assert t["reaches"] == (t["objective"] >= sizing["goal"]["min"] - 1e-12)
        assert row["count"] == min(t["count"] for t in tried if t["reaches"])
    best = min(reached, key=lambda r: r["count"] * r["ris_size"][0] * r["ris_size"][1])
    answer = sizing["answer"]
    assert answer["ris_size"] == best["ris_size"] and answer["count"] == best["count"]
    for row in sizing["sizes"]:
        if row["count"] is None and "skipped" in (row["note"] or ""):
            r, c = row["ris_size"]
            assert row["lower_bound"] * r * c >= answer["elements"]


def test_rest_plan_job_runs_the_district_search(tmp_path: Path) -> None:
    """POST /v1/plans with search.method 'district': a job that reports progress and ends with
    the district plan.json (bound and gap per count) and its figure."""
    from api_helpers import api_client, wait_for

    doc = street_doc(counts=(2, 3))
    with api_client(tmp_path, workers=1) as client:
        answer = client.post("/v1/plans", json=doc)
        assert answer.status_code == 202, answer.text
        job = answer.json()["id"]
        view = wait_for(client, job, ("succeeded", "failed"), timeout_s=240)
        assert view["status"] == "succeeded", view.get("error")
        plan = view["result"]
        assert plan["search_method"]["used"] == "district"
        assert [e["ris_count"] for e in plan["by_count"]] == [2, 3]
        assert all(e["certificate"]["objective_bound"] >= e["objective"] for e in plan["by_count"])
        assert "district" in view["figures"]


def test_the_relaxations_layout_keeps_the_constraints() -> None:
    """Largest z first, the required sites kept, the excluded and conflicting ones skipped."""
    z = np.array([0.9, 0.8, 0.7, 0.6, 0.5])
    conflict = np.zeros((5, 5), dtype=bool)
    conflict[0, 1] = conflict[1, 0] = True  # one mounting point
    assert search.rounded_layout(z, 3, (4,), (2,), conflict) == (0, 3, 4)
    assert search.rounded_layout(z, 5, (), (2,), conflict) == (0, 3, 4)  # runs out: fewer


def test_lp_roundings_keep_the_constraints_and_are_reproducible() -> None:
    """The top-L rounding first, then distinct randomized ones of the full count, each with the
    required site, without the excluded one and never both sites of one mounting point; the
    same seed gives the same layouts; a site of z = 0 is drawn only after every positive one."""
    rng = np.random.default_rng(5)
    z = rng.random(12) * (rng.random(12) > 0.3)
    conflict = np.zeros((12, 12), dtype=bool)
    conflict[0, 1] = conflict[1, 0] = True
    got = search.lp_layouts(z, 4, (5,), (2,), conflict, tries=8)
    assert got[0] == (search.rounded_layout(z, 4, (5,), (2,), conflict), "LP rounding")
    assert len({lay for lay, _ in got}) == len(got) > 1
    positive = set(np.flatnonzero(z > 0).tolist())
    for lay, how in got:
        assert how in ("LP rounding", "randomized LP rounding")
        assert len(lay) == 4 and 5 in lay and 2 not in lay and not {0, 1} <= set(lay)
        if len(positive - {2}) >= 4:
            assert set(lay) - {5} <= positive
    assert got == search.lp_layouts(z, 4, (5,), (2,), conflict, tries=8)


def test_what_the_search_sees_is_each_pairs_strongest_sites(site) -> None:
    """strongest(k) keeps, per pair, exactly the k serving sites of largest information on the
    metric's position (brute force over each pair's entries, ties aside), the rest of the
    problem unchanged; a layout's coverage seen through them never exceeds its exact one."""
    _, problem, _ = site
    k = 3
    seen = problem.strongest(k)
    strength = problem.strength()
    for p in range(problem.n_pairs):
        lo, hi = problem.pair_start[p], problem.pair_start[p + 1]
        mine = seen.sites_of(p)
        assert len(mine) == min(k, hi - lo)
        s = strength[lo:hi]
        if hi - lo > k and np.sort(s)[::-1][k - 1] > np.sort(s)[::-1][k]:  # no tie at the cut
            want = problem.entry_site[lo:hi][np.argsort(-s)[:k]]
            assert set(mine.tolist()) == set(want.tolist()), p
    for s in range(problem.n_sites):  # the by-site index is the pruned entries'
        assert np.array_equal(seen.pairs_of(s), np.sort(seen.entry_pair[seen.entry_site == s]))
    for layout in itertools.combinations(range(problem.n_sites), 3):
        assert sparse.LayoutState(seen, list(layout)).coverage() <= sparse.exact_coverage(
            problem, layout
        )
    assert problem.strongest(10_000) is problem


def test_reported_coverage_is_exact_when_the_search_sees_fewer_sites(
    site, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With the search seeing two sites per pair, every count's reported coverage is still the
    exact one of its layout (all serving sites), at least what the search saw, and within the
    certified bound."""
    doc, problem, _ = site
    monkeypatch.setattr(district_plan, "SEARCH_SITES", 2)
    plan = run_plan(doc).to_json()
    for e in plan["by_count"]:
        exact = sparse.exact_coverage(problem, tuple(e["sites"]))
        assert_close(e["objective"], exact, ulps=2 * problem.n_pairs)  # a reordered sum
        seen = sparse.LayoutState(problem.strongest(2), e["sites"]).coverage()
        assert seen <= exact <= e["certificate"]["objective_bound"]


def test_sizing_path_stops_at_the_transmissions() -> None:
    """A target or sizing path places at most one RIS fewer than the pilot transmissions (L
    RISs need L + 1 time-orthogonal transmissions) and at most MAX_DISTRICT_RIS."""
    assert search.most_ris(6) == 5
    assert search.most_ris(999) == search.MAX_DISTRICT_RIS


def test_a_spherical_plan_is_not_told_to_use_the_spherical_model() -> None:
    """The near-field advice ("use system.wavefront = 'spherical'") is for planar plans: the
    benchmark district's spherical plan carried it (docs/validation/benchmarks.md, "District
    physics"); the same street site planar still does."""
    doc = street_doc(counts=(2,))
    planar = run_plan(doc).to_json()["warnings"]
    assert any(w.startswith("near field") for w in planar)
    doc["system"] = {**doc.get("system", {}), "wavefront": "spherical"}
    spherical = run_plan(doc).to_json()["warnings"]
    assert not any(w.startswith("near field") for w in spherical), spherical


@pytest.mark.parametrize("large", [False, True])
def test_sizing_lower_count_starts_beside_the_beams(large, monkeypatch) -> None:
    """A plan whose sizing reuses its district run starts the sizing's certified lower count
    at the document's size on the certificate thread as soon as the counts are certified
    (beside the colours, the roll-out and the beams), not in the sizing stage: the sizing and
    the certificate are those of the plan that solves it in the sizing stage – for a small
    model and for one solved the large way (interior point, rounds of separated cuts)."""
    import threading

    if large:
        monkeypatch.setattr(lp, "SIMPLEX_MAX_NONZEROS", 0)
    threads: list[str] = []
    real_lower, real_run = district_plan._lower_count, district_plan.run_district

    def spy(*args):  # type: ignore[no-untyped-def]
        threads.append(threading.current_thread().name)
        return real_lower(*args)

    monkeypatch.setattr(district_plan, "_lower_count", spy)
    doc = street_doc(counts=(2, 3))  # 32 × 32 RISs: the document's own size alone
    doc["sizing"] = {"target": {"objective": 0.5}, "ris_sizes": [[32, 32]]}
    early = run_plan(doc).to_json()
    assert len(threads) == 1 and threads[0].startswith("district-relaxation"), threads
    threads.clear()
    monkeypatch.setattr(
        district_plan, "run_district", lambda *a, **k: real_run(*a, **{**k, "sizing": None})
    )
    late = run_plan(doc).to_json()
    assert len(threads) == 1 and threads[0].startswith("district-sizing"), threads

    def certified(plan: dict) -> tuple:
        cert = plan["search_details"]["certificate"]
        rows = [(r["ris_count"], r["bound"], r["cut_rounds"]) for r in cert["by_count"]]
        size = [(r["count"], r["lower_bound"]) for r in plan["sizing"]["sizes"]]
        return cert["model"], rows, size

    assert certified(early) == certified(late)
    assert early["sizing"]["sizes"][0]["lower_bound"] >= 1
