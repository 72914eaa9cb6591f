"""Geographic frames: round trips, accuracy of the local tmerc frame against geodesics,
document conversion at the boundary and its errors."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

pyproj = pytest.importorskip("pyproj")

from ris_planner.core.errors import DocumentFieldError, RisPlannerError  # noqa: E402
from ris_planner.io.frames import MAX_FRAME_RADIUS_M, Frame, to_local  # noqa: E402

GEOD = pyproj.Geod(ellps="WGS84")

ROUND_TRIP_TOLERANCE_M = 1e-6
"""lon/lat → local → lon/lat: PROJ's tmerc (Poder/Engsager series) inverts to nanometres;
1 µm is a thousand times below the 1 mm a site plan needs."""

EARTH_RADIUS_MIN_M = 6.36e6
"""A lower bound of the Earth's radii of curvature at the origins tested (|lat| ≤ 61°)."""

DISTANCE_SLACK = 1.01
"""tmerc distance from the origin vs the geodesic: error ≤ 1.01 · d³/(6R²) (the leading term of
the point scale k ≈ 1 + x²/(2R²), integrated; the 1 % covers its higher orders)."""

ORIGINS = [(24.949, 60.1655, 0.0), (0.0, 0.0, 0.0), (-70.6, -33.4, 500.0), (179.99, 10.0, 0.0)]


def _geodesic_points(origin: tuple[float, float, float], n: int, d_max: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    az = rng.uniform(-180, 180, n)
    d = rng.uniform(0, d_max, n)
    lon, lat, _ = GEOD.fwd(np.full(n, origin[0]), np.full(n, origin[1]), az, d)
    return np.column_stack([lon, lat, origin[2] + rng.uniform(0, 50, n)]), az, d


@pytest.mark.parametrize("origin", ORIGINS)
def test_round_trip_lonlat_local_lonlat(origin: tuple[float, float, float]) -> None:
    frame = Frame(origin)
    ll, _, _ = _geodesic_points(origin, 500, 20_000)
    back = frame.to_geographic(frame.from_geographic(ll))
    _, _, err = GEOD.inv(ll[:, 0], ll[:, 1], back[:, 0], back[:, 1])
    assert np.max(err) < ROUND_TRIP_TOLERANCE_M
    assert np.max(np.abs(back[:, 2] - ll[:, 2])) < ROUND_TRIP_TOLERANCE_M


@pytest.mark.parametrize("origin", ORIGINS)
def test_local_frame_matches_geodesics(origin: tuple[float, float, float]) -> None:
    """Distances from the origin agree with WGS84 geodesics to d³/(6R²), and a geodesic
    leaving at azimuth az ends near d·(sin az, cos az): x east, y north."""
    frame = Frame(origin)
    ll, az, d = _geodesic_points(origin, 2000, 20_000, seed=1)
    xy = frame.from_geographic(ll)[:, :2]
    bound = DISTANCE_SLACK * d**3 / (6 * EARTH_RADIUS_MIN_M**2) + 1e-6
    assert np.all(np.abs(np.hypot(xy[:, 0], xy[:, 1]) - d) <= bound)
    expected = np.column_stack([d * np.sin(np.radians(az)), d * np.cos(np.radians(az))])
    # the geodesic curves in the projection by O(d³/R²): 2 d³/R² bounds what was measured
    assert np.all(np.hypot(*(xy - expected).T) <= 2 * d**3 / EARTH_RADIUS_MIN_M**2 + 1e-6)
    assert np.allclose(frame.from_geographic(np.array([origin]))[0], 0, atol=1e-9)


def _plan(origin: tuple[float, float, float]) -> dict:
    frame = Frame(origin)
    ll = frame.to_geographic
    return {
        "frame": {"origin": list(origin)},
        "candidates": [{"position": ll(np.array([[10.0, 20.0, 5.0]]))[0].tolist()}],
        "walls": [
            {
                "start": ll(np.array([[0.0, 0.0]]))[0].tolist(),
                "end": ll(np.array([[30.0, 0.0]]))[0].tolist(),
                "heights_m": [origin[2] + 4.0],
                "spacing_m": 5,
            }
        ],
        "tx_map": {
            "points": ll(np.array([[1.0, 2.0, 1.5], [-40.0, 3.0, 1.5]])).tolist(),
            "roads": [
                {
                    "points": ll(np.array([[0.0, -10.0], [50.0, -10.0]])).tolist(),
                    "width_m": 6,
                    "step_m": 5,
                    "height_m": origin[2] + 1.5,
                }
            ],
        },
        "heatmap_tx": ll(np.array([[5.0, 5.0, 1.5]]))[0].tolist(),
        "environment": {
            "obstacles": [
                {
                    "kind": "prism",
                    "footprint": ll(
                        np.array([[20.0, 20.0], [30, 20], [30, 30], [20, 30]])
                    ).tolist(),
                    "base_m": origin[2],
                    "height_m": 10,
                },
                {
                    "kind": "wall",
                    "start": ll(np.array([[-5.0, 0.0]]))[0].tolist(),
                    "end": ll(np.array([[-5.0, 9.0]]))[0].tolist(),
                    "height_m": 3,
                    "base_m": origin[2] + 0.5,
                },
            ]
        },
    }


@pytest.mark.parametrize("origin", [(24.949, 60.1655, 0.0), (-70.6, -33.4, 500.0)])
def test_to_local_converts_every_coordinate(origin: tuple[float, float, float]) -> None:
    doc = _plan(origin)
    before = copy.deepcopy(doc)
    local, frame = to_local(doc)
    assert doc == before  # the input is not modified
    assert frame is not None and frame.origin == origin and "frame" not in local
    tol = 1e-6
    assert np.allclose(local["candidates"][0]["position"], [10, 20, 5], atol=tol)
    w = local["walls"][0]
    assert np.allclose([*w["start"], *w["end"], *w["heights_m"]], [0, 0, 30, 0, 4], atol=tol)
    assert np.allclose(local["tx_map"]["points"], [[1, 2, 1.5], [-40, 3, 1.5]], atol=tol)
    road = local["tx_map"]["roads"][0]
    assert np.allclose(road["points"], [[0, -10], [50, -10]], atol=tol)
    assert road["height_m"] == pytest.approx(1.5)
    assert np.allclose(local["heatmap_tx"], [5, 5, 1.5], atol=tol)
    prism, wall = local["environment"]["obstacles"]
    assert np.allclose(prism["footprint"], [[20, 20], [30, 20], [30, 30], [20, 30]], atol=tol)
    assert prism["base_m"] == pytest.approx(0.0) and prism["height_m"] == 10
    assert np.allclose([*wall["start"], *wall["end"]], [-5, 0, -5, 9], atol=tol)
    assert wall["base_m"] == pytest.approx(0.5)


def test_local_documents_pass_unchanged() -> None:
    doc = {"candidates": [{"position": [1.0, 2.0, 3.0]}], "tx_map": {"grid": {"x": [0, 1, 1]}}}
    out, frame = to_local(doc)
    assert frame is None and out is doc


def test_scenario_points_and_batches() -> None:
    origin = (24.949, 60.1655, 0.0)
    ll = Frame(origin).to_geographic
    doc = {
        "frame": {"origin": [24.949, 60.1655]},
        "ris": [{"position": ll(np.array([[4.0, 0.0, 2.0]]))[0].tolist()}],
        "tx": ll(np.array([[1.0, 1.0, 0.0]]))[0].tolist(),
        "rx": ll(np.array([[2.0, 2.0, 0.0], [3.0, -1.0, 0.0]])).tolist(),
    }
    local, _ = to_local(doc)
    assert np.allclose(local["ris"][0]["position"], [4, 0, 2], atol=1e-6)
    assert np.allclose(local["tx"], [1, 1, 0], atol=1e-6)
    assert np.allclose(local["rx"], [[2, 2, 0], [3, -1, 0]], atol=1e-6)


def test_rectangle_walls_become_outward_segments() -> None:
    from ris_planner.model.plan import PlanDocument
    from ris_planner.planning.inputs.sites import expand_sites

    origin = (24.949, 60.1655, 0.0)
    frame = Frame(origin)
    lo, hi = frame.to_geographic(np.array([[-10.0, -5.0], [10.0, 5.0]]))
    base = {
        "tx_map": {"points": [[0, 0, 1.5]]},
        "rx_map": {"points": [[1, 0, 1.5]]},
        "objective": {"kind": "coverage", "threshold_m": 1},
        "ris_count": [1],
    }
    wall = {"heights_m": [3], "spacing_m": 5}
    geo = {**base, "frame": {"origin": list(origin)}}
    geo["walls"] = [{**wall, "rectangle": [lo[0], lo[1], hi[0], hi[1]]}]
    geo["tx_map"] = {"points": frame.to_geographic(np.array([[0.0, 0, 1.5]])).tolist()}
    geo["rx_map"] = {"points": frame.to_geographic(np.array([[1.0, 0, 1.5]])).tolist()}
    local, _ = to_local(geo)
    assert len(local["walls"]) == 4
    sites_geo = expand_sites(PlanDocument.model_validate(local))
    ref = {**base, "walls": [{**wall, "rectangle": [-10, -5, 10, 5]}]}
    sites_ref = expand_sites(PlanDocument.model_validate(ref))
    assert len(sites_geo) == len(sites_ref)
    for a, b in zip(sites_geo, sites_ref, strict=True):
        # the rectangle's sides in lon/lat are parallels and meridians: 1e-5 rad of convergence
        assert np.allclose(a.ris.position, b.ris.position, atol=1e-3)
        turn = np.angle(np.exp(1j * (np.array(a.ris.orientation) - b.ris.orientation)))
        assert np.allclose(turn, 0, atol=1e-4)  # yaw ±π alike


def test_projected_crs_frame_matches_lonlat_frame() -> None:
    utm = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32635", always_xy=True)
    origin = (24.949, 60.1655, 0.0)
    doc = _plan(origin)
    ll = np.array(doc["tx_map"]["points"])
    e, n = utm.transform(ll[:, 0], ll[:, 1])
    e0, n0 = utm.transform(origin[0], origin[1])
    crs_doc = {
        "frame": {"crs": "EPSG:32635", "origin": [e0, n0, 0.0]},
        "tx_map": {"points": np.column_stack([e, n, ll[:, 2]]).tolist()},
    }
    local, frame = to_local(crs_doc)
    assert frame is not None
    assert np.allclose(frame.origin[:2], origin[:2], atol=1e-9)
    assert np.allclose(local["tx_map"]["points"], [[1, 2, 1.5], [-40, 3, 1.5]], atol=1e-6)
    # no origin: the bounding-box centre (rounded to the metre)
    auto, frame2 = to_local({**crs_doc, "frame": {"crs": "EPSG:32635"}})
    assert frame2 is not None
    span = np.ptp(np.array(auto["tx_map"]["points"])[:, 0])
    assert span == pytest.approx(41.0, abs=1e-3)
    assert abs(np.mean(np.array(auto["tx_map"]["points"])[:, 0])) < 1.0


@pytest.mark.parametrize(
    ("frame", "match"),
    [
        ({"origin": [60.17, 24.95, 0]}, r"^frame\.origin: .*lies among them: lat/lon swapped\?"),
        ({"origin": [200, 10]}, "not a WGS84 position"),
        ({"crs": "EPSG:4326"}, "not a projected CRS"),
        ({"crs": "EPSG:999999"}, "unknown CRS"),
        ({"center": [1, 2]}, "frame: expected"),
    ],
)
def test_bad_frames(frame: dict, match: str) -> None:
    doc = {"frame": frame, "tx_map": {"points": [[24.949, 60.1655, 1.5]]}}
    with pytest.raises(RisPlannerError, match=match):
        to_local(doc)


def test_swapped_feature_coordinates_name_the_field() -> None:
    doc = _plan((24.949, 60.1655, 0.0))
    fp = doc["environment"]["obstacles"][0]["footprint"]
    fp[2] = [fp[2][1], fp[2][0]]  # one vertex given as [lat, lon]
    with pytest.raises(
        RisPlannerError, match=r"environment\.obstacles\.0\.footprint\.2: .*swapped"
    ):
        to_local(doc)
    doc = _plan((24.949, 60.1655, 0.0))
    doc["candidates"][0]["position"][0] += 1.0  # 55 km east at 60° N
    with pytest.raises(RisPlannerError, match=r"candidates\.0\.position: .* 5[56] km"):
        to_local(doc)
    assert MAX_FRAME_RADIUS_M == 50_000


@pytest.mark.parametrize("bad", ["grid", "csv_text"])
def test_grids_are_rejected_in_geographic_frames(bad: str) -> None:
    doc = {"frame": {"origin": [24.9, 60.1]}, "rx_map": {bad: {"x": [0, 1, 1]}}}
    with pytest.raises(RisPlannerError, match=f"rx_map.{bad}: not supported"):
        to_local(doc)


def test_malformed_point_names_the_field() -> None:
    doc = {"frame": {"origin": [24.9, 60.1]}, "tx_map": {"points": [[24.9, 60.1]]}}
    with pytest.raises(RisPlannerError, match=r"tx_map\.points\.0: expected 3 numbers"):
        to_local(doc)


def test_bounds_cli_takes_a_geographic_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ris_planner.cli import main
    from ris_planner.model.scenario import preset_document

    local = preset_document("paper-table1")
    frame = Frame((24.949, 60.1655, 0.0))
    geo = copy.deepcopy(local)
    geo["frame"] = {"origin": list(frame.origin)}
    for ris in geo["ris"]:
        ris["position"] = frame.to_geographic(np.array([ris["position"]]))[0].tolist()
    for key in ("tx", "rx"):
        geo[key] = frame.to_geographic(np.array([local[key]]))[0].tolist()
    answers = []
    for doc in (local, geo):
        path = tmp_path / "scenario.json"
        path.write_text(json.dumps(doc))
        assert main(["bounds", str(path)]) == 0
        answers.append(json.loads(capsys.readouterr().out))
    # positions survive the round trip to ~1e-9 m: bounds agree to far better than 1e-6
    assert answers[1]["peb_rx_m"] == pytest.approx(answers[0]["peb_rx_m"], rel=1e-6)
    assert answers[1]["peb_tx_m"] == pytest.approx(answers[0]["peb_tx_m"], rel=1e-6)


def test_power_cli_takes_a_geographic_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ris_planner.cli import main
    from ris_planner.model.scenario import preset_document

    local = preset_document("paper-table1")
    local["codebook"] = {"kind": "directional_derivative", "prior": {"sigma_m": 0.1, "samples": 4}}
    frame = Frame((24.949, 60.1655, 0.0))
    geo = copy.deepcopy(local) | {"frame": {"origin": list(frame.origin)}}
    for ris in geo["ris"]:
        ris["position"] = frame.to_geographic(np.array([ris["position"]]))[0].tolist()
    for key in ("tx", "rx"):
        geo[key] = frame.to_geographic(np.array([local[key]], dtype=float))[0].tolist()
    answers = []
    for doc in (local, geo):
        path = tmp_path / "scenario.json"
        path.write_text(json.dumps(doc))
        assert main(["power", str(path), "--objective", "sum"]) == 0
        answers.append(json.loads(capsys.readouterr().out))
    assert answers[1]["sdp"]["objective"] == pytest.approx(answers[0]["sdp"]["objective"], rel=1e-6)


def test_missing_extra_message() -> None:
    from ris_planner.io import MissingExtraError, require

    with pytest.raises(MissingExtraError, match=r"pip install 'ris_planner\[gis\]'"):
        require("ris_planner_no_such_gis_library")
    assert issubclass(MissingExtraError, RisPlannerError)  # CLI: exit 2, REST: 4xx


GREAT_CIRCLE_RTOL = 6e-3
"""The pre-check's sphere (mean radius) is within 0.6 % of WGS84 geodesics at any latitude
(the ellipsoid's radii of curvature span 6335–6400 km)."""


@pytest.mark.parametrize("origin", [(24.949, 60.1655, 0.0), (-70.6, -33.45, 0.0), (0.0, 0.0, 0.0)])
def test_far_point_precheck_against_geodesics(origin: tuple[float, float, float]) -> None:
    """The great-circle distance that refuses far points before projecting (the tmerc frame is
    undefined 90° from its meridian) against pyproj's geodesics; a point on the far side of the
    Earth is refused naming its field, not a projection error."""
    from ris_planner.io.frames import great_circle_m

    rng = np.random.default_rng(7)
    ll = np.column_stack([rng.uniform(-180, 180, 200), rng.uniform(-80, 80, 200)])
    _, _, want = GEOD.inv(np.full(200, origin[0]), np.full(200, origin[1]), ll[:, 0], ll[:, 1])
    got = great_circle_m(ll, origin)
    assert np.allclose(got, want, rtol=GREAT_CIRCLE_RTOL, atol=1.0)
    antipode = [origin[0] - 180 if origin[0] > 0 else origin[0] + 180, -origin[1], 0.0]
    doc = {"frame": {"origin": list(origin)}, "tx": list(origin), "rx": antipode}
    with pytest.raises(RisPlannerError, match=r"^rx: .* lies 200\d\d km from the frame origin"):
        to_local(doc)


def test_a_swapped_origin_is_blamed_on_the_origin_not_a_point() -> None:
    """Every point far from the origin while the origin read as [lat, lon] lies among them:
    the origin is at fault (checked before any single point is blamed)."""
    doc = {
        "frame": {"origin": [60.1655, 24.949, 0.0]},
        "candidates": [{"position": [24.9491, 60.1656, 5.0], "orientation": [0, 0, 0]}],
        "tx_map": {"points": [[24.949, 60.1655, 1.5], [24.9495, 60.1652, 1.5]]},
    }
    with pytest.raises(DocumentFieldError, match=r"^frame\.origin: .*swapped\?") as info:
        to_local(doc)
    assert info.value.field == "frame.origin"
    # an origin far from everything, not swapped: still the origin's fault
    with pytest.raises(DocumentFieldError, match=r"^frame\.origin: .*the wrong origin") as info:
        to_local(doc | {"frame": {"origin": [10.0, 50.0]}})
    # one point swapped among good ones: that point, with "swapped?"
    bad = doc | {"frame": {"origin": [24.949, 60.1655]}}
    bad["tx_map"] = {"points": [[24.949, 60.1655, 1.5], [60.1652, 24.9495, 1.5]]}
    with pytest.raises(DocumentFieldError, match=r"^tx_map\.points\.1: .*swapped\?"):
        to_local(bad)
    # a projected frame whose origin has easting and northing swapped
    utm = {"frame": {"crs": "EPSG:3067", "origin": [6672000, 385000]}}
    utm |= {"tx": [385100, 6672100, 0], "rx": [385200, 6672000, 0]}
    with pytest.raises(DocumentFieldError, match=r"^frame\.origin: .*easting/northing swapped"):
        to_local(utm)
    # licence fields are taken off (the exports carry them), with or without a frame
    local, frame = to_local({"license": "ODbL", "tx": [0.0, 0.0, 0.0]})
    assert local == {"tx": [0.0, 0.0, 0.0]} and frame is None
