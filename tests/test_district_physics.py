"""District plans with the physics their range needs (docs/concepts/district-physics.md):
each site's designed codebook gives the bounds an independent evaluation gives with the same
profiles and powers, the profile colours separate every pair's RISs, and Γ follows the
colours."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest
from district_site import street_doc
from numpy.typing import NDArray
from tolerance import BOUND_ACCURACY, SDP_ACCURACY, assert_close

from ris_planner.bounds.compute import compute_bounds
from ris_planner.model.profiles import block_count
from ris_planner.physics.separable import beam_block, grid_axes
from ris_planner.planning.beams import layout_scenario
from ris_planner.planning.pipeline import run_plan
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.scoring.sparse import DistrictProblem, LayoutState, build_problem
from ris_planner.planning.scoring.time_blocks import conflict_graph, profile_colours

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]


def _designed(kind: str) -> dict:
    doc = street_doc(threshold_m=1.0, side=16, counts=(2, 3))
    doc["codebook"] = {"kind": kind}
    return doc


def _designed_layout_bounds(
    doc: dict, layout: list[int], blocks: int
) -> tuple[DistrictProblem, FloatArray, IntArray, FloatArray]:
    """(the district problem, its metric of ``layout`` on the pairs the layout serves, those
    pairs, ``compute_bounds``' PEB_R of them) on a scenario of the layout's sites with each
    site's designed profiles and the district's beam powers – Γ made the district's by padding
    the scenario with RISs that serve no pair; the scenario's wavefront the document's."""
    inputs = prepare_plan(doc)
    problem = build_problem(inputs, blocks=blocks)
    cb = problem.codebooks
    assert cb.designed and cb.blocks == blocks and cb.xi.shape[1] == 192 // blocks
    state = LayoutState(problem, layout)
    served = np.flatnonzero(
        np.isin(problem.entry_pair, problem.entry_pair[np.isin(problem.entry_site, layout)])
    )
    pairs = np.unique(problem.entry_pair[served])
    d = inputs.document
    ris = [inputs.sites[s].ris for s in layout]
    wavelength = 3e8 / d.system.carrier_hz
    profiles = []
    for s, r in zip(layout, ris, strict=True):
        yc, zr = grid_axes(r.rows, r.cols, r.element_spacing(wavelength))
        profiles.append(
            beam_block(yc, zr, cb.xi[s], cb.zeta[s], cb.beam_types, wavelength).profiles()
        )
    # padding: RISs high above the street facing up serve none of the pairs, so Γ = blocks
    pad = ris[0].model_copy(
        update={"position": [0.0, 0.0, 300.0], "orientation": [0.0, -np.pi / 2, 0.0]}
    )
    n_pad = blocks - 1 - len(layout)
    assert block_count(d.system.transmissions, len(layout) + n_pad) == blocks
    scenario = layout_scenario(d.system, ris + [pad] * n_pad, list(d.known), d.environment)
    all_profiles = profiles + [profiles[0]] * n_pad
    res = compute_bounds(
        scenario,
        inputs.pairs.tx[pairs],
        inputs.pairs.rx[pairs],
        profiles=all_profiles,
        beam_powers=cb.powers,
        channel=False,
    )
    return problem, state.metric[pairs], pairs, res.peb_rx


@pytest.mark.parametrize("kind", ["directional", "directional_derivative"])
def test_designed_information_is_compute_bounds_with_the_same_profiles(kind: str) -> None:
    """For a layout and every pair it serves, the district's metric with each site's designed
    block equals ``compute_bounds`` (element-by-element products, its own state assembly and
    inversion) on a scenario of those sites with the same profiles and beam powers – Γ made
    the district's by padding the scenario with RISs that serve no pair."""
    _, got, _, want = _designed_layout_bounds(_designed(kind), [0, 10, 12], 4)
    assert np.array_equal(np.isfinite(got), np.isfinite(want))
    fin = np.isfinite(got)
    assert fin.sum() > 10
    assert_close(got[fin], want[fin], accuracy=BOUND_ACCURACY)


@pytest.mark.parametrize("kind", ["directional", "directional_derivative"])
@pytest.mark.parametrize("layout", [[0, 10, 12], [6]])
def test_designed_near_field_information_is_spherical_compute_bounds(
    kind: str, layout: list[int]
) -> None:
    """With ``system.wavefront: "spherical"`` a designed block's entries inside the Fraunhofer
    distance take the exact per-element response with the block's dense profiles, the others
    the planar O(columns + rows) products: a pair every RIS of the layout serves from inside
    its Fraunhofer distance has the metric of the spherical ``compute_bounds`` (element by
    element for every path) with the same profiles and powers. 32 × 32 RISs at 30 GHz on the
    street's facades (2D²/λ ≈ 10 m) leave both near and far entries."""
    doc = _designed(kind)
    doc["ris"] = {"rows": 32, "cols": 32}
    doc["system"] = {**doc["system"], "wavefront": "spherical"}
    problem, got, pairs, want = _designed_layout_bounds(doc, layout, 4)
    assert problem.factor.shape[1] == 7  # the spherical square-root rows
    mine = np.isin(problem.entry_site, layout)
    assert np.any(problem.far[mine]) and np.any(~problem.far[mine])
    # pairs whose every layout entry is near: the spherical model for all their RIS paths
    far_entry = np.zeros(problem.n_pairs, dtype=bool)
    np.logical_or.at(far_entry, problem.entry_pair[mine], problem.far[mine])
    near = ~far_entry[pairs]
    assert np.array_equal(np.isfinite(got[near]), np.isfinite(want[near]))
    fin = near & np.isfinite(got)
    assert fin.sum() > 10
    assert_close(got[fin], want[fin], accuracy=BOUND_ACCURACY)


def test_a_designed_spherical_district_plan_plans() -> None:
    """A designed codebook with ``system.wavefront: "spherical"`` – refused before the near
    entries took the block's dense profiles – plans: its layouts cover pairs from inside and
    outside the Fraunhofer distance, with the codebook it was designed with."""
    doc = _designed("directional_derivative")
    doc["ris"] = {"rows": 32, "cols": 32}
    doc["system"] = {**doc["system"], "wavefront": "spherical"}
    plan = run_plan(doc).to_json()
    assert plan["physics"]["wavefront"] == "spherical"
    assert plan["search_details"]["codebook"]["kind"] == "directional_derivative"
    assert sorted(lay["ris_count"] for lay in plan["layouts"]) == [2, 3]
    for lay in plan["layouts"]:
        assert 0.0 < lay["near_field_fraction"] < 1.0
        assert 0.0 < lay["objective"] <= 1.0


def test_profile_colours_separate_every_pairs_rises() -> None:
    """No pair hears two RISs of one colour audibly; the colours are at least the most RISs
    one pair hears audibly (a clique) and at most the layout's size."""
    inputs = prepare_plan(street_doc(side=16))
    problem = build_problem(inputs)
    rng = np.random.default_rng(0)
    for _ in range(20):
        layout = sorted(rng.choice(problem.n_sites, size=6, replace=False).tolist())
        colour = profile_colours(problem, layout)
        adjacent = conflict_graph(problem, layout)
        for i, j in zip(*np.nonzero(adjacent), strict=True):
            assert colour[i] != colour[j]
        heard = np.zeros(problem.n_pairs, dtype=int)
        loud = np.isin(problem.entry_site, layout) & problem.audible
        np.add.at(heard, problem.entry_pair[loud], 1)
        assert heard.max() <= colour.max() + 1 <= len(layout)


def test_a_designed_district_plan_reports_its_blocks_and_codebook() -> None:
    plan = run_plan(_designed("directional_derivative")).to_json()
    timing = plan["search_details"]["time_orthogonal"]
    assert timing["blocks"] >= timing["blocks_needed"]
    assert 192 % timing["blocks"] == 0 and timing["beams_per_block"] == 192 // timing["blocks"]
    assert timing["blocks"] == timing["designed_for"]
    for row in timing["counts"]:
        assert row["blocks_needed"] == block_count(192, row["colours"])
        assert row["colours"] <= timing["designed_for"] - 1  # fits the information's blocks
        assert len(row["colour_of_site"]) == row["ris_count"]
    cb = plan["search_details"]["codebook"]
    assert cb["kind"] == "directional_derivative" and cb["blocks"] == timing["blocks"]
    assert sum(cb["slot_powers"]) == pytest.approx(cb["beams_per_block"], rel=1e-12)


def _counted_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The Γ of every information build of a district plan run after the call (the list
    fills as the plan runs)."""
    import ris_planner.planning.district_plan as district_plan

    builds: list[int] = []
    real = district_plan.build_problem

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        builds.append(kwargs.get("blocks", 0))
        return real(*args, **kwargs)

    monkeypatch.setattr(district_plan, "build_problem", counted)
    return builds


def test_every_layout_fits_the_blocks_of_its_one_information_build(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Γ is fixed before the designed information and the layouts are held to its Γ − 1
    profile colours: with the planner's first Γ too small for the searched layouts (2
    colours: Γ = 3), the plan builds the information once – no second run with a larger Γ –
    and every reported layout's colours fit, the held ones re-scored exactly."""
    import ris_planner.planning.district_plan as district_plan

    builds = _counted_builds(monkeypatch)
    monkeypatch.setattr(district_plan, "INITIAL_COLOURS", 2)
    doc = _designed("directional_derivative")
    doc["ris_count"] = [2, 3, 4]
    doc["sizing"] = {"ris_sizes": [[16, 16]], "target": {"objective": 0.3}}
    result = run_plan(doc)
    plan = result.to_json()
    assert builds == [3]  # one information build, for Γ = 3
    timing = plan["search_details"]["time_orthogonal"]
    problem = result.scorer.problem  # type: ignore[attr-defined]
    for row in timing["counts"]:  # the reported colouring is proper and below Γ − 1
        sites = [int(x) for x in row["colour_of_site"]]
        colour = np.array([row["colour_of_site"][str(x)] for x in sites])
        adjacent = conflict_graph(problem, sites)
        assert not (adjacent & (colour[:, None] == colour[None, :])).any()
        assert colour.max() < 2 and row["colours"] == colour.max() + 1
    assert timing["designed_for"] == 3
    assert timing["blocks"] == 3 and timing["blocks_needed"] <= 3
    assert all(row["colours"] <= 2 for row in timing["counts"])
    held = timing["held_to_blocks"]
    assert held and all(h["fits"] and h["removed"] and h["added"] for h in held)
    by_count = {e["ris_count"]: e for e in plan["by_count"]}
    colours = {row["ris_count"]: row["colour_of_site"] for row in timing["counts"]}
    for h in held:
        assert by_count[h["ris_count"]]["objective"] == pytest.approx(
            h["coverage_after"], abs=1e-12
        )
        sites = {int(s) for s in colours[h["ris_count"]]}
        assert not sites & set(h["removed"]) and set(h["added"]) <= sites
    assert "colours" in plan["timing_s"]
    # the sizing's greedy path reaches the target only with 3 colours: no answer, and why
    (row,) = plan["sizing"]["sizes"]
    assert row["count"] is None and row["sites"] is None
    assert "3 profile colours, more than the Γ − 1 = 2" in row["note"]


def test_every_held_layout_carries_a_proper_colouring_below_the_limit() -> None:
    """Over 150 random layouts of 3 to 5 of the street site's candidates that need more than 2
    profile colours: held to 2 (Γ = 3) each keeps its count, never takes back a site it took
    out, and carries a colouring that is proper on its conflict graph and below 2 – the
    colouring the plan reports (built with the refill, not DSatur run again: that could need
    more)."""
    from ris_planner.planning.search.colour_fit import fit_colours

    problem = build_problem(prepare_plan(_designed("directional_derivative")), blocks=3)
    rng = np.random.default_rng(7)
    needing = held = 0
    while needing < 150:
        size = int(rng.integers(3, 6))
        layout = tuple(sorted(rng.choice(problem.n_sites, size, replace=False).tolist()))
        if int(profile_colours(problem, layout).max()) + 1 <= 2:
            continue
        needing += 1
        fit = colour_fit_checked(fit_colours(problem, problem, layout, 2), problem, 2)
        if fit.fits:
            held += 1
            assert len(fit.layout) == size and not set(fit.removed) & set(fit.layout)
            assert set(fit.added) == set(fit.layout) - set(layout)
    assert held > 20, held


def colour_fit_checked(fit, problem, colours):  # type: ignore[no-untyped-def]
    """``fit`` after checking its colouring: proper on the conflict graph, below ``colours``
    where it fits."""
    colour = np.array(fit.colour)
    assert colour.size == len(fit.layout)
    if fit.fits:
        adjacent = conflict_graph(problem, fit.layout)
        assert not (adjacent & (colour[:, None] == colour[None, :])).any()
        assert colour.max() < colours
    return fit


def test_a_count_no_refill_can_hold_is_infeasible_not_a_second_build(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A count whose layout cannot be held to the Γ − 1 colours (no candidate with a free
    colour is left) is reported as an infeasible count, saying how many
    colours it needs – the information is still built once, for the Γ fixed before it."""
    import ris_planner.planning.district_plan as district_plan

    builds = _counted_builds(monkeypatch)
    monkeypatch.setattr(district_plan, "INITIAL_COLOURS", 1)  # Γ = 2: one colour
    doc = _designed("directional_derivative")
    doc["ris_count"] = [2, 3, 4]
    plan = run_plan(doc).to_json()
    assert builds == [2]
    held = plan["search_details"]["time_orthogonal"]["held_to_blocks"]
    unheld = [h["ris_count"] for h in held if not h["fits"]]
    assert unheld and plan["infeasible_counts"] == unheld
    assert all(h["colours"] > 1 for h in held if not h["fits"])
    reported = {e["ris_count"] for e in plan["by_count"]}
    assert not reported & set(unheld) and reported
    for row in plan["search_details"]["time_orthogonal"]["counts"]:
        assert row["colours"] <= 1


def test_nested_layouts_of_a_designed_plan_are_held_to_its_colours(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With ``rollout: nested`` each nested layout of a designed plan fits the Γ − 1 profile
    colours its information was computed with, and still holds the previous count's sites."""
    import ris_planner.planning.district_plan as district_plan

    monkeypatch.setattr(district_plan, "INITIAL_COLOURS", 2)
    doc = _designed("directional_derivative")
    doc["ris_count"] = [2, 3, 4, 5]
    doc["rollout"] = "nested"
    inputs = prepare_plan(doc)
    result = run_plan(doc)
    problem = result.scorer.problem  # type: ignore[attr-defined]
    assert problem.codebooks.blocks == 3
    rows = result.to_json()["rollout"]["counts"]
    prev: set[int] = set()
    nested = [r["nested_layout"] for r in rows[1:]]
    assert any(n is not None for n in nested)
    for r in rows[1:]:
        lay = r["nested_layout"]
        if lay is None:
            continue
        assert prev <= set(lay) and len(lay) == r["ris_count"]
        assert int(profile_colours(problem, lay).max()) + 1 <= 2
        prev = set(lay)
    assert inputs.document.rollout == "nested"


def test_designed_codebooks_are_refused_by_the_enumerating_searches() -> None:
    from ris_planner.core.errors import DocumentFieldError
    from ris_planner.planning.resources.admission import admit

    doc = _designed("directional") | {"search": {"method": "exhaustive"}}
    with pytest.raises(DocumentFieldError, match=r"codebook\.kind"):
        admit(doc)


def test_district_beams_solve_one_sdp_per_ris() -> None:
    """``beams`` on a district plan: each count's layout gets DIR+DER blocks, the γ_P search
    over the layout's design positions and the appendix SDP once per RIS over the positions it
    serves – each RIS's optimum (mean PEB² there, by the bounds' route) never above γ_P's or
    uniform powers', both feasible points of it – its status and time as data, and the layout
    re-scored on every pair under each allocation; the progress bar moves on through the
    beams stage."""
    doc = _designed("directional_derivative") | {"beams": {"design_positions": 12}}
    doc["ris_count"] = [3]
    seen: list[tuple[float, str]] = []
    plan = run_plan(doc, lambda f, m: seen.append((f, m))).to_json()
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions)
    beams = [f for f, m in seen if "beams" in m]
    assert beams and beams[-1] > beams[0] + 0.1, seen
    (lay,) = plan["beams"]["layouts"]
    sdp = lay["sdp"]
    assert [r["site"] for r in sdp["per_ris"]] == lay["sites"]
    solved = [r for r in sdp["per_ris"] if r["status"] in ("optimal", "inaccurate")]
    assert solved, sdp
    for r in solved:  # optimal: the solver's optimum is the bound at its powers
        own = r["design_objective_m2"]
        agree = abs(r["solver_objective_m2"] - own["sdp"]) <= 1e-3 * own["sdp"]
        assert (r["status"] == "optimal") == agree, r
    # this site has a RIS whose optimum leaves a position near singular: said, not hidden
    assert any(r["status"] == "inaccurate" and "not the bound" in r["message"] for r in solved)
    for r in solved:
        own = r["design_objective_m2"]
        assert 1 <= r["design_positions"] <= 8 and r["solve_time_s"] > 0
        assert own["sdp"] <= own["gamma_p"] * (1 + SDP_ACCURACY)
        assert own["sdp"] <= own["uniform"] * (1 + SDP_ACCURACY)
    assert sum(sdp["status_counts"].values()) == len(lay["sites"])
    assert sdp["solve_time_s"] == pytest.approx(
        sum(r.get("solve_time_s", 0) for r in sdp["per_ris"])
    )
    design = lay["design_objective_m2"]
    assert design["gamma_p"] <= design["uniform"] * (1 + SDP_ACCURACY)
    for name in ("dir_der_uniform", "dir_der_gamma_p", "dir_der_sdp"):
        assert 0.0 <= lay["objective"][name] <= 1.0
    assert sum(lay["powers"]["sdp"]) == pytest.approx(lay["beams_per_block"], rel=1e-9)
    colours = plan["search_details"]["time_orthogonal"]["counts"][0]["colour_of_site"]
    assert [r["colour"] for r in lay["ris"]] == [colours[str(s)] for s in lay["sites"]]


def test_per_ris_sdps_on_the_plan_pool_answer_as_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """From ``SDP_POOL_MIN_RIS`` RISs on, each RIS's information and SDP is a task on the plan's
    process pool (:class:`RisSdpTask`, with the shared :class:`RisSdpShared`), answering as
    in-process: the same statuses and design positions, the mean PEB² at uniform and γ_P
    powers to the bounds' accuracy (another process, another BLAS thread count) and at the SDP
    powers to the SDP's."""
    import ris_planner.planning.district_beams as district_beams
    from ris_planner.runtime.executor import LocalExecutor

    class Recording(LocalExecutor):
        tasks: ClassVar[list[tuple[str, int]]] = []

        def map(self, fn, shared, chunks, on_done=None):  # type: ignore[no-untyped-def]
            self.tasks.append((fn.__name__, len(chunks)))
            return super().map(fn, shared, chunks, on_done)

    doc = _designed("directional_derivative") | {"beams": {"design_positions": 12}}
    doc["ris_count"] = [3]
    (here,) = run_plan(doc).to_json()["beams"]["layouts"]
    monkeypatch.setattr(district_beams, "SDP_POOL_MIN_RIS", 1)
    pool = Recording(workers=2)
    try:
        (pooled,) = run_plan(doc, executor=pool).to_json()["beams"]["layouts"]
        assert pool.worker_pids()  # the pool ran (its workers stop with it)
    finally:
        pool.close()
    assert ("_solve_ris", 3) in Recording.tasks
    for a, b in zip(here["sdp"]["per_ris"], pooled["sdp"]["per_ris"], strict=True):
        assert (a["site"], a["status"], a["design_positions"]) == (
            b["site"],
            b["status"],
            b["design_positions"],
        )
        got, want = b["design_objective_m2"], a["design_objective_m2"]
        for kind in ("uniform", "gamma_p"):
            assert_close(got[kind], want[kind], accuracy=BOUND_ACCURACY)
        assert_close(got["sdp"], want["sdp"], accuracy=SDP_ACCURACY)
    assert pooled["sdp"]["status_counts"] == here["sdp"]["status_counts"]


def test_a_failed_per_ris_sdp_is_data_never_a_silent_fallback(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A RIS whose SDP fails keeps its status and message in its row and adds nothing to the
    layout's allocation, nor does one whose solve is ``inaccurate`` (its powers are not what
    its optimum claims); when every RIS's SDP fails the layout has no ``sdp`` allocation (no
    powers, no objective) rather than another in its place."""
    from dataclasses import replace

    import ris_planner.power.sdp as sdp_module

    real = sdp_module.solve_power_sdp
    calls: list[int] = []

    def failing(info, objective="rx", solver="CLARABEL", total_power=None):  # type: ignore[no-untyped-def]
        calls.append(1)
        if fail_all or (len(calls) == 1 and not inaccurate_first):
            return sdp_module.SdpResult("failed", None, None, 0.0, solver, "test: solver failed")
        res = real(info, objective, solver, total_power)
        assert res.powers is not None
        if not inaccurate_first:
            return res
        if len(calls) == 1:  # every power on one slot, said to be inaccurate
            lopsided = np.zeros_like(res.powers)
            lopsided[0] = res.powers.sum()
            return replace(res, status="inaccurate", powers=lopsided, message="test")
        return replace(res, status="optimal", powers=np.ones_like(res.powers))

    monkeypatch.setattr(sdp_module, "solve_power_sdp", failing)
    doc = _designed("directional_derivative") | {"beams": {"design_positions": 12}}
    doc["ris_count"] = [3]
    fail_all, inaccurate_first = False, True
    (lay,) = run_plan(doc).to_json()["beams"]["layouts"]
    assert [r["status"] for r in lay["sdp"]["per_ris"]] == ["inaccurate", "optimal", "optimal"]
    # the two optimal RISs' uniform powers alone: the lopsided inaccurate ones are left out
    assert_close(lay["powers"]["sdp"], np.ones(lay["beams_per_block"]))
    calls.clear()
    inaccurate_first = False
    (lay,) = run_plan(doc).to_json()["beams"]["layouts"]
    rows = lay["sdp"]["per_ris"]
    assert rows[0]["status"] == "failed" and rows[0]["message"] == "test: solver failed"
    assert rows[0]["design_objective_m2"]["sdp"] is None
    assert lay["sdp"]["status_counts"]["failed"] == 1 and "sdp" in lay["powers"]
    fail_all = True
    (lay,) = run_plan(doc).to_json()["beams"]["layouts"]
    assert lay["sdp"]["status_counts"] == {"failed": 3}
    assert "sdp" not in lay["powers"] and "dir_der_sdp" not in lay["objective"]
    assert lay["design_objective_m2"]["sdp"] is None


def test_district_validation_checks_each_pair_with_the_rises_it_hears() -> None:
    """``validation`` on a district plan: each checked pair is simulated with the layout's RISs
    it hears audibly – a subset of the layout – and its bound is compute_bounds' of that
    configuration."""
    doc = _designed("directional") | {"validation": {"pairs": 4, "draws": 1}}
    doc["ris_count"] = [3]
    plan = run_plan(doc).to_json()
    (lay,) = plan["validation"]["layouts"]
    assert lay["codebook"]["kind"] == "designed" and lay["codebook"]["blocks"] >= 4
    for pair in lay["pairs"]:
        assert set(pair["paths"]["ris"]) <= set(lay["sites"])


def test_the_audible_only_coverage_is_compute_bounds_with_the_rises_each_pair_hears() -> None:
    """plan.json ``search_details.audible_paths``: per count the layout's coverage counting
    only the RIS paths heard above the noise over the whole pilot – per pair, the metric equals
    ``compute_bounds`` on a scenario of the layout's RISs that pair hears audibly (random
    phases: no Γ to pad), and the covered weight is the plan's figure; never above the
    coverage that counts every path."""
    doc = street_doc(threshold_m=1.0, side=16, counts=(3,))
    result = run_plan(doc)
    plan = result.to_json()
    problem = result.scorer.problem  # type: ignore[attr-defined]
    (row,) = plan["search_details"]["audible_paths"]["by_count"]
    layout = [int(x) for x in plan["by_count"][0]["sites"]]
    state = LayoutState(problem.audible_only(), layout)
    inputs = prepare_plan(doc)
    d = inputs.document
    heard: dict[tuple[int, ...], list[int]] = {}
    for pair in range(problem.n_pairs):
        lo, hi = problem.pair_start[pair], problem.pair_start[pair + 1]
        loud = set(problem.entry_site[lo:hi][problem.audible[lo:hi]].tolist())
        heard.setdefault(tuple(s for s in layout if s in loud), []).append(pair)
    checked = 0
    for rises, pairs in heard.items():
        got = state.metric[pairs]
        if not rises:
            assert np.isinf(got).all()
            continue
        scenario = layout_scenario(
            d.system, [inputs.sites[s].ris for s in rises], list(d.known), d.environment
        )
        res = compute_bounds(
            scenario, inputs.pairs.tx[pairs], inputs.pairs.rx[pairs], channel=False
        )
        assert np.array_equal(np.isfinite(got), np.isfinite(res.peb_rx))
        fin = np.isfinite(got)
        assert_close(got[fin], res.peb_rx[fin], accuracy=BOUND_ACCURACY)
        checked += int(fin.sum())
    assert checked > 20
    covered = float(problem.weights[state.metric <= problem.threshold].sum())
    assert row["audible_only"] == pytest.approx(covered, abs=1e-12)
    assert row["audible_only"] <= row["coverage"] + 1e-12
    assert row["coverage"] == pytest.approx(plan["by_count"][0]["objective"], abs=1e-12)
    share = plan["search_details"]["audible_paths"]["audible_entries_share"]
    assert share == pytest.approx(problem.audible.mean(), abs=1e-12)
    warned = [w for w in plan["warnings"] if "counting only RIS paths heard" in w]
    assert bool(warned) == (row["audible_only"] < 0.8 * row["coverage"]), (row, warned)


def test_no_audible_paths_warning_where_the_paths_are_heard() -> None:
    """At 60 dBm on the street site most paths are audible and the coverage counting only
    them is within the warning's share: no warning (at 30 dBm the same layout count warns)."""
    doc = street_doc(threshold_m=1.0, side=16, counts=(3,))
    doc["system"]["tx_power_dbm"] = 60
    plan = run_plan(doc).to_json()
    (row,) = plan["search_details"]["audible_paths"]["by_count"]
    assert row["audible_only"] >= 0.8 * row["coverage"] > 0
    assert not [w for w in plan["warnings"] if "counting only RIS paths heard" in w]


def test_a_designed_plan_no_count_of_which_can_be_held_says_why() -> None:
    """When no count's layout can be held to the Γ − 1 colours (12 of the street's 14 sites,
    which need 8 colours, against Γ = 6), the plan stops with a message naming the colours and
    what to change – not an empty plan (its summary and figures have no count to show)."""
    from ris_planner.core.errors import RisPlannerError

    doc = street_doc(threshold_m=1.0, side=16, counts=(12,))
    doc["codebook"] = {"kind": "directional_derivative"}
    with pytest.raises(RisPlannerError, match="fits the 5 profile colours") as err:
        run_plan(doc)
    assert "codebook.blocks" in str(err.value)


def test_the_expected_random_warning_follows_the_profile_colours() -> None:
    """A district plan's random-phase blocks are sized by its profile colours, not its RIS
    count: 12 RISs in 8 colours take Γ = 12 (G̃ = 16 beams, no optimism warning, where 12 + 1
    RISs would have given G̃ = 12), and a designed codebook has no random phases to warn of."""
    plan = run_plan(street_doc(threshold_m=1.0, side=16, counts=(12,))).to_json()
    (row,) = plan["search_details"]["time_orthogonal"]["counts"]
    assert row["colours"] < 12 and 192 // block_count(192, row["colours"]) >= 16
    assert not [w for w in plan["warnings"] if "expected_random optimism" in w]
    designed = run_plan(_designed("directional_derivative")).to_json()
    assert not [w for w in designed["warnings"] if "expected_random optimism" in w]


def test_design_positions_information_takes_presence_in_one_query() -> None:
    """The design positions' stacked information finds every position's paths in one
    visibility query (:func:`~ris_planner.planning.district_beams._presence`) and is, bit for
    bit, the information of each position found on its own (``beam_information`` finding its
    paths); the padding RIS carries no path and the layout's RISs theirs."""
    from ris_planner.planning import district_beams as db
    from ris_planner.planning.outputs.estimator_check import padding_ris
    from ris_planner.power.information import beam_information

    doc = _designed("directional_derivative")
    inputs = prepare_plan(doc)
    problem = build_problem(inputs, blocks=3)
    layout = (0, 4, 9)
    design = db.PlanCodebook(kind="directional_derivative", seed=0)
    g_tilde = db.beams_per_block(inputs.document.system.transmissions, 3, "directional_derivative")
    blocks, _, _ = db._layout_blocks(problem, inputs, layout, design, g_tilde)
    serves = LayoutState(problem, list(layout))
    pick = np.flatnonzero(np.isfinite(serves.metric))[:6]
    assert pick.size == 6
    start = problem.pair_start
    mine = [[s for s in layout if s in problem.entry_site[start[p] : start[p + 1]]] for p in pick]
    sys_, env = inputs.document.system, inputs.document.environment
    pad = (padding_ris(inputs.sites[layout[0]].ris), blocks[layout[0]])
    ris = [[inputs.sites[s].ris for s in m] for m in mine]
    own = [[blocks[s] for s in m] for m in mine]
    tx, rx = inputs.pairs.tx[pick], inputs.pairs.rx[pick]
    got = db._stacked_information(sys_, env, tx, rx, ris, own, pad, 3)
    width = max(len(r) for r in ris)
    for i in range(pick.size):
        n_pad = width - len(ris[i])
        scenario = layout_scenario(sys_, ris[i] + [pad[0]] * n_pad, [], env)
        prof = [b.profiles() for b in own[i]] + [pad[1].profiles()] * n_pad
        want = beam_information(scenario, tx[[i]], rx[[i]], prof, [], n_blocks=3)
        np.testing.assert_array_equal(got.stack[i], want.stack[0])
        for k, path in enumerate(want.paths):
            assert bool(got.paths[k].present[i]) == bool(path.present[0]), (i, path.name)
            if path.name != "los":  # the position's own RISs serve it, the padding nobody
                assert path.present[0] == (int(path.name[3:]) <= len(ris[i])), (i, path.name)
