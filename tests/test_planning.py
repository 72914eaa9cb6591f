"""Planning engine: cached layout scores against compute_bounds, the Fig. 10 anchor search,
exhaustive vs greedy, maps/sites/objectives against brute force, bad input, CLI, schema."""

from __future__ import annotations

import itertools
import json
import math
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from ris_planner.bounds.compute import compute_bounds
from ris_planner.cli import main
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.objectives import weighted_quantile
from ris_planner.model.paper import fig10_pairs
from ris_planner.model.scenario import Scenario, load_scenario, preset_document
from ris_planner.physics.geometry import rotation_matrix
from ris_planner.planning import (
    PLAN_PRESET_NAMES,
    PlanDocument,
    SerialExecutor,
    load_plan_file,
    plan_preset,
    run_plan,
)
from ris_planner.planning.inputs.sites import expand_sites, wall_poses
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs, road_points
from ris_planner.planning.scoring.scorer import (
    Scorer,
    loss_from_metric,
    objective_value,
    select_metric,
)
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility
from ris_planner.planning.search.layouts import SearchOutcome, exhaustive, greedy

GRID = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0.5, 0.5]}}
RTOL = 1e-9
"""The cached score must be the compute_bounds value: both invert through
ris_planner.inversion.ldl, so
only a different summation order of the cached 7×7 matrices could move it (by ≤ cond·ε)."""


def ring(n: int, radius: float = 4.5, tilt: float = math.pi / 6) -> list[dict[str, Any]]:
    """n candidates on a circle around the origin, facing the centre, 2–3 m high."""
    out = []
    for k in range(n):
        phi = 2 * math.pi * k / n + 0.1
        out.append(
            {
                "position": [radius * math.cos(phi), radius * math.sin(phi), 2.0 + (k % 2)],
                "orientation": [phi + math.pi, tilt, 0.0],
            }
        )
    return out


def plan_doc(**over: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "candidates": ring(6),
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": 300, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [3],
    }
    doc.update(over)
    return doc


def setup(doc: dict[str, Any]) -> tuple[PlanDocument, Any, Any, Scorer]:
    d = PlanDocument.model_validate(doc)
    sites = expand_sites(d)
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, d.max_pairs)
    # the plan's visibility rules: fields of view (and obstacles) per (point, site)
    vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)
    cache = build_site_cache(d.system, sites, pairs, visibility=vis, known=tuple(d.known))
    return d, sites, pairs, Scorer(cache, pairs.weights, d.objective, tuple(d.known))


def reference_metric(d: PlanDocument, sites: Any, pairs: Any, layout: tuple[int, ...]) -> Any:
    scen = Scenario(
        system=d.system,
        ris=[sites[s].ris for s in layout],
        tx=[0.1, 0.2, 9.0],
        rx=[0.3, -0.2, 9.0],
        codebook={"kind": "expected_random"},
        known=d.known,
    )
    res = compute_bounds(scen, tx=pairs.tx, rx=pairs.rx)
    return select_metric(d.objective.metric, res.peb_tx, res.peb_rx)


@pytest.mark.parametrize(
    ("known", "metric", "los"),
    [
        ([], "rx", True),
        ([], "tx", True),
        ([], "max", True),
        (["clock"], "rx", True),
        (["height"], "max", True),
        (["tx"], "rx", True),
        ([], "rx", False),
    ],
)
def test_cached_score_equals_compute_bounds(known: list[str], metric: str, los: bool) -> None:
    doc = plan_doc(
        known=known,
        objective={"kind": "mean_capped", "metric": metric, "cap_m": 1.0},
        system={"los": los},
        # one RX point on candidate 0 exercises the degenerate-pair path (inf in both routes)
        rx_map={**GRID, "points": [ring(6)[0]["position"]]},
        pairs={"sample": 300, "seed": 3},
    )
    d, sites, pairs, scorer = setup(doc)
    layouts = [(0, 1, 2), (1, 3, 5), (0, 2, 4), (2, 3, 4), (0, 1), (1, 4)]
    got = scorer.metric(np.array(layouts[:4]))
    # the compiled kernel and the numpy route: the same bits
    np.testing.assert_array_equal(got, scorer.metric_reference(np.array(layouts[:4])))
    for row, lay in enumerate(layouts):
        m = got[row] if row < 4 else scorer.metric(np.array([lay]))[0]
        ref = reference_metric(d, sites, pairs, lay)
        np.testing.assert_array_equal(m, ref)  # bit for bit compute_bounds
        ref_loss = loss_from_metric(d.objective, ref[None], pairs.weights)[0]
        assert scorer.loss(np.array([lay]))[0] == pytest.approx(ref_loss, rel=RTOL)
    # a pickled scorer (what a worker receives) leaves its pair blocks behind, scores the same
    sent = pickle.loads(pickle.dumps(scorer))
    assert "_kernel_inputs" in vars(scorer) and "_kernel_inputs" not in vars(sent)
    np.testing.assert_array_equal(sent.metric(np.array(layouts[:4])), got)
    if not los:  # 2 RISs without LOS: 6 channel parameters for 7 states
        assert np.all(np.isinf(scorer.metric(np.array([(0, 1)]))))


BLOCK = {
    "kind": "prism",
    "name": "block",
    "footprint": [[0.5, 0.5], [2.5, 0.5], [2.5, 2.5], [0.5, 2.5]],
    "height_m": 3.5,
}
"""A tall block: it hides sites from points, so some pairs (and some pair chunks) are blind."""


@pytest.mark.parametrize("environment", [None, {"obstacles": [BLOCK]}])
def test_kernel_reuses_partial_sums_with_the_same_bits(environment: Any) -> None:
    """The compiled score keeps the partial sums (LOS + the first sites) of the last layout and
    reuses them for the next layouts that start with the same sites: every layout of an
    exhaustive (lexicographic) batch – long shared prefixes, chunks where every pair is blind
    in between – gives the numpy route's bits, and each layout scored alone or in a shuffled
    batch (no reuse) the same bits again."""
    from ris_planner.planning.search.layouts import all_layouts

    doc = plan_doc(
        candidates=ring(7),
        rx_map={**GRID, "points": [ring(7)[0]["position"]]},  # a UE on site 0: degenerate
        pairs={"sample": 200, "seed": 4},
        environment=environment,
    )
    _, _, _, scorer = setup(doc)
    for n_ris in (2, 3, 4):
        lay = all_layouts(7, n_ris)
        got = scorer.metric(lay)
        np.testing.assert_array_equal(got, scorer.metric_reference(lay))
        assert np.isinf(got).any() and np.isfinite(got).any()
        perm = np.random.default_rng(n_ris).permutation(len(lay))
        np.testing.assert_array_equal(scorer.metric(lay[perm]), got[perm])
        for k in (0, len(lay) // 2, len(lay) - 1):
            np.testing.assert_array_equal(scorer.metric(lay[k : k + 1])[0], got[k])
    if environment is not None:
        assert scorer.cache.present is not None and not scorer.cache.present.all()


def test_fig10_anchor_search_beats_l_and_parallel_and_more_ris_improve() -> None:
    res = run_plan(plan_preset("fig10-anchors"), executor=SerialExecutor())
    tx, rx = fig10_pairs()

    def unordered(a: Any, b: Any) -> list[tuple[tuple[float, ...], ...]]:
        return sorted(tuple(sorted((tuple(p), tuple(q)))) for p, q in zip(a, b, strict=True))

    assert unordered(res.pairs.tx, res.pairs.rx) == unordered(tx, rx)  # the Fig. 10 pairs
    obj = res.document.objective
    w = np.full(2 * len(tx), 1 / (2 * len(tx)))

    def preset_objective(name: str) -> float:
        """The objective over both directions of every unordered pair, half weight each: the
        reverse direction's PEB_R is this direction's PEB_T (the state FIM is permuted; tested
        in test_planning_environment), taken from the same compute_bounds call."""
        scen = load_scenario(preset_document(name) | {"codebook": {"kind": "expected_random"}})
        res = compute_bounds(scen, tx=tx, rx=rx)
        assert res.peb_tx is not None
        peb = np.concatenate([res.peb_rx, res.peb_tx])
        return float(objective_value(obj, peb[None], w)[0])

    best = {c.ris_count: c.ranked[0] for c in res.counts}
    assert best[2][1] <= preset_objective("2-ris-L")
    assert best[2][1] <= preset_objective("2-ris-P")
    assert best[3][1] < best[2][1]
    assert best[4][1] < best[3][1]
    assert best[4][1] == pytest.approx(preset_objective("4-ris"), rel=RTOL)
    # every 2-RIS layout's score is the independent compute_bounds value of that layout
    ranked2 = dict(res.counts[0].ranked)
    assert ranked2[(0, 1)] == pytest.approx(preset_objective("2-ris-L"), rel=RTOL)
    assert ranked2[(0, 2)] == pytest.approx(preset_objective("2-ris-P"), rel=RTOL)
    out = res.to_json()
    json.dumps(out, allow_nan=False)
    assert [b["ris_count"] for b in out["by_count"]] == [2, 3, 4]
    assert out["by_count"][1]["marginal_gain"] == pytest.approx(best[2][1] - best[3][1])
    objs = [lay["objective"] for lay in out["layouts"]]
    assert objs == sorted(objs)  # lower is better for a quantile


@pytest.mark.parametrize(
    "objective",
    [
        {"kind": "mean_capped", "metric": "rx", "cap_m": 0.5},
        {"kind": "coverage", "metric": "max", "threshold_m": 0.1},
        {"kind": "quantile", "metric": "tx", "q": 0.8},
    ],
)
def test_greedy_agrees_with_exhaustive(objective: dict[str, Any]) -> None:
    doc = plan_doc(candidates=ring(9), objective=objective, search={"restarts": 2, "seed": 4})
    d, sites, _, scorer = setup(doc)
    ex = exhaustive(scorer, len(sites), 3, SerialExecutor())
    gr = greedy(scorer, len(sites), 3, d.search, SerialExecutor())
    assert gr.ranked(1) == ex.ranked(1)
    assert gr.evaluated < ex.evaluated  # it did not enumerate everything
    again = greedy(scorer, len(sites), 3, d.search, SerialExecutor())
    assert again.as_dict() == gr.as_dict()  # seeded, reproducible


def test_weighted_quantile_and_objectives_brute_force(rng: np.random.Generator) -> None:
    vals = rng.exponential(size=(5, 40))
    vals[0, :7] = np.inf
    w = rng.uniform(0, 1, 40)
    w /= w.sum()
    for q in (0.1, 0.5, 0.9):
        got = weighted_quantile(vals, w, q)
        for b in range(5):  # smallest v with weighted CDF(v) ≥ q
            cands = sorted(vals[b])
            ref = next(v for v in cands if w[vals[b] <= v].sum() >= q - 1e-12)
            assert got[b] == ref
    cov = objective_value(
        PlanDocument.model_fields["objective"].annotation.model_validate(  # type: ignore[union-attr]
            {"kind": "coverage", "threshold_m": 0.5}
        ),
        vals,
        w,
    )
    np.testing.assert_allclose(cov, [(w * (v <= 0.5)).sum() for v in vals], rtol=1e-12)
    assert not np.any(np.isnan(cov))


def test_maps_pairs_and_walls() -> None:
    d = PlanDocument.model_validate(
        plan_doc(
            tx_map={"points": [[0, 0, 0], [1, 0, 0]], "weights": [1, 3]},
            rx_map={"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}},
            pairs="all",
        )
    )
    txm, rxm = build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx")
    assert len(rxm.points) == 49  # stop included
    pairs = build_pairs(txm, rxm, d.pairs, d.max_pairs)
    assert pairs.size == 2 * 49 - 2  # the two coinciding positions dropped
    assert pairs.weights.sum() == pytest.approx(1.0)
    assert pairs.weights[pairs.tx_index == 1][0] == pytest.approx(3 * pairs.weights[0])
    # seeded sample: reproducible, distinct positions
    s1 = build_pairs(txm, rxm, PlanDocument.model_validate(plan_doc()).pairs, 10**5)
    s2 = build_pairs(txm, rxm, PlanDocument.model_validate(plan_doc()).pairs, 10**5)
    np.testing.assert_array_equal(s1.tx, s2.tx)
    assert np.all(np.linalg.norm(s1.tx - s1.rx, axis=1) > 0)
    # roads: lattice along and across, all at the height
    road = d.tx_map.model_validate(
        {"roads": [{"points": [[0, 0], [10, 0]], "width_m": 4, "step_m": 1, "height_m": 1.2}]}
    ).roads[0]  # type: ignore[index]
    pts = road_points(road).points
    assert len(pts) == 11 * 5 and np.all(pts[:, 2] == 1.2)
    assert pts[:, 1].min() == -2 and pts[:, 1].max() == 2
    # a repeated end vertex adds no samples (it once stacked 5 copies of the end point)
    repeated = d.tx_map.model_validate(
        {"roads": [{"points": [[0, 0], [10, 0], [10, 0]], "width_m": 4, "step_m": 1}]}
    ).roads[0]  # type: ignore[index]
    np.testing.assert_array_equal(road_points(repeated).points[:, :2], pts[:, :2])
    # csv
    csv_map = d.tx_map.model_validate({"csv_text": "x,y,z,weight\n0,0,0,2\n1,1,0,0\n"})
    pm = build_map(csv_map, "tx")
    assert len(pm.points) == 1 and pm.weights[0] == 2
    # a rectangle's sites face outward, a segment's face the chosen side
    doc = PlanDocument.model_validate(
        plan_doc(
            candidates=[],
            walls=[
                {"rectangle": [0, 0, 4, 2], "heights_m": [3], "spacing_m": 2, "tilts_rad": [0.2]},
                {"start": [0, -5], "end": [4, -5], "heights_m": [2], "spacing_m": 4},
            ],
        )
    )
    poses = wall_poses(doc.walls[0])
    assert len(poses) == 2 + 1 + 2 + 1
    for pos, ori, _ in poses:
        face = rotation_matrix(ori)[:, 0]
        out = np.asarray(pos[:2]) - [2, 1]
        assert np.dot(face[:2], out) > 0 and face[2] < 0  # outward, tilted down
    ((pos, ori, _),) = wall_poses(doc.walls[1])
    assert pos == [2.0, -5.0, 2.0]
    np.testing.assert_allclose(rotation_matrix(ori)[:, 0], [0, 1, 0], atol=1e-15)
    assert len(expand_sites(doc)) == 7


BAD: list[tuple[dict[str, Any], str]] = [
    (plan_doc(candidates=[]), "no candidate sites"),
    (plan_doc(ris_count=[7]), "exceeds the 6 candidate sites"),
    (plan_doc(tx_map={"points": [[0, 0, 0]], "weights": [0]}), "tx_map is empty"),
    (plan_doc(rx_map={"points": []}), "points is empty"),
    (plan_doc(rx_map={"grid": {"x": [0, 3, -1], "y": [0, 0, 1], "z": [0, 0, 1]}}), "step"),
    (
        plan_doc(
            tx_map={"grid": {"x": [0, 99, 0.1], "y": [0, 99, 0.1], "z": [0, 0, 1]}},
            pairs="all",
        ),
        "max_pairs",
    ),
    (plan_doc(pairs={"sample": 30000}), "max_pairs = 20000"),
    (plan_doc(codebook={"kind": "random", "seed": 0}), "expected_random"),
    (plan_doc(objective={"kind": "coverage"}), "threshold_m"),
    (plan_doc(known=["tx"], objective={"kind": "quantile", "metric": "max", "q": 0.5}), "'tx'"),
    (plan_doc(search={"method": "exhaustive", "max_exhaustive": 5}), "max_exhaustive = 5"),
]


@pytest.mark.parametrize(("doc", "message"), BAD)
def test_bad_input_names_the_limit(doc: dict[str, Any], message: str) -> None:
    with pytest.raises((ValidationError, RisPlannerError)) as exc:
        run_plan(doc, executor=SerialExecutor())
    assert message in str(exc.value)
    if message.startswith("max_"):
        assert isinstance(exc.value, LimitExceededError)


def test_schema_fields_have_descriptions() -> None:
    schema = PlanDocument.model_json_schema()
    missing = []
    for name, model in [("PlanDocument", schema), *schema["$defs"].items()]:
        for field, prop in model.get("properties", {}).items():
            if "description" not in prop:
                missing.append(f"{name}.{field}")
    assert not missing
    assert set(PLAN_PRESET_NAMES) == {"fig10-anchors", "junction", "hall"}
    for name in PLAN_PRESET_NAMES:
        PlanDocument.model_validate(plan_preset(name))


def test_cli_plan_writes_json_and_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["plan", "--preset", "fig10-anchors", "--out", str(tmp_path), "--workers", "1"]
    assert main(args) == 0
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["layouts"][0]["sites"] == [0, 1, 2, 3]
    assert {b["ris_count"] for b in plan["by_count"]} == {2, 3, 4}
    for name in ("topview", "heatmap", "cdf"):
        assert (tmp_path / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(plan_doc(ris_count=[9])))
    assert main(["plan", str(bad), "--out", str(tmp_path)]) == 2
    assert "exceeds the 6 candidate sites" in capsys.readouterr().err


def test_layout_enumeration_is_complete() -> None:
    _, sites, _, scorer = setup(plan_doc(candidates=ring(5)))
    out = exhaustive(scorer, len(sites), 2, SerialExecutor())
    assert set(out.as_dict()) == set(itertools.combinations(range(5), 2))
    tie = SearchOutcome(np.array([[2, 3], [0, 4], [0, 3], [1, 2]]), np.array([1.0, 1.0, 1.0, 0.5]))
    assert [lay for lay, _ in tie.ranked(4)] == [(1, 2), (0, 3), (0, 4), (2, 3)]


def test_heatmap_with_fixed_tx_is_compute_bounds() -> None:
    doc = plan_doc(heatmap_tx=[0.5, 0.5, 0.0], ris_count=[2, 3])
    res = run_plan(doc, executor=SerialExecutor())
    pts, vals, lay = res.heatmap()
    assert len(lay) == 3 and len(pts) == len(res.rx_map.points)
    ok = np.linalg.norm(pts - [0.5, 0.5, 0.0], axis=1) > 0
    assert np.all(np.isnan(vals[~ok])) and np.all(vals[ok] > 0)
    scen = Scenario(
        ris=[res.sites[s].ris for s in lay],
        tx=[0.5, 0.5, 0.0],
        rx=pts[ok][7].tolist(),
        codebook={"kind": "expected_random"},
    )
    assert vals[ok][7] == pytest.approx(compute_bounds(scen).peb_rx[0], rel=RTOL)


def test_heatmap_of_symmetric_layout_is_symmetric() -> None:
    """Four anchors facing the centre and a centred grid: mirroring x or y maps the layout, the
    TX map and the RX map onto themselves, so the median-over-TX map must be mirror-symmetric
    (whatever subset of pairs the plan scored). Values are medians of bounds whose FIMs have
    scaled cond ≤ ~1e8, hence agreement to 1e-6 relative, not bit for bit."""
    res = run_plan(plan_preset("fig10-anchors"), executor=SerialExecutor())
    pts, vals, lay = res.heatmap()
    assert lay == (0, 1, 2, 3) and np.all(np.isfinite(vals))
    key = {tuple(np.round(p, 6)): v for p, v in zip(pts, vals, strict=True)}
    for p, v in zip(pts, vals, strict=True):
        for mirror in ((-1, 1, 1), (1, -1, 1)):
            assert key[tuple(np.round(p * mirror, 6) + 0.0)] == pytest.approx(v, rel=1e-6)


def test_plan_file_with_csv_map_and_progress(tmp_path: Path) -> None:
    pts = [[x, y, 0.0] for x in range(-3, 4) for y in range(-3, 4)]
    (tmp_path / "ues.csv").write_text(
        "x,y,z,weight\n" + "".join(f"{x},{y},{z},{1 + (x > 0)}\n" for x, y, z in pts)
    )
    doc = plan_doc(tx_map={"csv": "ues.csv"}, rx_map={"csv": "ues.csv"}, ris_count=[2, 3])
    (tmp_path / "plan.json").write_text(json.dumps(doc))
    loaded = load_plan_file(tmp_path / "plan.json")
    assert "csv_text" in loaded["tx_map"]
    seen: list[float] = []
    res = run_plan(loaded, progress=lambda f, m: seen.append(f), executor=SerialExecutor())
    assert seen == sorted(seen) and seen[-1] == 1.0
    np.testing.assert_array_equal(res.tx_map.points, np.array(pts))
    assert res.tx_map.weights.max() == 2
    (tmp_path / "bad.json").write_text(json.dumps(plan_doc(tx_map={"csv": "missing.csv"})))
    with pytest.raises(RisPlannerError, match=r"missing\.csv"):
        load_plan_file(tmp_path / "bad.json")


def test_issue_document_form_is_accepted() -> None:
    issue_doc = {
        "system": {"tx_power_dbm": 30},
        "ris": {"rows": 10, "cols": 10},
        "candidates": [{"position": [-4, 0, 2], "orientation": [0, 0.52, 0]}],
        "tx_map": {"points": [[0, 0, 0], [1, 0, 0]], "weights": [1, 1]},
        "rx_map": {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}},
        "pairs": "all",
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 10},
        "ris_count": [2, 3],
        "codebook": {"kind": "expected_random"},
        "known": [],
        "search": {"method": "auto"},
    }
    PlanDocument.model_validate(issue_doc)
    more = [{"position": c["position"], "orientation": c["orientation"]} for c in ring(4)]
    res = run_plan(issue_doc | {"candidates": issue_doc["candidates"] + more})
    out = res.to_json()
    assert out["pairs"] == 2 * 49 - 2
    assert [b["ris_count"] for b in out["by_count"]] == [2, 3]
    assert all(0 < lay["objective"] <= 10 for lay in out["layouts"])


def test_site_cache_budget_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    """Above the budget even as float32: refused before any work, naming the budget and its
    setting; a bad setting is named too."""
    doc = plan_doc(candidates=ring(450), pairs="all")  # 450 × 9506 pairs: 456 MiB as float32
    monkeypatch.setenv("RIS_PLANNER_CACHE_MEMORY_MB", "400")
    with pytest.raises(LimitExceededError, match="site-cache budget of 400 MiB"):
        run_plan(doc, executor=SerialExecutor())
    monkeypatch.setenv("RIS_PLANNER_CACHE_MEMORY_MB", "lots")
    with pytest.raises(RisPlannerError, match="RIS_PLANNER_CACHE_MEMORY_MB must be an integer"):
        run_plan(doc, executor=SerialExecutor())
