"""Candidate sites on facades and along roads (:mod:`ris_planner.io.candidates`): the layout
against a brute-force reference written from the rules (a rectangle and an L-shaped building,
either winding: count per facade, outward azimuth, corner clearance, offset out of the prism),
facades facing an empty or a blocked side give nothing, poles stand beside the road facing
across it, no candidate of the Helsinki example lies inside a building (checked with shapely,
not the scene), and the file goes into a plan as it is (import_sites / ``ris-planner import
sites`` → the same local poses; a tiny plan runs on them)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely

from ris_planner.cli import main
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.io.candidates import (
    CandidateOptions,
    _parse_site,
    candidate_sites,
    generate_candidates,
)
from ris_planner.io.frames import Frame, to_local
from ris_planner.io.geojson_read import import_features
from ris_planner.io.site_import import PLAN_DEFAULTS, import_data, plan_from_import
from ris_planner.io.site_points import import_sites
from ris_planner.model.plan import RISDefaults
from ris_planner.model.plan_physics import PLAN_MAX_ANGLE_DEG

ORIGIN = (24.94, 60.17, 5.0)
"""A frame origin in Helsinki, 5 m above the ellipsoid (heights are relative to it)."""
FRAME = Frame(ORIGIN)
HELSINKI = Path(__file__).resolve().parent.parent / "examples" / "helsinki"

POSITION_TOL_M = 1e-6
"""local → lon/lat → local moves a point by < 1 nm near the origin (test_io_frames); the
contract of the round trip is 1 µm."""
ANGLE_TOL_RAD = 1e-9
"""azimuth_deg and tilt_deg are written unrounded: degrees ↔ radians loses a few ulps."""

FOOTPRINT_AZIMUTH_TOL_DEG = 1e-7
"""The reference takes the footprint in metres, the generator the footprint after local → lon/lat
→ local (≤ 1 nm per vertex): over an 8 m edge its direction moves by ≤ 2.5e-10 rad ≈ 1.5e-8°."""

RECTANGLE = [[0.0, 0.0], [20.0, 0.0], [20.0, 12.0], [0.0, 12.0]]
L_SHAPE = [[0.0, 0.0], [20.0, 0.0], [20.0, 8.0], [8.0, 8.0], [8.0, 20.0], [0.0, 20.0]]
OPTIONS = CandidateOptions(
    kinds=["facade"], spacing_m=5.0, heights_m=[4.0, 8.0, 12.0], corner_clearance_m=2.0
)
"""12 m is above the 10 m buildings: skipped."""


def geo(xy: Any) -> list[list[float]]:
    """Local [x, y(, z)] points → [lon, lat(, h)] of :data:`FRAME`."""
    return FRAME.to_geographic(np.asarray(xy, dtype=float)).tolist()


def prism(footprint: list[list[float]], height: float = 10.0, name: str = "b") -> dict[str, Any]:
    return {"kind": "prism", "name": name, "footprint": geo(footprint), "height_m": height}


def site_doc(obstacles: list[dict[str, Any]], points: list[list[float]]) -> dict[str, Any]:
    """An imported document (the shape import_features gives) with UE points at local xyz."""
    return {
        "frame": {"origin": list(ORIGIN)},
        "environment": {"obstacles": obstacles},
        "ue_map": {"points": geo(points)},
    }


def ring(centre: tuple[float, float], radius: float, n: int = 36) -> list[list[float]]:
    """UE points at 1.5 m on a circle."""
    phi = 2 * np.pi * np.arange(n) / n
    return [[centre[0] + radius * math.cos(p), centre[1] + radius * math.sin(p), 1.5] for p in phi]


def local_poses(collection: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The candidates as the plan sees them: import_sites (the file as it is) → the plan
    document's candidates → to_local; positions [S, 3] and orientations [S, 3]."""
    fragment, summary = import_sites(collection, tuple(collection["frame"]["origin"]))
    assert summary.candidates == len(collection["features"])
    local, _ = to_local({"frame": fragment["frame"], "candidates": fragment["candidates"]})
    pos = np.array([c["position"] for c in local["candidates"]])
    ori = np.array([c["orientation"] for c in local["candidates"]])
    return pos.reshape(-1, 3), ori.reshape(-1, 3)


def reference(footprint: list[list[float]], opts: CandidateOptions, top: float) -> list[tuple]:
    """Brute force from the rules: for each edge a→b of length ℓ > 2c, n = max(1, round((ℓ −
    2c)/s)) points at a + (c + (k + ½)(ℓ − 2c)/n)·u + offset·outward, outward = the side away
    from the polygon's interior (tested with shapely), at each height below the top."""
    poly = shapely.Polygon(footprint)
    out = []
    v = np.asarray(footprint)
    for e in range(len(v)):
        a, b = v[e], v[(e + 1) % len(v)]
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        normal = np.array([u[1], -u[0]])
        mid = (a + b) / 2
        if poly.contains(shapely.Point(*(mid + 1e-3 * normal))):
            normal = -normal
        usable = length - 2 * opts.corner_clearance_m
        if usable <= 0:
            continue
        n = max(1, round(usable / opts.spacing_m))
        azimuth = math.degrees(math.atan2(normal[0], normal[1])) % 360
        for k in range(n):
            xy = a + (opts.corner_clearance_m + (k + 0.5) * usable / n) * u + opts.offset_m * normal
            for h in opts.heights_m:
                if h < top:
                    out.append((e, xy[0], xy[1], h, azimuth))
    return out


def _check_against_reference(footprint: list[list[float]]) -> None:
    pts = [*ring((10.0, 10.0), 40.0), [14.0, 14.0, 1.5]]  # all around, and in the L's notch
    fc, summary = candidate_sites(site_doc([prism(footprint)], pts), OPTIONS)
    want = reference(footprint, OPTIONS, 10.0)
    assert summary.candidates == len(want) == len(fc["features"])
    pos, ori = local_poses(fc)
    props = [f["properties"] for f in fc["features"]]
    got_edges = [p["facade"] for p in props]
    assert got_edges == [w[0] for w in want]  # edges in footprint order, one per site
    np.testing.assert_allclose(pos, [[w[1], w[2], w[3]] for w in want], rtol=0, atol=POSITION_TOL_M)
    azimuth = np.array([p["azimuth_deg"] for p in props])
    diff = (azimuth - np.array([w[4] for w in want]) + 180) % 360 - 180
    np.testing.assert_allclose(diff, 0.0, atol=FOOTPRINT_AZIMUTH_TOL_DEG)
    yaw_want = np.radians(90 - np.array([w[4] for w in want]))
    d_yaw = np.angle(np.exp(1j * (ori[:, 0] - yaw_want)))
    np.testing.assert_allclose(d_yaw, 0.0, atol=ANGLE_TOL_RAD)
    np.testing.assert_allclose(ori[:, 1:], 0.0, atol=ANGLE_TOL_RAD)
    # outside the prism by the offset, at least the clearance from both corners
    poly = shapely.Polygon(footprint)
    for x, y, _ in pos:
        assert not poly.contains(shapely.Point(x, y))
        assert abs(poly.exterior.distance(shapely.Point(x, y)) - OPTIONS.offset_m) < 1e-6
        corner = min(math.dist((x, y), c) for c in footprint)
        assert corner >= math.hypot(OPTIONS.corner_clearance_m, OPTIONS.offset_m) - 1e-6
    assert all(p["kind"] == "facade" and p["building"] == "b" for p in props)
    assert all(p["sees_points"] > 0 for p in props)
    assert len({p["name"] for p in props}) == len(props)


@pytest.mark.parametrize("winding", [1, -1], ids=["ccw", "cw"])
def test_rectangle_against_brute_force(winding: int) -> None:
    footprint = RECTANGLE[::winding]
    _check_against_reference(footprint)
    # 20 m edges: round(16 / 5) = 3 sites, 12 m edges: round(8 / 5) = 2; heights 4 and 8
    assert len(reference(footprint, OPTIONS, 10.0)) == (3 + 2 + 3 + 2) * 2


@pytest.mark.parametrize("winding", [1, -1], ids=["ccw", "cw"])
def test_l_shape_against_brute_force(winding: int) -> None:
    footprint = L_SHAPE[::winding]
    _check_against_reference(footprint)
    # edges 20, 8, 12, 12, 8, 20 m → 3, 1, 2, 2, 1, 3 sites
    assert len(reference(footprint, OPTIONS, 10.0)) == 12 * 2


def test_short_edges_and_low_buildings_carry_nothing() -> None:
    square = [[0.0, 0.0], [3.9, 0.0], [3.9, 3.9], [0.0, 3.9]]  # every edge < 2 × 2 m
    low = [[x + 30, y] for x, y in RECTANGLE]
    doc = site_doc([prism(square, name="kiosk"), prism(low, 3.0, name="shed")], ring((20, 5), 50))
    fc, summary = candidate_sites(doc, OPTIONS)
    assert fc["features"] == [] and summary.candidates == 0
    reasons = summary.buildings_without_candidates
    assert "corner clearance" in reasons["B0 (kiosk)"]
    assert "no mounting height below its top" in reasons["B1 (shed)"]


def test_an_edge_just_longer_than_both_clearances_far_out_gets_its_site() -> None:
    """A 4.0016 m edge 400 m from the origin (an OSM building of central Helsinki) leaves a
    1.6 mm wall between its corner clearances: one site in its middle, not a refusal of the
    whole site (a relative test at 400 m called the two ends one point)."""
    edge = 2 * OPTIONS.corner_clearance_m + 1.6e-3
    square = [[400.0, 0.0], [400.0 + edge, 0.0], [400.0 + edge, 12.0], [400.0, 12.0]]
    pts = ring((400.0 + edge / 2, 6.0), 30.0)
    fc, summary = candidate_sites(site_doc([prism(square)], pts), OPTIONS)
    want = len(reference(square, OPTIONS, 10.0))
    assert summary.candidates == len(fc["features"]) == want > 0


def test_facades_facing_an_empty_or_blocked_side_give_nothing() -> None:
    """UE points north of building A and east beyond a tall long block C: A's north facade sees
    the north points; its east facade faces C (blocked), south and west face nobody."""
    a = prism(RECTANGLE, name="A")
    c = prism([[22.0, -50.0], [24.0, -50.0], [24.0, 62.0], [22.0, 62.0]], 30.0, name="C")
    north = [[x, 30.0, 1.5] for x in np.arange(1.0, 19.5, 2.0)]
    east = [[40.0, y, 1.5] for y in np.arange(1.0, 22.5, 2.0)]
    fc, summary = candidate_sites(site_doc([a, c], north + east), OPTIONS)
    on_a = [f["properties"] for f in fc["features"] if f["properties"]["building"] == "A"]
    assert on_a and {p["facade"] for p in on_a} == {2}  # edge (20, 12) → (0, 12): north
    assert all(abs(p["azimuth_deg"] % 360) < 1e-9 or p["azimuth_deg"] > 360 - 1e-9 for p in on_a)
    assert all(p["sees_points"] == len(north) for p in on_a)
    # an east facade of A, taken alone (no C), sees the east points: C is what blocks it
    fc_free, _ = candidate_sites(site_doc([a], north + east), OPTIONS)
    assert {f["properties"]["facade"] for f in fc_free["features"]} == {1, 2}
    assert summary.dropped_unseen > 0


def test_poles_stand_beside_the_road_facing_across() -> None:
    road = {"points": geo([[0.0, 0.0], [100.0, 0.0]]), "width_m": 8.0, "step_m": 5.0}
    road["height_m"] = ORIGIN[2] + 1.5
    doc = {"frame": {"origin": list(ORIGIN)}, "ue_map": {"roads": [road]}}
    opts = CandidateOptions(kinds=["pole"], pole_spacing_m=25.0, pole_height_m=6.0)
    fc, summary = candidate_sites(doc, opts)
    assert summary.by_kind == {"pole": 4}
    pos, ori = local_poses(fc)
    offset = 4.0 + opts.pole_setback_m
    want = [[12.5, offset, 6.0], [37.5, -offset, 6.0], [62.5, offset, 6.0], [87.5, -offset, 6.0]]
    np.testing.assert_allclose(pos, want, rtol=0, atol=POSITION_TOL_M)
    facing = np.array([[math.cos(y), math.sin(y)] for y in ori[:, 0]])
    np.testing.assert_allclose(facing, [[0, -1], [0, 1], [0, -1], [0, 1]], atol=1e-9)
    assert [f["properties"]["road"] for f in fc["features"]] == [0, 0, 0, 0]
    # every road point is in front of every pole and nothing blocks: with the open half-space
    # as field of view all are seen; with the default (the plan's 84.26°) those within it
    wide, wide_summary = candidate_sites(doc, opts.model_copy(update={"max_angle_deg": 90.0}))
    assert wide_summary.ue_points == summary.ue_points
    assert all(f["properties"]["sees_points"] == summary.ue_points for f in wide["features"])
    ue = _parse_site(doc, opts).ue_points
    for p, (x, y, z), yaw in zip(fc["features"], pos, ori[:, 0], strict=True):
        d = ue - [x, y, z]
        cos = (d[:, 0] * math.cos(yaw) + d[:, 1] * math.sin(yaw)) / np.linalg.norm(d, axis=1)
        want = int(np.count_nonzero(cos > math.cos(math.radians(PLAN_MAX_ANGLE_DEG))))
        assert p["properties"]["sees_points"] == want < summary.ue_points


def test_the_field_of_view_default_is_the_plans(capsys: pytest.CaptureFixture[str]) -> None:
    """``ris-planner sites`` and ``ris-planner import --plan`` use one field of view: the plan
    physics' PLAN_MAX_ANGLE_DEG (also the plan document's ris default), so a site kept for
    seeing a UE point sees it in the plan."""
    assert CandidateOptions().max_angle_deg == PLAN_MAX_ANGLE_DEG
    assert PLAN_DEFAULTS["ris"]["max_angle_deg"] == PLAN_MAX_ANGLE_DEG
    assert RISDefaults().max_angle_deg == PLAN_MAX_ANGLE_DEG
    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    fragment, summary = import_data(json.dumps(site).encode(), "geojson")
    plan_doc, _ = plan_from_import(fragment, "geojson", summary)
    assert plan_doc["ris"]["max_angle_deg"] == CandidateOptions().max_angle_deg
    assert main(["sites", "--help"]) == 0
    assert f"({PLAN_MAX_ANGLE_DEG:g})" in " ".join(capsys.readouterr().out.split())
    # a site whose only UE point lies 87° off its normal is dropped: the plan would not see it
    # (the south facade's one site at (10, -0.05), 4 m up, faces −y; the point is 10 m away)
    a = math.radians(87.0)
    off = [[10.0 + 10.0 * math.sin(a), -0.05 - 10.0 * math.cos(a), 4.0]]
    opts = CandidateOptions(kinds=["facade"], spacing_m=100.0, heights_m=[4.0])
    _, narrow = candidate_sites(site_doc([prism(RECTANGLE)], off), opts)
    assert narrow.candidates == 0 and narrow.dropped_unseen == narrow.generated > 0
    wide = opts.model_copy(update={"max_angle_deg": 90.0})
    fc, summary = candidate_sites(site_doc([prism(RECTANGLE)], off), wide)
    assert summary.candidates == 1 and fc["features"][0]["properties"]["facade"] == 0


def helsinki_candidates(**options: Any) -> tuple[dict[str, Any], Any]:
    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    return candidate_sites(site, CandidateOptions(**options))


def test_helsinki_no_candidate_inside_a_building() -> None:
    fc, summary = helsinki_candidates()
    assert fc["license"] == "© OpenStreetMap contributors, ODbL 1.0"
    assert summary.by_kind["facade"] > 0 and summary.by_kind["pole"] > 0
    assert summary.dropped_inside > 0  # party walls between the block's buildings
    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    fragment, _ = import_features(site, tuple(fc["frame"]["origin"]))
    env, _ = to_local({"frame": fragment["frame"], "environment": fragment["environment"]})
    pos, _ = local_poses(fc)
    for ob in env["environment"]["obstacles"]:
        poly = shapely.Polygon(ob["footprint"]).buffer(-0.01)  # the 1 cm margin of "inside"
        top = ob["base_m"] + ob["height_m"]
        inside = shapely.contains_xy(poly, pos[:, 0], pos[:, 1])
        inside &= (pos[:, 2] > ob["base_m"]) & (pos[:, 2] < top)
        assert not inside.any(), ob.get("name")
    names = [f["properties"]["name"] for f in fc["features"]]
    assert len(set(names)) == len(names)
    # max_candidates keeps those that see the most points
    few, s = helsinki_candidates(max_candidates=10)
    seen = sorted((f["properties"]["sees_points"] for f in fc["features"]), reverse=True)
    assert sorted(f["properties"]["sees_points"] for f in few["features"])[0] >= seen[9]
    assert s.dropped_max_candidates == summary.candidates - 10


def test_road_classes_choose_the_roads_with_poles() -> None:
    _, s_streets = helsinki_candidates(kinds=["pole"], road_classes=["residential"])
    every, s_every = helsinki_candidates(kinds=["pole"], road_classes=None)
    assert 0 < s_streets.roads < s_every.roads and s_streets.ue_points == s_every.ue_points
    assert 0 < s_streets.candidates <= s_every.candidates
    # an imported document's roads carry no class: all of them carry poles, and a note says so
    fragment, _ = import_features(json.loads((HELSINKI / "helsinki.geojson").read_text()))
    opts = CandidateOptions(kinds=["pole"], road_classes=["residential"])
    fc, summary = candidate_sites(fragment, opts)
    assert summary.roads == s_every.roads and fc["features"] == every["features"]
    assert any("road_classes apply to a GeoJSON site only" in n for n in summary.notes)


def test_the_file_goes_into_a_plan_as_it_is(tmp_path: Path) -> None:
    """generate → ``ris-planner import sites`` (the collection's frame, no --origin) → the same
    candidates as import_sites with the origin; the plan document takes them and runs."""
    from ris_planner.planning import SerialExecutor, run_plan

    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    fragment, _ = import_features(site)  # the imported document: frame, environment, ue_map
    fc = generate_candidates(fragment, CandidateOptions(max_candidates=6, kinds=["facade"]))
    path = tmp_path / "candidates.geojson"
    path.write_text(json.dumps(fc))
    from_file, _ = import_data(path.read_bytes(), "sites")
    direct, _ = import_sites(fc, tuple(fragment["frame"]["origin"]))
    assert from_file == direct and from_file["frame"] == fragment["frame"]
    doc = {
        "frame": fragment["frame"],
        "environment": fragment["environment"],
        "candidates": from_file["candidates"],
        "tx_map": fragment["ue_map"],
        "rx_map": fragment["ue_map"],
        "ris": {"rows": 4, "cols": 4},
        "pairs": {"sample": 30, "seed": 1},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 5.0},
        "known": ["height"],
        "ris_count": [2],
        "search": {"certificate_iterations": 0},
    }
    local, _ = to_local(doc)
    with SerialExecutor() as ex:
        result = run_plan(local, executor=ex)
    assert len(result.sites) == 6
    assert [s.name for s in result.sites] == [f["properties"]["name"] for f in fc["features"]]


def test_site_errors() -> None:
    with pytest.raises(RisPlannerError, match="no UE positions"):
        candidate_sites(site_doc([prism(RECTANGLE)], [[0, 0, 1.5]]) | {"ue_map": None})
    with pytest.raises(RisPlannerError, match="expected a GeoJSON FeatureCollection"):
        candidate_sites({"type": "Feature"})
    bad = site_doc([prism(RECTANGLE)], [[50.0, 0.0, 1.5], [40.0, 0.0, 1.5]])
    bad["ue_map"]["points"][0] = [*bad["ue_map"]["points"][0][1::-1], 1.5]  # [lat, lon]
    with pytest.raises(RisPlannerError) as err:
        candidate_sites(bad)
    assert getattr(err.value, "field", "").startswith("site.ue_map.points.0")
    with pytest.raises(LimitExceededError, match="visibility legs"):
        candidate_sites(site_doc([prism(RECTANGLE)], ring((10, 6), 30)), max_legs=10)


def test_cli_sites(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "c.geojson"
    src = str(HELSINKI / "helsinki.geojson")
    assert main(["sites", src, "--kinds", "facade", "--heights-m", "4", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    fc, summary = helsinki_candidates(kinds=["facade"], heights_m=[4.0])
    assert json.loads(out.read_text()) == fc
    assert err.startswith(f"sites: {summary.candidates} candidates ({summary.candidates} facade)")
    assert re.search(r"B23( \([^)]*\))?: no candidate: 3 m tall", err), err
    for bad, field in [
        (["--spacing-m", "0"], "spacing_m"),
        (["--kinds", "facade,tree"], "kinds"),
        (["--heights-m", "4,x"], "--heights-m"),
        (["--tilts-deg", "95"], "tilts_deg"),
    ]:
        assert main(["sites", src, *bad]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and field in err, err
    # ris-planner import sites reads the file as it is, in the site's frame
    assert main(["import", "sites", str(out)]) == 0
    fragment = json.loads(capsys.readouterr().out)
    assert fragment == import_sites(fc, tuple(fc["frame"]["origin"]))[0]
    assert main(["sites", str(tmp_path / "missing.geojson")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_a_site_in_a_projected_crs_and_one_without_buildings() -> None:
    """A GeoJSON site in EPSG:3067 named by its crs member gives the WGS84 site's candidates
    (within 1 cm), with a note; a site of roads only is laid out with the no-buildings note."""
    import pyproj

    from ris_planner.io.geojson_read import NO_BUILDINGS_WARNING

    site = json.loads((HELSINKI / "helsinki.geojson").read_text())
    t = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:3067", always_xy=True)

    def conv(c: list) -> list:
        if isinstance(c[0], int | float):
            return [*t.transform(c[0], c[1]), *c[2:]]
        return [conv(p) for p in c]

    projected = json.loads(json.dumps(site))
    for f in projected["features"]:
        f["geometry"]["coordinates"] = conv(f["geometry"]["coordinates"])
    projected["crs"] = {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3067"}}
    opts = CandidateOptions(kinds=["facade", "pole"], heights_m=[4.0])
    want, _ = candidate_sites(site, opts)
    got, summary = candidate_sites(projected, opts)
    assert got["frame"] == want["frame"] and got["license"] == want["license"]
    props = [
        {k: v for k, v in f["properties"].items() if k != "azimuth_deg"} for f in got["features"]
    ]
    assert props == [
        {k: v for k, v in f["properties"].items() if k != "azimuth_deg"} for f in want["features"]
    ]
    pos_g, ori_g = local_poses(got)
    pos_w, ori_w = local_poses(want)
    assert np.abs(pos_g - pos_w).max() < 0.01 and np.abs(ori_g - ori_w).max() < 1e-6
    assert any("converted from the crs member" in n for n in summary.notes)
    roads = {**site, "features": [f for f in site["features"] if "highway" in f["properties"]]}
    _, summary = candidate_sites(roads, CandidateOptions(kinds=["pole"]))
    assert summary.candidates > 0 and NO_BUILDINGS_WARNING in summary.notes
