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
from district_site import street_doc
from pydantic import ValidationError
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.bounds.compute import compute_bounds
from ris_planner.model.plan import PlanDocument
from ris_planner.planning import district as dist
from ris_planner.planning.beam_design import layout_scenario
from ris_planner.planning.inputs import prepare_plan
from ris_planner.planning.pipeline import run_plan


@pytest.fixture(scope="module", params=[0.5, 2.0])
def site(request: pytest.FixtureRequest) -> tuple[dict, dist.DistrictProblem, dist.Needs]:
    doc = street_doc(threshold_m=request.param)
    inputs = prepare_plan(doc)
    problem = dist.build_problem(inputs)
    return doc, problem, dist.sites_needed(problem)


def test_district_reaches_the_exhaustive_optimum_and_its_bound_holds(site) -> None:
    doc, problem, needs = site
    exact = run_plan({**doc, "search": {"method": "exhaustive"}})
    path = dist.greedy_path(problem, 3)
    for cr in exact.counts:
        best = -cr.ranked[0][1]  # the search's loss is −coverage
        _, cov = dist.improve(problem, path[cr.ris_count - 1].sites)
        assert cov >= best - 0.01  # within 1 % of the optimum
        assert cov <= best + BOUND_ACCURACY
        assert dist.coverage_upper_bound(problem, cr.ris_count, needs) >= best - 1e-9


def test_district_coverage_is_the_bounds_engines(site) -> None:
    """The coverage the district search reports for a layout equals the weighted fraction of
    compute_bounds' PEB_R within the threshold (the environment's paths from the scene)."""
    doc, problem, _ = site
    inputs = prepare_plan(doc)
    layout, cov = dist.improve(problem, dist.greedy_path(problem, 3)[-1].sites)
    d = inputs.document
    ris = [inputs.sites[s].ris for s in layout]
    scenario = layout_scenario(d.system, ris, list(d.known), d.environment)
    res = compute_bounds(scenario, inputs.pairs.tx, inputs.pairs.rx, profiles=None)
    state = dist.LayoutState(problem, list(layout))
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
        smaller = range(len(sites) + 1) if need[p] == 0 else range(int(need[p]))
        for m in smaller:
            for sub in itertools.combinations(sites, m):
                st = dist.LayoutState(problem, list(sub))
                assert not st.metric[p] <= problem.threshold, (p, sub, need[p])


def test_sizing_answers_with_a_certified_count(site) -> None:
    _, problem, needs = site
    goal = 0.5 * float(problem.weights[needs.need > 0].sum())
    path = dist.greedy_path(problem, problem.n_sites, target=goal)
    lower = dist.count_lower_bound(problem, goal, needs)
    assert lower is not None
    assert path[-1].coverage >= goal - 1e-12
    assert 1 <= lower <= len(path[-1].sites)
    # every count below the certified one: its upper bound is below the goal
    assert dist.coverage_upper_bound(problem, lower - 1, needs) < goal + 1e-6


def test_counts_above_sixteen_need_the_district_search() -> None:
    doc = street_doc(counts=(20,), method="greedy")
    with pytest.raises(ValidationError, match=r"need search\.method 'district'"):
        PlanDocument.model_validate(doc)
    PlanDocument.model_validate({**doc, "search": {"method": "district"}})


def test_district_refuses_what_it_does_not_plan() -> None:
    doc = street_doc()
    doc["objective"] = {"kind": "mean_capped", "metric": "rx", "cap_m": 5}
    with pytest.raises(Exception, match="coverage objective"):
        dist.build_problem(prepare_plan(doc))


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
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    plan = json.loads((out / "plan.json").read_text())
    assert plan["method"] == "district"
    assert [e["ris_count"] for e in plan["by_count"]] == [2, 4]
    for e in plan["by_count"]:
        assert e["upper_bound"] >= e["objective"] and e["gap"] >= 0
    sizing = plan["sizing"]
    assert sizing["count"] is not None and sizing["lower_bound"] <= sizing["count"]
    assert "certified" in run.stdout and "sizing:" in run.stdout
    assert (out / "district.png").stat().st_size > 10_000


def test_cover_sets_are_exactly_the_covering_subsets(site) -> None:
    """For the pairs whose m_p-subsets were all tried: a subset of m_p serving sites covers the
    pair iff it is one of its cover sets (brute force over the subsets)."""
    _, problem, needs = site
    listed: dict[int, set[tuple[int, ...]]] = {}
    for p, row in zip(needs.cover_pair.tolist(), needs.cover_sites.tolist(), strict=True):
        listed.setdefault(p, set()).add(tuple(sorted(s for s in row if s >= 0)))
    pairs = np.flatnonzero(needs.complete)
    assert pairs.size > 0
    for p in np.random.default_rng(1).choice(pairs, size=min(30, pairs.size), replace=False):
        m = int(needs.need[p])
        for sub in itertools.combinations(sorted(problem.sites_of(int(p)).tolist()), m):
            covered = dist.LayoutState(problem, list(sub)).metric[p] <= problem.threshold
            assert covered == (sub in listed.get(int(p), set())), (p, sub)
