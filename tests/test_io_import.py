"""Import: GeoJSON / OSM buildings, roads and density areas, mounting sites, DXF floor plans."""

from __future__ import annotations

import json
import math
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyproj")
pytest.importorskip("shapely")

from ris_planner.cli import main
from ris_planner.core.errors import DocumentFieldError, RisPlannerError
from ris_planner.environment import Scene
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment
from ris_planner.io.frames import Frame, to_local
from ris_planner.io.geojson_read import HIGHWAY_WIDTH_M, NO_BUILDINGS_WARNING, import_features
from ris_planner.io.import_options import (
    DEFAULT_BUILDING_HEIGHT_M,
    METRES_PER_LEVEL,
    OSM_LICENSE,
    FeatureError,
    ImportOptions,
    parse_length,
)
from ris_planner.io.osm_xml import osm_xml_features
from ris_planner.io.site_points import import_sites, yaw_from_azimuth

ORIGIN = (24.949, 60.1655, 0.0)
FRAME = Frame(ORIGIN)
HELSINKI = Path(__file__).parent.parent / "examples" / "helsinki"

COORD_TOLERANCE_M = 1e-6
"""Footprints survive metres → lon/lat → metres to nanometres (tests/test_io_frames.py)."""


def _ring(xy: list[list[float]]) -> list[list[float]]:
    ll = FRAME.to_geographic(np.asarray(xy, dtype=float)).tolist()
    return [*ll, ll[0]]


def _feature(geom: dict, fid: str | None = None, **props: object) -> dict:
    f: dict = {"type": "Feature", "properties": props, "geometry": geom}
    if fid is not None:
        f["id"] = fid
    return f


def _poly(*rings: list[list[float]]) -> dict:
    return {"type": "Polygon", "coordinates": [_ring(r) for r in rings]}


def _fc(*features: dict) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


SQUARE = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]]
L_SHAPE = [[30.0, 0.0], [50.0, 0.0], [50.0, 8.0], [38.0, 8.0], [38.0, 25.0], [30.0, 25.0]]


def _at(feature: dict) -> str:
    """How messages write a feature's first position."""
    coords = feature["geometry"]["coordinates"]
    while isinstance(coords[0], list):
        coords = coords[0]
    return f"[{coords[0]:.6f}, {coords[1]:.6f}]"


def _import(*features: dict, **opts: object) -> tuple[dict, object]:
    fragment, summary = import_features(_fc(*features), ORIGIN, ImportOptions(**opts))  # type: ignore[arg-type]
    return fragment, summary


def test_building_heights_levels_defaults_and_holes() -> None:
    features = [
        _feature(_poly(SQUARE), "way/1", building="yes", height="21.5 m"),
        _feature(_poly(L_SHAPE), "way/2", building="yes", **{"building:levels": "5"}),
        _feature(_poly([[0, 30], [10, 30], [10, 40]]), "way/3", building="yes", name="Shed"),
        _feature(
            _poly(SQUARE, [[5, 5], [5, 10], [10, 10]]),
            "way/4",
            building="y",
            min_height=3,
            height=12,
        ),
        _feature(_poly([[60, 0], [70, 0], [70, 10]]), "way/5", building="no"),
    ]
    fragment, summary = _import(*features)
    obs = fragment["environment"]["obstacles"]
    # the courtyard building is cut into simple pieces (tests below: the hole stays open)
    assert [o["name"] for o in obs] == ["way/1", "way/2", "Shed", "way/4#0", "way/4#1"]
    assert obs[0]["height_m"] == 21.5 and obs[0]["base_m"] == 0
    assert obs[1]["height_m"] == 5 * METRES_PER_LEVEL
    assert obs[2]["height_m"] == DEFAULT_BUILDING_HEIGHT_M
    assert all(o["base_m"] == 3 and o["height_m"] == 9 for o in obs[3:])
    assert summary.default_height == ["feature 2 (id way/3, name 'Shed') at " + _at(features[2])]
    assert summary.heights_from_levels == 1 and summary.courtyards == 1
    assert summary.tag_problems == [] and summary.repaired == []
    assert summary.skipped == 1  # building=no
    local, _ = to_local(fragment)
    env = Environment.model_validate(local["environment"])
    assert np.allclose(env.obstacles[1].vertices, L_SHAPE, atol=COORD_TOLERANCE_M)
    # other metres per level and default height
    fragment, _ = _import(*features[1:3], metres_per_level=3.5, default_height_m=7)
    assert [o["height_m"] for o in fragment["environment"]["obstacles"]] == [17.5, 7]


def test_multipolygon_gives_one_prism_per_part() -> None:
    geom = {"type": "MultiPolygon", "coordinates": [[_ring(SQUARE)], [_ring(L_SHAPE)]]}
    fragment, summary = _import(_feature(geom, name="Twin", building="yes", height=9))
    assert [o["name"] for o in fragment["environment"]["obstacles"]] == ["Twin#0", "Twin#1"]
    assert summary.buildings == 1 and summary.prisms == 2


def test_plain_building_layer_without_building_tags() -> None:
    fragment, _ = _import(_feature(_poly(SQUARE), height=6), _feature(_poly(L_SHAPE)))
    assert len(fragment["environment"]["obstacles"]) == 2


def test_imported_building_blocks_the_same_legs_as_the_metre_prism() -> None:
    fragment, _ = _import(_feature(_poly(L_SHAPE), building="yes", height=12, min_height=2))
    local, _ = to_local(fragment)
    imported = Scene.from_environment(Environment.model_validate(local["environment"]))
    typed = Scene.from_environment(
        Environment(obstacles=[Prism(footprint=L_SHAPE, base_m=2, height_m=10)])
    )
    rng = np.random.default_rng(3)
    a = rng.uniform([10, -20, 0], [70, 45, 16], size=(4000, 3))
    b = rng.uniform([10, -20, 0], [70, 45, 16], size=(4000, 3))
    blocked = typed.blocked(a, b)
    assert 0.1 < blocked.mean() < 0.9  # the legs exercise both outcomes
    assert np.array_equal(imported.blocked(a, b), blocked)


@pytest.mark.parametrize(
    ("geometry", "match"),
    [
        (
            _poly([[0, 0], [10, 10], [10, 0], [0, 10]]),
            "feature 0 \\(id way/9\\) at \\[24.949000, 60.165500\\].*Self-intersection at"
            " \\[24.94909\\d, 60.16554\\d\\]",
        ),
        ({"type": "Polygon", "coordinates": []}, "feature 0 \\(id way/9.*empty"),
        (
            {"type": "Polygon", "coordinates": [_ring(SQUARE)[:-1]]},
            "feature 0 \\(id way/9.*ring not closed",
        ),
        (
            {"type": "Polygon", "coordinates": [[list(ORIGIN[:2])] * 4]},
            "feature 0 \\(id way/9.*at least 3 distinct",
        ),
        (
            {"type": "Polygon", "coordinates": [[[200, 0], [201, 0], [201, 1], [200, 0]]]},
            "feature 0 \\(id way/9.*not a WGS84",
        ),
        (
            {
                "type": "Polygon",
                "coordinates": [[[24.9, 95], [24.91, 95], [24.9, 95.1], [24.9, 95]]],
            },
            "feature 0 \\(id way/9\\) at \\[24.900000, 95.000000\\].*not a WGS84.*swapped\\?",
        ),
        ({"type": "LineString", "coordinates": [[24.9, 60.1]]}, "at least 2 distinct"),
    ],
)
def test_invalid_geometries_name_the_feature(geometry: dict, match: str) -> None:
    with pytest.raises(RisPlannerError, match=match) as info:
        _import(_feature(geometry, "way/9", building="yes", highway="residential"), invalid="error")
    # the feature's path for the service's 422, and an error that survives a process boundary
    assert isinstance(info.value, FeatureError) and info.value.field == "features.0"
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is FeatureError and str(back) == str(info.value)
    assert (back.field, back.reason) == (info.value.field, info.value.reason)
    plain = DocumentFieldError("codebook.kind", "unknown")
    assert str(pickle.loads(pickle.dumps(plain))) == "codebook.kind: unknown"


def test_building_top_below_base_is_an_error() -> None:
    with pytest.raises(RisPlannerError, match=r"feature 0.*top 5 m must lie above its base 8 m"):
        _import(_feature(_poly(SQUARE), building="yes", height=5, min_height=8))


def test_roads_widths_by_property_and_class() -> None:
    def line(xy: list[list[float]]) -> dict:
        return {"type": "LineString", "coordinates": FRAME.to_geographic(np.array(xy)).tolist()}

    fragment, summary = _import(
        _feature(line([[0, -10], [50, -10]]), highway="residential"),
        _feature(line([[0, -20], [50, -20]]), highway="primary", width="12.5"),
        _feature(line([[0, -30], [50, -30]]), highway="bus_guideway"),
        _feature(line([[0, -40], [50, -40]]), width=4),
        road_step_m=2.5,
        ue_height_m=1.2,
    )
    roads = fragment["ue_map"]["roads"]
    assert [r["width_m"] for r in roads] == [HIGHWAY_WIDTH_M["residential"], 12.5, 4.0]
    assert all(r["step_m"] == 2.5 and r["height_m"] == 1.2 for r in roads)
    assert summary.roads_skipped == {"bus_guideway": 1}
    local, _ = to_local({**fragment, "tx_map": fragment["ue_map"]})
    assert np.allclose(local["tx_map"]["roads"][0]["points"], [[0, -10], [50, -10]], atol=1e-6)
    only, s2 = _import(
        _feature(line([[0, -10], [50, -10]]), highway="residential"),
        _feature(line([[0, -20], [50, -20]]), highway="footway"),
        highways=("footway",),
    )
    assert len(only["ue_map"]["roads"]) == 1 and s2.roads_skipped == {"residential (not chosen)": 1}


def test_density_areas_become_weighted_grid_points() -> None:
    area = [[0.0, 0.0], [50.0, 0.0], [50.0, 30.0], [0.0, 30.0]]
    tiny = [[100.0, 0.0], [101.0, 0.0], [101.0, 1.0], [100.0, 1.0]]
    fragment, summary = _import(
        _feature(_poly(area), name="square", density=0.2),
        _feature(_poly(tiny), name="kiosk", density=2.0),
        area_step_m=5.0,
    )
    ue = fragment["ue_map"]
    assert len(ue["points"]) == 10 * 6 + 1 and summary.area_points == 61
    w = np.array(ue["weights"])
    assert w[:60].sum() == pytest.approx(0.2 * 50 * 30)  # density × area, cell by cell
    assert w[60] == pytest.approx(2.0 * 1.0, rel=1e-6)  # a sub-cell area: one point
    local, _ = to_local({**fragment, "rx_map": ue})
    xyz = np.array(local["rx_map"]["points"])
    assert np.allclose(xyz[:, 2], 1.5)
    assert np.allclose(np.sort(np.unique(np.round(xyz[:60, 0], 3))), 2.5 + 5 * np.arange(10))
    assert fragment.get("environment") is None  # an area is not a building


def test_parse_length() -> None:
    assert parse_length("12") == 12 and parse_length("12,5 m") == 12.5
    assert parse_length("40 ft") == pytest.approx(12.192) and parse_length("10'") == pytest.approx(
        3.048
    )
    assert (
        parse_length("tall") is None and parse_length(True) is None and parse_length(None) is None
    )


def test_mounting_points_and_lines_become_candidates() -> None:
    pt = FRAME.to_geographic(np.array([[5.0, -0.1]]))[0].tolist()
    line = FRAME.to_geographic(np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 10.0]])).tolist()
    fc = _fc(
        _feature(
            {"type": "Point", "coordinates": pt},
            name="pole",
            height=6,
            azimuth_deg=180,
            tilt_deg=15,
        ),
        _feature({"type": "Point", "coordinates": [*pt, 4.0]}, orientation=90),
        _feature(
            {"type": "LineString", "coordinates": line},
            heights_m=[3, 5],
            spacing_m=4,
            side="right",
            tilts_deg=[0, 20],
        ),
    )
    fragment, summary = import_sites(fc, ORIGIN)
    local, _ = to_local(fragment)
    c0, c1 = local["candidates"]
    assert np.allclose(c0["position"], [5, -0.1, 6], atol=1e-6)
    assert np.allclose(c0["orientation"], [-math.pi / 2, math.radians(15), 0])  # faces south
    assert np.allclose(c1["position"][2], 4) and np.allclose(c1["orientation"][0], 0)  # east
    walls = local["walls"]
    assert len(walls) == 2 and summary.walls == 2 and summary.candidates == 2
    assert np.allclose([*walls[0]["start"], *walls[0]["end"]], [0, 0, 20, 0], atol=1e-6)
    assert walls[1]["heights_m"] == [3, 5] and walls[1]["side"] == "right"
    assert np.allclose(walls[1]["tilts_rad"], [0, math.radians(20)])
    with pytest.raises(RisPlannerError, match=r"feature 0.*azimuth_deg"):
        import_sites(_fc(_feature({"type": "Point", "coordinates": pt}, height=3)), ORIGIN)


def test_yaw_from_azimuth() -> None:
    for az, yaw in [(0, math.pi / 2), (90, 0), (180, -math.pi / 2), (270, math.pi)]:
        assert math.isclose(math.cos(yaw_from_azimuth(az) - yaw), 1.0)


OSM_XML = """<?xml version='1.0' encoding='UTF-8'?>
<osm version="0.6">
 {nodes}
 <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
  <tag k="building" v="yes"/><tag k="building:levels" v="4"/><tag k="name" v="Talo"/></way>
 <way id="11"><nd ref="5"/><nd ref="6"/><tag k="highway" v="tertiary"/></way>
 <way id="12"><nd ref="5"/><nd ref="99"/><tag k="highway" v="tertiary"/></way>
 <way id="13"><nd ref="7"/><nd ref="8"/><nd ref="9"/><nd ref="7"/></way>
 <relation id="20"><member type="way" ref="13" role="outer"/>
  <tag k="type" v="multipolygon"/><tag k="building" v="yes"/><tag k="height" v="8"/></relation>
</osm>
"""


def test_osm_xml(tmp_path: Path) -> None:
    xy = [[0, 0], [20, 0], [20, 20], [0, 20], [0, -10], [50, -10], [30, 30], [40, 30], [35, 40]]
    ll = FRAME.to_geographic(np.array(xy, dtype=float))
    nodes = "\n ".join(
        f'<node id="{i + 1}" lat="{lat!r}" lon="{lon!r}"/>'
        for i, (lon, lat) in enumerate(ll.tolist())
    )
    path = tmp_path / "site.osm"
    path.write_text(OSM_XML.format(nodes=nodes))
    fc, summary = osm_xml_features(path)
    assert [f["id"] for f in fc["features"]] == ["way/10", "way/11", "relation/20"]
    assert any("outside the file" in n for n in summary.notes)
    fragment, _ = import_features(fc, ORIGIN)
    obs = fragment["environment"]["obstacles"]
    assert [(o["name"], o["height_m"]) for o in obs] == [("Talo", 12.0), ("relation/20", 8.0)]
    assert fragment["ue_map"]["roads"][0]["width_m"] == HIGHWAY_WIDTH_M["tertiary"]
    # and through the CLI
    out = tmp_path / "frag.json"
    assert main(["import", "osm", str(path), "--origin", "24.949,60.1655", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == fragment


def test_cli_import_geojson_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "b.geojson"
    src.write_text(json.dumps(_fc(_feature(_poly(SQUARE), "way/1", building="yes"))))
    assert main(["import", "geojson", str(src), "--default-height", "7"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["environment"]["obstacles"][0]["height_m"] == 7
    assert "import summary" in captured.err and "way/1" in captured.err
    bad = tmp_path / "bad.geojson"
    bad.write_text(json.dumps(_fc(_feature(_poly([[0, 0], [10, 10], [10, 0], [0, 10]]), "w/7"))))
    assert main(["import", "geojson", str(bad), "--invalid", "error"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: feature 0 (id w/7) at [") and err.count("\n") == 1
    assert "invalid outline (Self-intersection at [" in err


def test_import_help_gives_each_option_its_unit_and_default() -> None:
    """``ris-planner import --help``: every option with a value says what it is, a length its
    unit, and the default it falls back to (the ImportOptions defaults, one source)."""
    import argparse

    from ris_planner.cli.app import build_parser

    parser = build_parser("import")
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command = sub.choices["import"]
    checked = []
    for action in command._actions:
        if not action.option_strings or action.nargs == 0 or action.dest == "help":
            continue
        help_text = command._get_formatter()._expand_help(action) if action.help else ""
        assert help_text, f"{action.option_strings[0]} has no help"
        if action.default is not None:
            assert f"({action.default}" in help_text, (action.option_strings[0], help_text)
            checked.append(action.dest)
        if action.type is float:
            assert "[m]" in help_text, (action.option_strings[0], help_text)
    options = ImportOptions()
    defaults = {
        "metres_per_level": options.metres_per_level,
        "default_height": options.default_height_m,
        "road_step": options.road_step_m,
        "ue_height": options.ue_height_m,
        "density_key": options.density_key,
        "area_step": options.area_step_m,
        "site_spacing": options.site_spacing_m,
        "invalid": options.invalid,
    }
    assert sorted(checked) == sorted(defaults)
    for dest, value in defaults.items():
        assert command.get_default(dest) == value, dest


def test_helsinki_data_imports() -> None:
    path = HELSINKI / "helsinki.geojson"
    assert path.stat().st_size < 200_000
    fc = json.loads(path.read_text())
    assert fc["license"] == "© OpenStreetMap contributors, ODbL 1.0"
    fragment, summary = import_features(fc)
    assert summary.prisms == 29 and summary.heights_from_levels == 13
    assert len(summary.default_height) == 16
    local, frame = to_local(fragment)
    assert frame is not None
    env = Environment.model_validate(local["environment"])
    span = np.ptp(np.vstack([o.vertices for o in env.obstacles if isinstance(o, Prism)]), axis=0)
    assert np.all((span > 150) & (span < 300))  # a few blocks, ~220 m across


# --- DXF ------------------------------------------------------------------------------------


def _floor_plan(path: Path, insunits: int) -> None:
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = insunits
    for name in ("WALLS", "COLUMNS", "FURNITURE"):
        doc.layers.add(name)
    msp = doc.modelspace()
    msp.add_line((0, 0), (10_000, 0), dxfattribs={"layer": "WALLS"})
    msp.add_lwpolyline(
        [(0, 5000), (4000, 5000), (4000, 8000)], dxfattribs={"layer": "WALLS"}
    )  # open: two walls
    msp.add_lwpolyline(
        [(6000, 2000), (6500, 2000), (6500, 2500), (6000, 2500)],
        close=True,
        dxfattribs={"layer": "COLUMNS"},
    )
    msp.add_line((0, 0), (0, 10_000), dxfattribs={"layer": "FURNITURE"})
    msp.add_circle((1000, 1000), 300, dxfattribs={"layer": "WALLS"})
    doc.saveas(path)


def test_dxf_floor_plan_imports_into_the_expected_walls(tmp_path: Path) -> None:
    from ris_planner.io.dxf import LayerSpec, import_dxf

    path = tmp_path / "floor.dxf"
    _floor_plan(path, insunits=4)  # millimetres
    layers = {"WALLS": LayerSpec("wall", 2.7), "COLUMNS": LayerSpec("prism", 3.0, 0.1)}
    fragment, summary = import_dxf(path, layers)
    env = Environment.model_validate(fragment["environment"])
    walls = [(o.start, o.end, o.height_m) for o in env.obstacles if o.kind == "wall"]
    assert walls == [
        ([0.0, 0.0], [10.0, 0.0], 2.7),
        ([0.0, 5.0], [4.0, 5.0], 2.7),
        ([4.0, 5.0], [4.0, 8.0], 2.7),
    ]
    (prism,) = [o for o in env.obstacles if isinstance(o, Prism)]
    assert np.allclose(prism.vertices, [[6, 2], [6.5, 2], [6.5, 2.5], [6, 2.5]])
    assert prism.base_m == 0.1 and prism.height_m == 3.0
    assert summary["units_to_m"] == 0.001
    assert summary["ignored"] == {"FURNITURE:LINE": 1, "WALLS:CIRCLE": 1}
    # $INSUNITS overridden; a wall across the room blocks a leg through it
    frag_cm, _ = import_dxf(path, {"WALLS": LayerSpec("wall", 2.7)}, units="cm")
    assert frag_cm["environment"]["obstacles"][0]["end"] == [100.0, 0.0]
    scene = Scene.from_environment(env)
    assert scene.blocked(np.array([[5.0, -1, 1.5]]), np.array([[5.0, 1, 1.5]]))[0]
    assert not scene.blocked(np.array([[5.0, -1, 2.8]]), np.array([[5.0, 1, 2.8]]))[0]


def test_dxf_errors_and_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "floor.dxf"
    _floor_plan(path, insunits=6)
    out = tmp_path / "env.json"
    args = ["import", "dxf", str(path), "--layer", "WALLS=wall:2.5", "--out", str(out)]
    assert main(args) == 0
    assert len(json.loads(out.read_text())["environment"]["obstacles"]) == 3
    assert main(["import", "dxf", str(path), "--layer", "DOORS=wall:2"]) == 2
    assert "layer(s) 'DOORS' not in the drawing" in capsys.readouterr().err
    assert main(["import", "dxf", str(path), "--layer", "WALLS=window:2"]) == 2
    assert "expected LAYER=wall:HEIGHT_M" in capsys.readouterr().err
    assert main(["import", "dxf", str(path), "--layer", "WALLS=prism:2"]) == 2
    err = capsys.readouterr().err
    assert "LWPOLYLINE" in err and "closed polylines" in err


# --- real data: invalid outlines, courtyards, tags, swaps, licence ---------------------------

BOWTIE = [[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]
COURTYARD = [[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]]
HOLE = [[12.0, 12.0], [28.0, 12.0], [28.0, 28.0], [12.0, 28.0]]
AREA_TOLERANCE_M2 = 1e-3
"""Footprints computed in metres and written as lon/lat with 1e-9° digits (≤ 0.1 mm): areas
of tens of metres across agree to well below 1e-3 m²."""


def _local_prisms(fragment: dict) -> list[Prism]:
    local, _ = to_local(fragment)
    env = Environment.model_validate(local["environment"])  # every footprint a simple polygon
    return [o for o in env.obstacles if isinstance(o, Prism)]


def _union(prisms: list[Prism]) -> object:
    import shapely

    return shapely.union_all([shapely.Polygon(p.vertices) for p in prisms])


@pytest.mark.parametrize("policy", ["repair", "skip", "error"])
def test_invalid_outline_policies(policy: str) -> None:
    bow = _feature(_poly(BOWTIE), "way/7", building="yes", name="Bockin talo")
    ok = _feature(_poly(SQUARE), "way/8", building="yes")
    if policy == "error":
        with pytest.raises(FeatureError, match=r"feature 0 \(id way/7, name 'Bockin talo'\) at"):
            _import(bow, ok, invalid=policy)
        return
    fragment, summary = _import(bow, ok, invalid=policy)
    prisms = _local_prisms(fragment)
    entries = summary.repaired if policy == "repair" else summary.skipped_invalid
    (entry,) = entries
    assert (entry["feature"], entry["id"], entry["name"]) == (0, "way/7", "Bockin talo")
    assert entry["lonlat"] == pytest.approx(list(ORIGIN[:2]), abs=1e-7)
    assert "Self-intersection at [24.9490" in entry["reason"]
    if policy == "skip":
        assert [p.name for p in prisms] == ["way/8"] and summary.repaired == []
        return
    # two triangles, 25 m² each: the enclosed area kept, no warning
    assert [p.name for p in prisms] == ["Bockin talo#0", "Bockin talo#1", "way/8"]
    assert entry["parts"] == 2 and "warning" not in entry
    assert entry["area_before_m2"] == pytest.approx(50) and entry["area_after_m2"] == 50
    assert _union(prisms[:2]).area == pytest.approx(50, abs=AREA_TOLERANCE_M2)


def test_a_repair_that_changes_the_area_is_flagged() -> None:
    # the outline loops back over itself: its lines enclose 225 m², of which 50 m² twice
    # over; the valid (even-odd) repair keeps 175 m²
    fold = [[0, 0], [20, 0], [20, 10], [5, 10], [5, -5], [15, -5], [15, 5], [0, 5]]
    _, summary = _import(_feature(_poly(fold), "way/3", building="yes"))
    (entry,) = summary.repaired
    assert (entry["area_before_m2"], entry["area_after_m2"]) == (225, 175)
    assert "warning" in entry and "changed the enclosed area" in entry["warning"]


def test_unclosed_and_degenerate_rings_follow_the_policy() -> None:
    open_ring = {"type": "Polygon", "coordinates": [_ring(SQUARE)[:-1]]}
    flat = {"type": "Polygon", "coordinates": [[list(ORIGIN[:2])] * 4]}
    fragment, summary = _import(
        _feature(open_ring, "way/1", building="yes"), _feature(flat, "way/2", building="yes")
    )
    assert [e["id"] for e in summary.repaired] == ["way/1"]
    assert "ring not closed" in summary.repaired[0]["reason"]
    assert [e["id"] for e in summary.skipped_invalid] == ["way/2"]
    assert summary.skipped_invalid[0]["lonlat"] == pytest.approx(list(ORIGIN[:2]))
    (prism,) = _local_prisms(fragment)
    assert np.allclose(prism.vertices, SQUARE, atol=COORD_TOLERANCE_M)


def test_random_bowties_are_repaired_into_valid_prisms() -> None:
    """Property: a quadrilateral with two corners swapped (a bowtie), anywhere, any size and
    orientation, imports as valid prisms whose union is shapely's repair of it."""
    import shapely

    rng = np.random.default_rng(11)
    for trial in range(40):
        c = rng.uniform(-300, 300, 2)
        w, h = rng.uniform(3, 60, 2)
        a = rng.uniform(0, np.pi)
        rect = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        quad = rect @ rot.T + c
        quad[[1, 2]] = quad[[2, 1]]  # crossing edges
        quad += rng.normal(0, 0.2, quad.shape)  # not a perfect X
        fragment, summary = _import(_feature(_poly(quad.tolist()), f"way/{trial}", building="yes"))
        (entry,) = summary.repaired
        assert entry["id"] == f"way/{trial}" and entry["parts"] >= 2
        got = _union(_local_prisms(fragment))
        want = shapely.make_valid(shapely.Polygon(quad))
        assert got.area == pytest.approx(want.area, abs=AREA_TOLERANCE_M2)
        assert shapely.symmetric_difference(got, want).area < AREA_TOLERANCE_M2


def _courtyard_scene(overlap_m: float | None = None) -> tuple[Scene, list[Prism]]:
    from ris_planner.io import geojson_read as gi

    if overlap_m is None:
        fragment, summary = _import(
            _feature(_poly(COURTYARD, HOLE), "way/5", building="yes", height=12)
        )
    else:
        saved = gi.PIECE_OVERLAP_M
        try:
            gi.simple_pieces.__defaults__ = (overlap_m,)
            fragment, summary = _import(
                _feature(_poly(COURTYARD, HOLE), "way/5", building="yes", height=12)
            )
        finally:
            gi.simple_pieces.__defaults__ = (saved,)
    assert summary.courtyards == 1
    prisms = _local_prisms(fragment)
    return Scene.from_environment(Environment(obstacles=prisms)), prisms


def test_courtyards_stay_open_and_cuts_do_not_leak() -> None:
    import shapely

    scene, prisms = _courtyard_scene()
    assert len(prisms) == 2
    want = shapely.Polygon(COURTYARD, [HOLE])
    got = _union(prisms)
    assert shapely.symmetric_difference(got, want).area < AREA_TOLERANCE_M2  # hole not filled
    a = np.array(
        [
            [20.0, 20.0, 1.5],  # courtyard → courtyard: clear
            [20.0, 20.0, 1.5],  # courtyard → out over the roof: clear
            [20.0, -5.0, 5.0],  # along the cut line x = 20 through the south wing: blocked
            [15.0, 5.0, 5.0],  # across the cut inside the south wing: blocked
            [20.0, 20.0, 1.5],  # courtyard → street through the east wing: blocked
        ]
    )
    b = np.array(
        [
            [25.0, 14.0, 1.5],
            [20.0, 32.0, 60.0],
            [20.0, 45.0, 5.0],
            [25.0, 5.0, 5.0],
            [60.0, 20.0, 1.5],
        ]
    )
    assert scene.blocked(a, b).tolist() == [False, False, True, True, True]
    # the courtyard is not inside the building; the wings are
    assert scene.inside(np.array([[20.0, 20.0, 1.5], [20.0, 5.0, 1.5]])).tolist()[0] == -1
    assert scene.inside(np.array([[20.0, 5.0, 1.5]]))[0] >= 0
    # without the overlap, a leg along the shared edge of two pieces would pass: the test
    # above can fail
    bare, _ = _courtyard_scene(overlap_m=0.0)
    assert not bare.blocked(a[2:3], b[2:3])[0]


def test_a_ue_area_in_a_courtyard_imports_and_plans() -> None:
    from ris_planner.io.site_import import import_data, plan_from_import
    from ris_planner.planning import run_plan

    def pt(x: float, y: float) -> list[float]:
        return FRAME.to_geographic(np.array([[x, y]]))[0].tolist()

    sites = [(12.05, 20, 90), (27.95, 20, 270), (20, 12.05, 0), (20, 27.95, 180)]
    fc = _fc(
        _feature(_poly(COURTYARD, HOLE), "way/1", building="yes", height="12"),
        _feature(_poly([[13, 13], [27, 13], [27, 27], [13, 27]]), "way/2", density=1),
        *(
            _feature(
                {"type": "Point", "coordinates": pt(x, y)}, name=f"s{k}", height=6, azimuth_deg=az
            )
            for k, (x, y, az) in enumerate(sites)
        ),
    )
    fragment, summary = import_data(json.dumps(fc).encode(), "geojson", origin=ORIGIN)
    assert summary["area_points"] == 9 and summary["candidates"] == 4
    doc, _ = plan_from_import(fragment, "geojson", summary)
    doc |= {"pairs": {"sample": 100, "seed": 1}, "ris_count": [2]}
    local, _ = to_local(doc)
    plan = run_plan(local).to_json()
    assert plan["dropped_points"] == {"tx": 0, "rx": 0}  # no courtyard point is "inside"
    assert plan["by_count"][0]["top_layouts"][0]["objective"] > 0.5


@pytest.mark.parametrize(
    ("tags", "problem", "used", "height"),
    [
        ({"height": "tall", "building:levels": "4"}, "height", "building:levels 4 × 3 m", 12.0),
        ({"height": "3;4"}, "height", "4 (the largest value)", 4.0),
        ({"height": ""}, "height", "the default height 10 m", DEFAULT_BUILDING_HEIGHT_M),
        ({"height": "-5"}, "height", "the default height", DEFAULT_BUILDING_HEIGHT_M),
        ({"height": "nan"}, "height", "the default height", DEFAULT_BUILDING_HEIGHT_M),
        ({"building:levels": "0"}, "building:levels", "the default height", 10.0),
        ({"height": 20, "min_height": "ground"}, "min_height", "base 0 m", 20.0),
    ],
)
def test_unusable_height_tags_are_reported(
    tags: dict, problem: str, used: str, height: float
) -> None:
    fragment, summary = _import(
        _feature(_poly(SQUARE), "way/4", building="yes", name="Talo", **tags)
    )
    (entry,) = summary.tag_problems
    assert (entry["id"], entry["name"], entry["tag"], entry["value"]) == (
        "way/4",
        "Talo",
        problem,
        tags[problem],
    )
    assert used in entry["used"] and entry["lonlat"] == pytest.approx(list(ORIGIN[:2]))
    assert fragment["environment"]["obstacles"][0]["height_m"] == pytest.approx(height)
    assert parse_length("-5") == -5  # a length; a negative height is the tag rule's to refuse


def _rect_ring(lon: float, lat: float, w_m: float, h_m: float, angle: float) -> list[list[float]]:
    frame = Frame((lon, lat, 0.0))
    r = np.array([[-w_m, -h_m], [w_m, -h_m], [w_m, h_m], [-w_m, h_m]]) / 2
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    ll = frame.to_geographic(r @ rot.T).tolist()
    return [*ll, ll[0]]


def _town(rng: np.random.Generator, lon: float, lat: float, n: int) -> list[dict]:
    """n rectangular buildings (rotated at random) within ~300 m of (lon, lat)."""
    out = []
    for k in range(n):
        dlon, dlat = rng.uniform(-300, 300, 2) / 111_000
        ring = _rect_ring(
            lon + dlon / math.cos(math.radians(lat)),
            lat + dlat,
            *rng.uniform(8, 30, 2),
            rng.uniform(0, np.pi),
        )
        out.append(_feature({"type": "Polygon", "coordinates": [ring]}, f"way/{k}", building="yes"))
    return out


def _swap(feature: dict) -> dict:
    geom = feature["geometry"]
    rings = [[[p[1], p[0]] for p in r] for r in geom["coordinates"]]
    return {**feature, "geometry": {"type": "Polygon", "coordinates": rings}}


def test_random_lat_lon_swaps_are_detected() -> None:
    """Property: in a town anywhere (where [lat, lon] lies far from [lon, lat]), one feature
    swapped is named, with "swapped?"; every feature swapped is told from the square corners
    where a degree of longitude and one of latitude differ in length; nothing is flagged in
    the town as given."""
    rng = np.random.default_rng(5)
    checked_file = 0
    for _ in range(25):
        lat = float(rng.uniform(-60, 60))
        lon = float(rng.uniform(-90, 90))
        if abs(lat - lon) < 2:
            continue
        feats = _town(rng, lon, lat, 8)
        fragment, _ = import_features(_fc(*feats))  # as given: fine
        assert len(fragment["environment"]["obstacles"]) == 8
        k = int(rng.integers(8))
        mixed = [*feats[:k], _swap(feats[k]), *feats[k + 1 :]]
        for origin in (None, (lon, lat)):
            with pytest.raises(FeatureError, match=r"swapped\?") as info:
                import_features(_fc(*mixed), origin)
            assert info.value.field == f"features.{k}"
            assert str(info.value).startswith(f"feature {k} (id way/{k}) at [")
        ratio = math.cos(math.radians(lat)) / math.cos(math.radians(lon))
        if abs(math.log(ratio)) > math.log(1.3):
            with pytest.raises(
                DocumentFieldError, match=r"swapped\?.*e\.g\. feature 0 \(id way/0\)"
            ):
                import_features(_fc(*[_swap(f) for f in feats]))
            import_features(
                _fc(*[_swap(f) for f in feats]), options=ImportOptions(swap_check=False)
            )
            checked_file += 1
    assert checked_file >= 10


def test_a_swapped_origin_is_blamed_on_the_origin() -> None:
    feats = _town(np.random.default_rng(2), 24.949, 60.1655, 3)
    with pytest.raises(
        DocumentFieldError, match=r"read as \[lat, lon\] the origin lies among"
    ) as info:
        import_features(_fc(*feats), (60.1655, 24.949))
    assert info.value.field == "origin"
    assert re.search(r"nearest feature, feature \d \(id way/\d\) at \[24\.9", str(info.value))
    with pytest.raises(DocumentFieldError, match=r"the wrong origin\?") as info:
        import_features(_fc(*feats), (10.0, 50.0))
    assert info.value.field == "origin"


def test_cli_swapped_file_is_one_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    feats = _town(np.random.default_rng(4), 24.949, 60.1655, 10)
    src = tmp_path / "swapped.geojson"
    src.write_text(json.dumps(_fc(*[_swap(f) for f in feats])))
    assert main(["import", "geojson", str(src)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: features: ") and "swapped?" in err and err.count("\n") == 1
    assert main(["import", "geojson", str(src), "--no-swap-check"]) == 0


def test_licence_is_carried_from_the_input() -> None:
    from ris_planner.io.site_import import plan_from_import

    fc = _fc(_feature(_poly(SQUARE), "b1", building="yes")) | {
        "license": "CC-BY 4.0",
        "attribution": "City survey",
    }
    fragment, summary = import_features(fc, ORIGIN)
    assert (fragment["license"], fragment["attribution"]) == ("CC-BY 4.0", "City survey")
    doc, _ = plan_from_import(fragment, "geojson", summary.to_json())
    assert doc["license"] == "CC-BY 4.0"
    local, _ = to_local(doc)
    assert "license" not in local and "attribution" not in local  # not the engine's
    # OSM ids and no licence of its own: the ODbL, with a note
    fragment, summary = import_features(_fc(_feature(_poly(SQUARE), "way/1", building="yes")))
    assert fragment["license"] == OSM_LICENSE and any(
        "OpenStreetMap ids" in n for n in summary.notes
    )
    fragment, _ = import_features(_fc(_feature(_poly(SQUARE), "b1", building="yes")))
    assert "license" not in fragment
    with pytest.raises(DocumentFieldError, match=r"^license: expected a text"):
        to_local({"license": 5, "frame": {"origin": list(ORIGIN)}})


OSM_CUT = Path(__file__).parent / "data" / "osm" / "bulevardi.geojson"


def test_real_osm_cut_imports_with_defaults() -> None:
    import shapely

    assert OSM_CUT.stat().st_size < 150_000
    fc = json.loads(OSM_CUT.read_text())
    assert fc["license"] == OSM_LICENSE
    fragment, summary = import_features(fc)
    assert fragment["license"] == OSM_LICENSE
    assert summary.buildings == 45 and summary.courtyards == 15 and summary.prisms == 61
    assert summary.repaired == [] and summary.skipped_invalid == []  # the extract has none
    prisms = _local_prisms(fragment)
    _, frame = to_local(fragment)
    assert frame is not None
    # every courtyard building: its pieces cover exactly the polygon less its courtyards
    by_name: dict[str, list[Prism]] = {}
    for p in prisms:
        by_name.setdefault(str(p.name).split("#")[0], []).append(p)
    for f in fc["features"]:
        if f["geometry"]["type"] != "MultiPolygon":
            continue
        want = shapely.MultiPolygon(
            [
                shapely.Polygon(
                    frame.from_source(np.array(poly[0])[:-1]),
                    [frame.from_source(np.array(r)[:-1]) for r in poly[1:]],
                )
                for poly in f["geometry"]["coordinates"]
            ]
        )
        got = _union(by_name[f["properties"].get("name") or f["properties"]["@id"]])
        assert shapely.symmetric_difference(got, want).area < 0.01 * 1e-3 * want.length + 1e-2
    # a real building made invalid (two corners exchanged): repaired and named by its OSM id
    i = next(k for k, f in enumerate(fc["features"]) if f["geometry"]["type"] == "Polygon")
    ring = fc["features"][i]["geometry"]["coordinates"][0]
    ring[1], ring[2] = ring[2], ring[1]
    _, summary = import_features(fc)
    (entry,) = summary.repaired
    assert entry["id"] == fc["features"][i]["properties"]["@id"] and entry["feature"] == i
    _, summary = import_features(fc, options=ImportOptions(invalid="skip"))
    assert [e["id"] for e in summary.skipped_invalid] == [entry["id"]]


def test_unusable_density_and_width_are_reported() -> None:
    def line(xy: list[list[float]]) -> dict:
        return {"type": "LineString", "coordinates": FRAME.to_geographic(np.array(xy)).tolist()}

    fragment, summary = _import(
        _feature(_poly(SQUARE), "a1", density="lots"),
        _feature(_poly(L_SHAPE), "a2", density=-1),
        _feature(line([[0, -10], [50, -10]]), "r1", highway="residential", width="wide"),
        _feature(line([[0, -20], [50, -20]]), "r2", width="narrow"),
    )
    got = [(e["id"], e["tag"], e["used"]) for e in summary.tag_problems]
    assert got == [
        ("a1", "density", "feature skipped"),
        ("a2", "density", "feature skipped"),
        ("r1", "width", "the residential default 6 m"),
        ("r2", "width", "not a road (skipped)"),
    ]
    assert summary.skipped == 2 and "environment" not in fragment and summary.areas == 0
    assert [r["width_m"] for r in fragment["ue_map"]["roads"]] == [HIGHWAY_WIDTH_M["residential"]]


def test_osm_xml_courtyard_relation_keeps_its_inner_ring(tmp_path: Path) -> None:
    import shapely

    outer = [[0, 0], [30, 0], [30, 30], [0, 30]]
    inner = [[10, 10], [20, 10], [20, 20], [10, 20]]
    ll = FRAME.to_geographic(np.array(outer + inner, dtype=float))
    nodes = "\n".join(
        f'<node id="{i + 1}" lat="{lat!r}" lon="{lon!r}"/>'
        for i, (lon, lat) in enumerate(ll.tolist())
    )
    xml = f"""<?xml version='1.0'?><osm version="0.6">{nodes}
     <way id="1"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/></way>
     <way id="2"><nd ref="5"/><nd ref="6"/><nd ref="7"/><nd ref="8"/><nd ref="5"/></way>
     <relation id="9"><member type="way" ref="1" role="outer"/>
      <member type="way" ref="2" role="inner"/>
      <tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation></osm>"""
    path = tmp_path / "court.osm"
    path.write_text(xml)
    fc, _ = osm_xml_features(path)
    assert fc["license"] == OSM_LICENSE
    fragment, summary = import_features(fc, ORIGIN)
    assert summary.courtyards == 1 and fragment["license"] == OSM_LICENSE
    got = _union(_local_prisms(fragment))
    want = shapely.Polygon(outer, [inner])
    assert shapely.symmetric_difference(got, want).area < AREA_TOLERANCE_M2


# --- a site without buildings ------------------------------------------------------------------


def _line(xy: list[list[float]]) -> dict:
    return {"type": "LineString", "coordinates": FRAME.to_geographic(np.array(xy)).tolist()}


def _mount(x: float, y: float, azimuth: float, name: str) -> dict:
    pt = FRAME.to_geographic(np.array([[x, y]]))[0].tolist()
    return _feature({"type": "Point", "coordinates": pt}, name=name, height=6, azimuth_deg=azimuth)


def test_an_import_without_buildings_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Roads and mounting points but no building: the import report warns (the parser's
    summary, the --plan report, the command line's stderr), and so does the plan.json of the
    document it makes; a site with buildings gets neither warning."""
    from ris_planner.io.geoplan import NO_OBSTACLES_WARNING, plan_document, site_warnings
    from ris_planner.io.site_import import import_data, plan_from_import
    from ris_planner.planning import SerialExecutor

    street = _feature(_line([[-30, 0], [30, 0]]), highway="residential")
    mounts = [_mount(x, 8.0, 180, f"m{k}") for k, x in enumerate((-20.0, 0.0, 20.0))]
    bare = _fc(street, *mounts)
    fragment, summary = import_features(bare, ORIGIN)
    assert "environment" not in fragment and summary.warnings == [NO_BUILDINGS_WARNING]
    assert summary.to_json()["warnings"] == [NO_BUILDINGS_WARNING]
    assert "no buildings" in NO_BUILDINGS_WARNING and "every leg as clear" in NO_BUILDINGS_WARNING
    with_building = _fc(street, _feature(_poly(SQUARE), building="yes"))
    assert import_features(with_building, ORIGIN)[1].warnings == []
    # the --plan report of ris-planner import / POST /v1/import
    data = json.dumps(bare).encode()
    frag, summ = import_data(data, "geojson", origin=ORIGIN)
    doc, report = plan_from_import(frag, "geojson", summ)
    assert report.to_json()["warnings"] == [NO_BUILDINGS_WARNING] and len(doc["candidates"]) == 3
    src = tmp_path / "bare.geojson"
    src.write_bytes(data)
    assert main(["import", "geojson", str(src), "--plan"]) == 0
    err = capsys.readouterr().err
    assert f"warning: {NO_BUILDINGS_WARNING}" in err.splitlines()
    # plan.json of that document says every leg was planned in line of sight
    assert site_warnings(doc) == [NO_OBSTACLES_WARNING]
    assert site_warnings({**doc, "environment": {"obstacles": [{"kind": "wall"}]}}) == []
    assert site_warnings({k: v for k, v in doc.items() if k not in ("frame", "license")}) == []
    doc |= {"pairs": {"sample": 40, "seed": 1}, "ris_count": [2], "ris": {"rows": 4, "cols": 4}}
    doc |= {"search": {"certificate_iterations": 0}}
    done = plan_document(doc, tmp_path / "out", executor=SerialExecutor())
    assert done.plan["warnings"][0] == NO_OBSTACLES_WARNING
    assert "no environment obstacles" in NO_OBSTACLES_WARNING


# --- a projected CRS named by the collection's crs member --------------------------------------

TM35FIN_URN = "urn:ogc:def:crs:EPSG::3067"
IMPORT_TOLERANCE_M = 0.01
"""A collection converted to EPSG:3067 and back on import lands within a centimetre of the WGS84
import (the round trip through pyproj is exact to far below that)."""


COURTYARD_FAR = [[0.0, 40.0], [40.0, 40.0], [40.0, 80.0], [0.0, 80.0]]
HOLE_FAR = [[12.0, 52.0], [28.0, 52.0], [28.0, 68.0], [12.0, 68.0]]


def _site_wgs84() -> dict:
    """Buildings (one with a courtyard), a street, a density area and two mounting points."""
    return _fc(
        _feature(_poly(SQUARE), "way/1", building="yes", height=12),
        _feature(_poly(L_SHAPE), "way/2", building="yes", **{"building:levels": 4}),
        _feature(_poly(COURTYARD_FAR, HOLE_FAR), "way/3", building="yes"),
        _feature(_line([[-20, -10], [80, -10]]), "way/4", highway="residential"),
        _feature(_poly([[60.0, 0.0], [80.0, 0.0], [80.0, 15.0], [60.0, 15.0]]), density=0.5),
        _mount(10.0, -0.2, 180, "s0"),
        _mount(40.0, -0.2, 180, "s1"),
    )


def _projected(collection: dict, crs: object, epsg: str = "EPSG:3067") -> dict:
    """The collection with every position transformed to ``epsg`` (easting, northing; heights
    kept) and the given ``crs`` member."""
    import pyproj

    t = pyproj.Transformer.from_crs("EPSG:4326", epsg, always_xy=True)

    def conv(c: list) -> list:
        if isinstance(c[0], int | float):
            x, y = t.transform(c[0], c[1])
            return [x, y, *c[2:]]
        return [conv(p) for p in c]

    out = json.loads(json.dumps(collection))
    for f in out["features"]:
        f["geometry"]["coordinates"] = conv(f["geometry"]["coordinates"])
    return {"type": "FeatureCollection", "crs": crs, "features": out["features"]}


def _local_xy(points: list) -> np.ndarray:
    return FRAME.from_geographic(np.asarray(points, dtype=float)[:, :2])


def _assert_same_site(got: dict, want: dict) -> None:
    """Two import fragments hold the same geometry within :data:`IMPORT_TOLERANCE_M`."""
    assert got["frame"] == want["frame"]
    obs_g, obs_w = got["environment"]["obstacles"], want["environment"]["obstacles"]
    assert [(o["name"], o["height_m"], o["base_m"]) for o in obs_g] == [
        (o["name"], o["height_m"], o["base_m"]) for o in obs_w
    ]
    for a, b in zip(obs_g, obs_w, strict=True):
        err = np.abs(_local_xy(a["footprint"]) - _local_xy(b["footprint"])).max()
        assert err < IMPORT_TOLERANCE_M, (a["name"], err)
    road_g, road_w = got["ue_map"]["roads"], want["ue_map"]["roads"]
    for a, b in zip(road_g, road_w, strict=True):
        assert np.abs(_local_xy(a["points"]) - _local_xy(b["points"])).max() < IMPORT_TOLERANCE_M
    pts_g, pts_w = got["ue_map"]["points"], want["ue_map"]["points"]
    assert len(pts_g) == len(pts_w) and got["ue_map"]["weights"] == want["ue_map"]["weights"]
    assert np.abs(_local_xy(pts_g) - _local_xy(pts_w)).max() < IMPORT_TOLERANCE_M
    assert np.allclose([p[2] for p in pts_g], [p[2] for p in pts_w])
    cand_g, cand_w = got["candidates"], want["candidates"]
    assert [c["name"] for c in cand_g] == [c["name"] for c in cand_w]
    pos_g = np.array([c["position"] for c in cand_g])
    pos_w = np.array([c["position"] for c in cand_w])
    assert np.abs(_local_xy(pos_g) - _local_xy(pos_w)).max() < IMPORT_TOLERANCE_M
    assert np.allclose(pos_g[:, 2], pos_w[:, 2])
    assert np.allclose([c["orientation"] for c in cand_g], [c["orientation"] for c in cand_w])


@pytest.mark.parametrize(
    "crs",
    [
        {"type": "name", "properties": {"name": TM35FIN_URN}},
        {"type": "name", "properties": {"name": "EPSG:3067"}},
        "EPSG:3067",
    ],
)
def test_a_projected_crs_is_converted_on_import(crs: object) -> None:
    from ris_planner.io.site_import import import_data, plan_from_import

    site = _site_wgs84()
    want, want_summary = import_data(json.dumps(site).encode(), "geojson", origin=ORIGIN)
    projected = _projected(site, crs)
    some = projected["features"][0]["geometry"]["coordinates"][0][0]
    assert some[0] > 1e5 and some[1] > 6e6  # metres: no WGS84 position
    got, summary = import_data(json.dumps(projected).encode(), "geojson", origin=ORIGIN)
    _assert_same_site(got, want)
    assert summary["crs"]["given"] == crs and summary["crs"]["name"] == "ETRS89 / TM35FIN(E,N)"
    assert summary["crs"]["converted_to"].startswith("WGS84")
    assert any("converted from the crs member" in n for n in summary["notes"])
    assert "crs" not in want_summary
    _, report = plan_from_import(got, "geojson", summary)
    assert report.to_json()["crs"]["name"] == "ETRS89 / TM35FIN(E,N)"
    # the default frame (the bounding-box centre) is the WGS84 file's too
    default, _ = import_data(json.dumps(projected).encode(), "geojson")
    wgs, _ = import_data(json.dumps(site).encode(), "geojson")
    assert np.allclose(default["frame"]["origin"], wgs["frame"]["origin"], atol=2e-6)


def test_a_projected_sites_file_and_a_wgs84_crs_member() -> None:
    from ris_planner.io.site_import import import_data

    mounts = _fc(*[f for f in _site_wgs84()["features"] if f["geometry"]["type"] == "Point"])
    want, _ = import_data(json.dumps(mounts).encode(), "sites", origin=ORIGIN)
    got, summary = import_data(
        json.dumps(_projected(mounts, "EPSG:3067")).encode(), "sites", origin=ORIGIN
    )
    assert summary["crs"]["name"] == "ETRS89 / TM35FIN(E,N)" and summary["candidates"] == 2
    pos_g = np.array([c["position"] for c in got["candidates"]])
    pos_w = np.array([c["position"] for c in want["candidates"]])
    assert np.abs(_local_xy(pos_g) - _local_xy(pos_w)).max() < IMPORT_TOLERANCE_M
    # a crs member naming WGS84 itself: the positions are read as they are
    site = _site_wgs84()
    for name in ("urn:ogc:def:crs:OGC:1.3:CRS84", "EPSG:4326"):
        named = {**site, "crs": {"type": "name", "properties": {"name": name}}}
        fragment, s = import_features(named, ORIGIN)
        assert fragment == import_features(site, ORIGIN)[0]
        assert s.crs is not None and s.crs["converted_to"] is None


@pytest.mark.parametrize(
    ("crs", "why"),
    [
        ({"type": "name", "properties": {"name": "EPSG:99999"}}, "PROJ knows no CRS 'EPSG:99999'"),
        ("not a crs at all", "PROJ knows no CRS 'not a crs at all'"),
        ({"type": "link", "properties": {"href": "http://x/crs", "type": "proj4"}}, "linked CRS"),
        ({"type": "name", "properties": {}}, "expected a named CRS"),
        ({"type": "name", "properties": {"name": "EPSG:5773"}}, "not a horizontal CRS"),
    ],
)
def test_an_unusable_crs_member_says_what_it_saw_and_how_to_convert(crs: object, why: str) -> None:
    projected = _projected(_site_wgs84(), crs)
    with pytest.raises(DocumentFieldError) as err:
        import_features(projected)
    assert err.value.field == "crs"
    message = str(err.value)
    assert message.startswith("crs: the collection has a crs member, ")
    assert json.dumps(crs) in message and why in message
    assert "ogr2ogr -f GeoJSON -t_srs EPSG:4326 out.geojson in.geojson" in message


def test_projected_coordinates_without_a_crs_member_say_so() -> None:
    projected = _projected(_site_wgs84(), None)
    del projected["crs"]
    with pytest.raises(RisPlannerError) as err:
        import_features(projected)
    message = str(err.value)
    assert "is not a WGS84 [lon, lat] position" in message
    assert "projected coordinates (metres) without a crs member?" in message
    assert "ogr2ogr -f GeoJSON -t_srs EPSG:4326" in message


def test_cli_imports_a_projected_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ris_planner.io.site_import import import_data

    src = tmp_path / "site-3067.geojson"
    src.write_text(
        json.dumps(_projected(_site_wgs84(), {"type": "name", "properties": {"name": TM35FIN_URN}}))
    )
    assert main(["import", "geojson", str(src), "--origin", "24.949,60.1655"]) == 0
    captured = capsys.readouterr()
    want, _ = import_data(json.dumps(_site_wgs84()).encode(), "geojson", origin=ORIGIN)
    got = json.loads(captured.out)
    _assert_same_site(got, want)  # the Point features too: import_sites with the crs
    assert len(got["candidates"]) == 2
    assert '"converted_to": "WGS84' in captured.err
