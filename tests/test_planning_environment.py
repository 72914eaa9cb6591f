"""Planning in an environment: the cached score against an independent per-pair evaluation
(each pair's sub-layout of present paths through today's ``compute_bounds``), facade sites,
dropped UE points, serve warnings, unordered pairs in both directions, the hall and junction
presets, figures and bad input."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import bounds_rtol
from pydantic import ValidationError
from test_planning import ring
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.bounds.compute import compute_bounds, kept_states
from ris_planner.bounds.paths import los_clear, ris_serves
from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.scenario import Scenario
from ris_planner.physics.geometry import rotation_matrix
from ris_planner.planning import PlanDocument, PlanResult, SerialExecutor, plan_preset, run_plan
from ris_planner.planning.inputs.sites import Site, expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.outputs.report import raster, write_figures
from ris_planner.planning.scoring.scorer import Scorer, objective_value, select_metric
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility, serve_matrix

RTOL = BOUND_ACCURACY
"""Cached score vs the per-pair reference: both invert the same FIM through
ris_planner.inversion.ldl; only the summation order of the 7×7 matrices (and exact zeros for
absent paths) differs, which moves a bound by ≤ ulps·ε·cond – and the FIMs here (obstacles
remove paths, a known clock leaves 6 states) reach cond ≈ 1e6–1e7, where 1e-9 was measured to
fail by 1.5e-9. Both are reported bounds, so the rule compares them at the bounds' accuracy
contract (tests/tolerance.py, docs/concepts/numerics.md "Comparing results")."""

MIRROR_RTOL = 1e-6
"""The mirrored score (reverse direction's PEB_R taken as PEB_T of the same inversion) against
listing both directions: two inversions of permuted FIMs differ by cond·ε; numerics.md requires
bounds accurate to relative 1e-6 wherever the FIM is non-singular."""

GRID = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0.5, 0.5]}}

OBSTACLES: list[dict[str, Any]] = [
    # a concave (L-shaped) block covering grid points: they are dropped
    {
        "kind": "prism",
        "name": "L",
        "footprint": [[0.5, 0.5], [2.5, 0.5], [2.5, 1.5], [1.5, 1.5], [1.5, 2.5], [0.5, 2.5]],
        "height_m": 1.0,
    },
    # raised (a bridge): blocks legs that pass between 1.2 m and 1.8 m
    {
        "kind": "prism",
        "name": "bridge",
        "footprint": [[-3.5, -0.5], [-1.5, -0.5], [-1.5, 0.5], [-3.5, 0.5]],
        "base_m": 1.2,
        "height_m": 0.6,
    },
    {
        "kind": "wall",
        "name": "partition",
        "start": [1.0, -3.5],
        "end": [1.0, -1.2],
        "height_m": 2.5,
    },
]


def env_doc(**over: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "candidates": ring(8),
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": 300, "seed": 2},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2],
        "environment": {"obstacles": OBSTACLES},
        "search": {"method": "exhaustive"},
    }
    doc.update(over)
    return doc


def per_pair_metric(
    doc: PlanDocument,
    sites: list[Site],
    tx: Any,
    rx: Any,
    layout: tuple[int, ...],
    metric: str | None = None,
) -> Any:
    """[P] the metric of a layout, pair by pair: each pair's sub-layout of the paths that exist
    for it (the RIS serves both UEs; LOS if the system has it and the leg is clear), scored by
    ``compute_bounds`` with expected_random; fewer channel parameters than unknowns → inf."""
    scene = Scene.from_environment(doc.environment)
    serves = np.array(
        [ris_serves(scene, sites[s].ris, tx) & ris_serves(scene, sites[s].ris, rx) for s in layout]
    )  # [L, P]
    los = los_clear(scene, tx, rx) & doc.system.los
    n_states = len(kept_states(doc.known))
    out = np.full(len(tx), np.inf)
    patterns = np.vstack([serves, los[None]]).T  # [P, L + 1]
    for pat in np.unique(patterns, axis=0):
        idx = np.nonzero(np.all(patterns == pat, axis=1))[0]
        ris = [sites[s].ris for s, on in zip(layout, pat[:-1], strict=True) if on]
        if 3 * len(ris) + int(pat[-1]) < n_states:
            continue
        scen = Scenario(
            system=doc.system.model_copy(update={"los": bool(pat[-1])}),
            ris=ris,
            tx=tx[idx[0]].tolist(),
            rx=rx[idx[0]].tolist(),
            codebook={"kind": "expected_random"},
            known=doc.known,
        )
        res = compute_bounds(scen, tx=tx[idx], rx=rx[idx])
        out[idx] = select_metric(metric or doc.objective.metric, res.peb_tx, res.peb_rx)
    return out


def reference_objective(res: PlanResult, layout: tuple[int, ...]) -> float:
    """The plan's objective of a layout from :func:`per_pair_metric`; unordered pairs with
    metric rx/tx in both directions with half the weight each."""
    doc, pairs, w = res.document, res.pairs, res.pairs.weights
    metric = per_pair_metric(doc, res.sites, pairs.tx, pairs.rx, layout)
    m = doc.objective.metric
    if doc.pairs == "unordered" and m != "max" and "tx" not in doc.known:
        # the reverse direction's PEB_R is this direction's PEB_T (and vice versa): see
        # test_reverse_direction_permutes_the_state_fim
        other = "tx" if m == "rx" else "rx"
        reverse = per_pair_metric(doc, res.sites, pairs.tx, pairs.rx, layout, other)
        metric, w = np.concatenate([metric, reverse]), np.concatenate([w, w]) / 2
    return float(objective_value(doc.objective, metric[None], w)[0])


def test_reverse_direction_permutes_the_state_fim(rng: np.random.Generator) -> None:
    """Swapping TX and RX swaps the p_T and p_R blocks of the state FIM (ξ, ζ, τ and τ0 are
    symmetric in the two UEs, the clock is shared): PEB_R of j → i is PEB_T of i → j, to the
    inversion's conditioning (conftest.bounds_rtol)."""
    scen = Scenario(
        ris=[
            {"position": [x, y, 2.5], "orientation": [yaw, 0.4, 0]}
            for x, y, yaw in ((-4, 0, 0), (0, 4, -math.pi / 2), (4, 0, math.pi))
        ],
        tx=[0, 0, 0],
        rx=[1, 0, 0],
        codebook={"kind": "expected_random"},
    )
    tx, rx = rng.uniform(-3, 3, (50, 3)), rng.uniform(-3, 3, (50, 3))
    fwd, rev = compute_bounds(scen, tx=tx, rx=rx), compute_bounds(scen, tx=rx, rx=tx)
    perm = [3, 4, 5, 0, 1, 2, 6]
    permuted = fwd.fim[:, perm][:, :, perm]
    scale = np.abs(fwd.fim).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(rev.fim / scale, permuted / scale, rtol=0, atol=1e-12)
    assert fwd.peb_tx is not None
    for p in range(len(tx)):
        tol = bounds_rtol(fwd.fim[p], 1e-12)
        assert rev.peb_rx[p] == pytest.approx(fwd.peb_tx[p], rel=tol)


@pytest.mark.parametrize(
    ("known", "metric", "los"),
    [([], "rx", True), (["clock"], "max", True), (["tx"], "rx", True), ([], "tx", False)],
)
def test_cached_score_equals_per_pair_reference(known: list[str], metric: str, los: bool) -> None:
    doc = env_doc(
        known=known,
        objective={"kind": "mean_capped", "metric": metric, "cap_m": 1.0},
        system={"los": los},
    )
    res = run_plan(doc, executor=SerialExecutor())
    d, sites, pairs = res.document, res.sites, res.pairs
    present = res.cache.present
    assert present is not None and 0.2 < present.mean() < 0.98  # obstacles do block
    if los:
        assert res.cache.los_present is not None and not np.all(res.cache.los_present)
    layouts = [(0, 1), (2, 5), (0, 1, 2), (1, 3, 6), (0, 2, 4, 6), (1, 2, 5, 7)]
    n_under = n_finite = 0
    both = np.array([lay for lay in layouts if len(lay) == 3])  # kernel vs numpy route
    np.testing.assert_array_equal(res.scorer.metric(both), res.scorer.metric_reference(both))
    for lay in layouts:
        got = res.scorer.metric(np.array([lay]))[0]
        ref = per_pair_metric(d, sites, pairs.tx, pairs.rx, lay)
        np.testing.assert_array_equal(np.isinf(got), np.isinf(ref))
        fin = np.isfinite(ref)
        assert_close(got[fin], ref[fin], accuracy=RTOL)
        n_under += int(np.sum(~fin))
        n_finite += int(np.sum(fin))
    assert n_under > 0 and n_finite > 0  # both the per-pair count rule and real bounds
    # the batched visibility is ris_serves per site
    pts = build_map(d.tx_map, "tx").points
    scene = Scene.from_environment(d.environment)
    ref_serve = np.array([ris_serves(scene, s.ris, pts) for s in sites])
    np.testing.assert_array_equal(serve_matrix(scene, sites, pts), ref_serve)
    best, _ = res.counts[0].ranked[0]
    assert res.to_json()["by_count"][0]["objective"] == pytest.approx(
        reference_objective(res, best), rel=RTOL
    )


def test_pattern_factor_scales_the_cached_information() -> None:
    """q > 0 multiplies |ρ| by (cos θ_T cos θ_R)^q (cosines from the RIS normal, computed here
    from the pose): the cached 7×7 of each site is the q = 0 one times the factor squared."""
    q = 1.5
    docs = [PlanDocument.model_validate(env_doc(ris={"pattern_exponent": e})) for e in (0, q)]
    caches = []
    for d in docs:
        sites = expand_sites(d)
        pm = build_map(d.tx_map, "tx")
        pairs = build_pairs(pm, pm, d.pairs, d.max_pairs)
        vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, True)
        caches.append((build_site_cache(d.system, sites, pairs, visibility=vis), sites, pairs))
    (c0, sites, pairs), (cq, _, _) = caches
    for s, site in enumerate(sites):
        normal = rotation_matrix(site.ris.orientation)[:, 0]
        c = np.asarray(site.ris.position)

        def cos(p: Any, normal: Any = normal, c: Any = c) -> Any:
            v = p - c
            return (v @ normal) / np.linalg.norm(v, axis=1)

        factor = (np.maximum(cos(pairs.tx), 0) * np.maximum(cos(pairs.rx), 0)) ** q
        # entries on the scale of their pair's largest (an off-diagonal entry can be a small
        # difference of large terms; the factor enters the gain before the Schur complement)
        scale = np.abs(c0.packed[:, s]).max(axis=0) * factor**2
        np.testing.assert_allclose(
            cq.packed[:, s] / np.where(scale > 0, scale, 1.0),
            c0.packed[:, s] * factor**2 / np.where(scale > 0, scale, 1.0),
            rtol=0,
            atol=1e-12,
        )
    assert cq.present is not None and c0.present is not None
    np.testing.assert_array_equal(cq.present, c0.present)


def test_unordered_pairs_count_both_directions_and_map_order_does_not_matter() -> None:
    pts = [[x, y, z] for x in (-3.0, -1.0, 1.0, 3.0) for y in (-2.0, 0.0, 2.5) for z in (0, 0.5)]
    pts = [p for p in pts if not (0.5 < p[0] < 2.5 and 0.5 < p[1] < 2.5)]
    base = env_doc(
        tx_map={"points": pts},
        rx_map={"points": pts},
        pairs="unordered",
        objective={"kind": "coverage", "metric": "rx", "threshold_m": 0.05},
        ris_count=[3],
    )
    res = run_plan(base, executor=SerialExecutor())
    assert res.scorer.mirror and res.pairs.size == len(pts) * (len(pts) - 1) // 2
    rev = copy.deepcopy(base)
    rev["tx_map"]["points"] = rev["rx_map"]["points"] = pts[::-1]
    res_rev = run_plan(rev, executor=SerialExecutor())
    lay = res.counts[0].ranked[0][0]
    assert res_rev.counts[0].ranked == res.counts[0].ranked  # bit for bit
    assert -res.counts[0].ranked[0][1] == pytest.approx(reference_objective(res, lay), rel=RTOL)
    for metric in ("rx", "tx"):  # the mirrored score is the score of both directions listed
        d = PlanDocument.model_validate(
            {**base, "objective": {"kind": "quantile", "q": 0.7, "metric": metric}}
        )
        mirrored = Scorer(res.cache, res.pairs.weights, d.objective, (), mirror=True)
        both = build_pairs(res.tx_map, res.tx_map, "unordered", 10**5, both_directions=True)
        vis = pair_visibility(res.scene, res.sites, both, True)  # type: ignore[arg-type]
        cache = build_site_cache(d.system, res.sites, both, visibility=vis)
        explicit = Scorer(cache, both.weights, d.objective, ())
        layouts = np.array([lay, (0, 3, 5), (1, 2, 6)])
        np.testing.assert_allclose(mirrored.loss(layouts), explicit.loss(layouts), rtol=MIRROR_RTOL)
        np.testing.assert_array_equal(mirrored.metric(layouts), mirrored.metric_reference(layouts))
    # a known TX breaks the symmetry: both directions are listed
    known = run_plan({**base, "known": ["tx"]}, executor=SerialExecutor())
    assert not known.scorer.mirror and known.pairs.size == 2 * res.pairs.size


def test_facade_sites_face_outward_for_any_winding() -> None:
    ccw = [[0, 0], [6, 0], [6, 3], [3, 3], [3, 6], [0, 6]]  # concave L
    env = {
        "obstacles": [
            {"kind": "prism", "name": "ccw", "footprint": ccw, "height_m": 5, "base_m": 1},
            {
                "kind": "prism",
                "name": "cw",
                "footprint": [[20, 0], [20, 4], [24, 4], [24, 0]],
                "height_m": 8,
            },
        ]
    }
    doc = PlanDocument.model_validate(
        env_doc(
            candidates=[],
            environment=env,
            facades=[
                {"of": ["ccw", "cw"], "heights_m": [2, 9], "spacing_m": 3, "offset_m": 0.05},
            ],
            tx_map={"points": [[10, 10, 1.5], [12, 10, 1.5]]},
            rx_map={"points": [[10, 10, 1.5], [12, 10, 1.5]]},
        )
    )
    sites = expand_sites(doc)
    scene = Scene.from_environment(doc.environment)
    # ccw: edges 6, 3, 3, 3, 3, 6 m → 2+1+1+1+1+2 sites; cw: 4 edges of 4 m → 1 each;
    # heights 1+2 = 3 and min(1+9, 6) = 6 (ccw), 2 and 8 (cw)
    assert len(sites) == 2 * (8 + 4)
    assert sorted({s.ris.position[2] for s in sites[:16]}) == [3.0, 6.0]
    assert sorted({s.ris.position[2] for s in sites[16:]}) == [2.0, 8.0]
    for s in sites:
        p = np.asarray(s.ris.position)
        face = rotation_matrix(s.ris.orientation)[:, 0]
        n = face[:2] / np.linalg.norm(face[:2])
        z = min(p[2], 4.0 if s.name.startswith("facades 0 cw") else 5.0)  # a height inside
        front = [*(p[:2] + 0.5 * n), z]
        back = [*(p[:2] - 0.5 * n), z]
        assert scene.inside(np.array([front]))[0] == -1, s.name
        assert scene.inside(np.array([back]))[0] >= 0, s.name
        # 5 cm in front of the facade: its distance to the footprint edges
        assert scene.inside(np.array([[*(p[:2] - 0.06 * n), z]]), margin=0.0)[0] >= 0
        assert scene.inside(np.array([[*(p[:2] - 0.04 * n), z]]), margin=0.0)[0] == -1


def test_candidate_facing_into_its_building_serves_nothing_and_is_warned() -> None:
    env = {
        "obstacles": [
            {
                "kind": "prism",
                "name": "b1",
                "footprint": [[-2, 4], [2, 4], [2, 8], [-2, 8]],
                "height_m": 10,
            },
        ]
    }
    facade = [0.0, 4.0, 3.0]
    cands = [
        {"position": facade, "orientation": [math.pi / 2, 0.2, 0], "name": "into b1"},
        {"position": facade, "orientation": [-math.pi / 2, 0.2, 0], "name": "street"},
        *ring(4, radius=3.5),
    ]
    res = run_plan(env_doc(candidates=cands, environment=env), executor=SerialExecutor())
    out = res.to_json()
    assert res.cache.present is not None
    assert not np.any(res.cache.present[0]) and np.all(res.cache.packed[:, 0] == 0)
    assert np.mean(res.cache.present[1]) > 0.5
    warned = [w for w in out["warnings"] if "into b1" in w]
    assert len(warned) == 1 and warned[0].startswith("candidate 0 (into b1) serves 0.0%")
    assert not any("street" in w for w in out["warnings"])
    assert all(0 not in lay["sites"] for lay in out["layouts"])


def test_points_inside_prisms_are_dropped_and_counted() -> None:
    res = run_plan(env_doc(pairs="all", max_pairs=10**5), executor=SerialExecutor())
    pts = build_map(PlanDocument.model_validate(env_doc()).tx_map, "tx").points
    x, y, z = pts.T
    margin = 0.01  # brute force: inside the L (two rectangles) by more than 1 cm, z < 1 m
    in_a = (x > 0.5 + margin) & (x < 2.5 - margin) & (y > 0.5 + margin) & (y < 1.5)
    in_b = (x > 0.5 + margin) & (x < 1.5 - margin) & (y >= 1.5) & (y < 2.5 - margin)
    inside = (in_a | in_b) & (z > margin) & (z < 1 - margin)
    assert int(inside.sum()) == 3  # (1, 1), (2, 1), (1, 2) at z = 0.5; z = 0 is on the base
    out = res.to_json()
    assert out["dropped_points"] == {"tx": 3, "rx": 3}
    assert out["tx_points"] == len(pts) - 3
    assert not np.any(np.all(np.isclose(res.tx_map.points, [1, 1, 0.5]), axis=1))
    free = run_plan({**env_doc(), "environment": None}, executor=SerialExecutor()).to_json()
    assert free["dropped_points"] == {"tx": 0, "rx": 0} and free["warnings"] == []


def _reduced_junction(reverse: bool) -> dict[str, Any]:
    doc = plan_preset("junction")
    for w in doc["walls"]:
        w["spacing_m"], w["tilts_rad"] = 17.0, [0.45]
    for key in ("tx_map", "rx_map"):
        roads = doc[key]["roads"]
        for r in roads:
            r["step_m"] = 8.0
        if reverse:
            doc[key]["roads"] = roads[::-1]
    doc["ris_count"] = [2, 3]
    return doc


def test_junction_reversed_road_order_gives_the_same_best_layout_and_rescores() -> None:
    res = run_plan(_reduced_junction(False), executor=SerialExecutor())
    rev = run_plan(_reduced_junction(True), executor=SerialExecutor())
    assert not np.array_equal(res.tx_map.points, rev.tx_map.points)  # the order did change
    for a, b in zip(res.counts, rev.counts, strict=True):
        assert a.ranked[0] == b.ranked[0]
    assert res.cache.los_present is not None and not np.all(res.cache.los_present)
    for entry in res.to_json()["by_count"]:
        lay = tuple(entry["sites"])
        assert entry["objective"] == pytest.approx(reference_objective(res, lay), rel=RTOL)


def test_every_junction_candidate_faces_the_street() -> None:
    doc = PlanDocument.model_validate(plan_preset("junction"))
    scene = Scene.from_environment(doc.environment)
    sites = expand_sites(doc)
    assert len(sites) == 64
    for s in sites:
        p = np.asarray(s.ris.position)
        face = rotation_matrix(s.ris.orientation)[:, 0]
        n = face[:2] / np.linalg.norm(face[:2])
        assert scene.inside(np.array([[*(p[:2] + n), p[2]]]))[0] == -1, s.name  # the street
        assert scene.inside(np.array([[*(p[:2] - n), p[2]]]))[0] >= 0, s.name  # its building
        assert abs(p[0]) == 6 or abs(p[1]) == 6


def test_hall_plan_rescored_and_figures(tmp_path: Path) -> None:
    doc = plan_preset("hall")
    for w in doc["walls"]:
        w["spacing_m"], w["heights_m"] = 13.0, [5.0]
    for key in ("tx_map", "rx_map"):
        for r in doc[key]["roads"]:
            r["step_m"] = 3.0
    doc["ris_count"] = [3]
    res = run_plan(doc, executor=SerialExecutor())
    entry = res.to_json()["by_count"][0]
    assert entry["objective"] == pytest.approx(
        reference_objective(res, tuple(entry["sites"])), rel=RTOL
    )
    assert res.cache.los_present is not None and 0.3 < res.cache.los_present.mean() < 0.9
    paths = write_figures(res, tmp_path)
    for p in paths.values():
        assert p.read_bytes()[:4] == b"\x89PNG"


def test_heatmap_raster_masks_obstacles_and_empty_cells() -> None:
    env = PlanDocument.model_validate(env_doc()).environment
    scene = Scene.from_environment(env)
    xs, ys = np.meshgrid(np.arange(-3.0, 3.5, 1.0), np.arange(-3.0, 3.5, 1.0))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 0.5)])
    keep = scene.inside(pts) < 0
    pts = pts[keep]
    vals = np.linspace(1, 2, len(pts))
    vals[0] = np.nan
    vals[1] = np.inf
    x_e, y_e, grid, empty = raster(pts, vals, scene)
    np.testing.assert_allclose(x_e[[0, -1]], [-3.5, 3.5])
    assert grid.shape == (7, 7)
    cell = {
        (round(x), round(y)): (i, j)
        for j, x in enumerate(x_e[:-1] + 0.5)
        for i, y in enumerate(y_e[:-1] + 0.5)
    }
    assert empty[cell[(1, 1)]] and empty[cell[(2, 1)]]  # inside the L: masked
    assert empty[cell[(-3, -3)]]  # its only point has no value (NaN)
    assert np.isinf(grid[cell[(-2, -3)]]) and not empty[cell[(-2, -3)]]  # blind
    assert grid[cell[(3, 3)]] == 2.0


BAD_ENV: list[tuple[dict[str, Any], str]] = [
    (
        env_doc(facades=[{"of": ["b9"], "heights_m": [4], "spacing_m": 5}]),
        "facades[0].of: no obstacle named 'b9'",
    ),
    (
        env_doc(facades=[{"of": ["partition"], "heights_m": [4], "spacing_m": 5}]),
        "obstacle 'partition' is a wall",
    ),
    (
        env_doc(environment=None, facades=[{"of": ["L"], "heights_m": [4], "spacing_m": 5}]),
        "no obstacle named 'L'",
    ),
    (
        env_doc(facades=[{"of": ["L"], "heights_m": [-1], "spacing_m": 5}]),
        "heights_m must be ≥ 0",
    ),
    (
        env_doc(
            environment={
                "obstacles": [
                    {
                        "kind": "prism",
                        "name": "flat",
                        "footprint": [[0, 0], [1, 1], [2, 2]],
                        "height_m": 3,
                    },
                ]
            }
        ),
        "prism 'flat': footprint has zero area",
    ),
    (
        env_doc(
            environment={
                "obstacles": [
                    {
                        "kind": "prism",
                        "name": "bow",
                        "footprint": [[0, 0], [2, 2], [2, 0], [0, 2]],
                        "height_m": 3,
                    },
                ]
            }
        ),
        "prism 'bow': footprint is self-intersecting",
    ),
    (
        env_doc(candidates=[{"position": [1.0, 1.0, 0.5]}, *ring(3)]),
        "1 candidate site lies inside a building (the RIS centre more than 1 cm inside a"
        " prism): candidate 0 (candidate 0) at [x, y, z] = [1.00, 1.00, 0.50] m inside"
        " environment obstacle 0 (prism 'L')",
    ),
    (env_doc(heatmap_tx=[2.0, 1.0, 0.5]), "heatmap_tx [2.0, 1.0, 0.5] lies inside"),
    (
        env_doc(tx_map={"points": [[1.0, 1.0, 0.5]]}),
        "tx_map: every point lies inside a prism",
    ),
]


@pytest.mark.parametrize(("doc", "message"), BAD_ENV)
def test_bad_environment_input_is_named(doc: dict[str, Any], message: str) -> None:
    with pytest.raises((ValidationError, RisPlannerError)) as exc:
        run_plan(doc, executor=SerialExecutor())
    assert message in str(exc.value)


def test_cli_names_an_unknown_facade_building(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ris_planner.cli import main

    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(env_doc(facades=[{"of": ["b9"], "heights_m": [4], "spacing_m": 5}])))
    assert main(["plan", str(bad), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "facades[0].of: no obstacle named 'b9'" in err and "Traceback" not in err
