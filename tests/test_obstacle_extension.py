"""An obstacle kind defined and registered only here – a vertical cylinder, ``bollard`` – runs
end to end through everything that reads, writes or draws obstacles
(docs/guides/adding-an-obstacle-kind.md): a plan document with it validates and plans (the
visibility asks its narrow phase; UE points inside it are dropped), plan.json, the
``plan.geojson`` export writes its own geometry (a Point with its radius), the GeoJSON import
reads that feature back to the same obstacle, the GeoTIFF leaves the pixels inside it without
data, and the web page draws it from the spec ``GET /v1/obstacle-kinds`` gives (headless
Chromium). The kind is registered by a fixture and removed after each test."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import pytest
from pydantic import Field, ValidationError
from tolerance import BOUND_ACCURACY

from ris_planner.environment.kinds import KINDS, footprint_contains, register, unregister
from ris_planner.environment.kinds.base import (
    BoolArray,
    Faces,
    FloatArray,
    GeoJSON,
    IntArray,
    ObstacleModel,
    ToOutput,
    coordinates,
    position_xy,
)
from ris_planner.environment.model import Environment
from ris_planner.environment.scene import Scene

try:  # the browser test's fixtures and helpers; the rest runs without a browser
    from test_web import (  # noqa: F401  (fixtures: browser, page, server, shots)
        browser,
        expect,
        open_page,
        page,
        path_vertices,
        screen_of,
        server,
        shots,
    )
    from test_web_map import upload

    NO_BROWSER = None
except pytest.skip.Exception as exc:
    NO_BROWSER = str(exc)

NAME = "bollard"
SIDES = 16
"""Faces of a bollard for reflections (a regular polygon around its circle)."""


class Bollard(ObstacleModel):
    """A vertical cylinder of radius ``radius_m`` around ``center`` (the toy kind)."""

    kind_name: ClassVar[str] = NAME
    kind: Literal["bollard"] = Field(NAME, description="Obstacle kind (discriminator)")
    center: list[float] = Field(min_length=2, max_length=2)
    radius_m: float = Field(gt=0, le=1e4, allow_inf_nan=False)

    def faces(self) -> Faces:
        a = 2 * np.pi * np.arange(SIDES) / SIDES
        v = np.asarray(self.center) + self.radius_m * np.column_stack([np.cos(a), np.sin(a)])
        w = np.roll(v, -1, axis=0)
        e = w - v
        normal = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
        return Faces(v, w, normal, False)

    def outline(self) -> FloatArray:
        c, r = np.asarray(self.center, dtype=float), self.radius_m
        return np.array([c - r, c + r])

    def work_units(self) -> int:
        return SIDES


@dataclass(frozen=True)
class PackedBollards:
    center: FloatArray
    radius: FloatArray
    base: FloatArray
    top: FloatArray


def bollard_depth(p: FloatArray, c: FloatArray, r: FloatArray, base: Any, top: Any) -> FloatArray:
    """[K] min(distance inside the circle, above the base, below the top) (≤ 0 outside)."""
    rho = np.hypot(p[..., 0] - c[:, 0], p[..., 1] - c[:, 1])
    return np.asarray(np.minimum(np.minimum(r - rho, p[..., 2] - base), top - p[..., 2]))


class BollardKind:
    """The toy's kind object: solid, numpy only; the leg's depth is concave along it, so a
    golden-section search finds its maximum."""

    name = NAME
    model: type[ObstacleModel] = Bollard
    solid = True
    compiled = False
    point_fields: tuple[tuple[str, ...], ...] = (("center",),)
    draw: ClassVar[dict[str, Any]] = {"shape": "circle", "center": "center", "radius": "radius_m"}
    calls = 0

    def pack(self, obstacles: list[Any]) -> PackedBollards:
        return PackedBollards(
            np.array([o.center for o in obstacles], dtype=float).reshape(-1, 2),
            np.array([o.radius_m for o in obstacles], dtype=float),
            np.array([o.base_m for o in obstacles], dtype=float),
            np.array([o.top_m for o in obstacles], dtype=float),
        )

    def blocks(
        self, packed: PackedBollards, rows: IntArray, a: FloatArray, b: FloatArray, tol: float
    ) -> BoolArray:
        BollardKind.calls += 1
        c, r = packed.center[rows], packed.radius[rows]
        base, top = packed.base[rows], packed.top[rows]

        def depth(t: FloatArray) -> FloatArray:
            return bollard_depth(a + t[:, None] * (b - a), c, r, base, top)

        lo, hi = np.zeros(len(rows)), np.ones(len(rows))
        g = (math.sqrt(5) - 1) / 2
        for _ in range(80):
            m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
            left = depth(m1) < depth(m2)
            lo, hi = np.where(left, m1, lo), np.where(left, hi, m2)
        return np.asarray(depth(0.5 * (lo + hi)) > tol)

    def depth(self, packed: PackedBollards, rows: IntArray, points: FloatArray) -> FloatArray:
        c, r = packed.center[rows], packed.radius[rows]
        d = bollard_depth(points, c, r, packed.base[rows], packed.top[rows])
        return np.asarray(np.maximum(d, 0.0))

    def to_geojson(self, obstacle: Bollard, xy: ToOutput) -> tuple[GeoJSON, GeoJSON]:
        centre = xy(np.array([obstacle.center], dtype=float))[0].tolist()
        return {"type": "Point", "coordinates": centre}, {"radius_m": obstacle.radius_m}

    def from_geojson(self, geometry: GeoJSON, properties: GeoJSON) -> dict[str, Any]:
        centre = position_xy(coordinates(geometry, self.name, "Point"))
        return {"center": centre, "radius_m": properties.get("radius_m")}


@pytest.fixture
def bollards() -> Iterator[BollardKind]:
    kind = BollardKind()
    register(kind)
    try:
        yield kind
    finally:
        unregister(NAME)


# the site: a 4 m prism block, a bollard of radius 1 m at (6, 0) and a UE grid around them
BLOCK = [[-4.0, -12.0], [-2.0, -12.0], [-2.0, -8.0], [-4.0, -8.0]]
CENTRE, RADIUS = (6.0, 0.0), 1.0
BOLLARD = {"kind": NAME, "name": "b1", "center": list(CENTRE), "radius_m": RADIUS, "height_m": 3}
ORIGIN = (24.949, 60.1655, 0.0)


def local_plan_document() -> dict[str, Any]:
    """A small plan in local metres: two candidates west of the bollard, UE points on a 1 m
    grid around it (those inside it are dropped)."""
    grid = [[x, y, 1.5] for x in np.arange(3.0, 10.0, 1.0) for y in np.arange(-3.0, 4.0, 1.0)]
    prism = {"kind": "prism", "name": "block", "footprint": BLOCK, "height_m": 4}
    return {
        "environment": {"obstacles": [prism, BOLLARD]},
        "candidates": [
            {"position": [0.0, 0.5, 2.0], "orientation": [0.0, 0.1, 0.0], "name": "A"},
            {"position": [0.0, -6.0, 2.0], "orientation": [0.5, 0.1, 0.0], "name": "B"},
        ],
        "tx_map": {"points": grid},
        "rx_map": {"points": grid},
        "pairs": {"sample": 60, "seed": 0},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [1],
    }


def test_a_registered_kind_validates_and_unregistered_is_unknown(bollards: BollardKind) -> None:
    env = Environment.model_validate({"obstacles": [BOLLARD]})
    (ob,) = env.obstacles
    assert isinstance(ob, Bollard) and ob.center == list(CENTRE)
    assert env.model_dump(mode="json")["obstacles"][0]["radius_m"] == RADIUS
    with pytest.raises(ValidationError, match="radius_m"):
        Environment.model_validate({"obstacles": [{**BOLLARD, "radius_m": -1}]})
    unregister(NAME)
    try:
        with pytest.raises(ValidationError, match="unknown obstacle kind 'bollard'"):
            Environment.model_validate({"obstacles": [BOLLARD]})
    finally:
        register(bollards)
    assert NAME in KINDS


def test_visibility_and_inside_ask_its_narrow_phase(bollards: BollardKind) -> None:
    env = Environment.model_validate({"obstacles": [BOLLARD]})
    scene = Scene(env)
    a = np.array([[0, 0, 1], [0, 1.5, 1], [0, 0, 4], [6, -5, 0.5]], dtype=float)
    b = np.array([[12, 0, 1], [12, 1.5, 1], [12, 0, 4], [6, 5, 2.5]], dtype=float)
    before = BollardKind.calls
    assert scene.blocked(a, b).tolist() == [True, False, False, True]
    assert BollardKind.calls > before
    assert scene.inside(np.array([[6.5, 0, 1], [7.5, 0, 1], [6, 0, 3.5]])).tolist() == [0, -1, -1]
    inside = footprint_contains(env.obstacles[0], np.array([[6.5, 0.5], [7.1, 0.0]]))
    assert inside.tolist() == [True, False]


def test_plan_with_it_runs(bollards: BollardKind) -> None:
    from ris_planner.planning import SerialExecutor, run_plan
    from ris_planner.planning.prepare import prepare_plan

    doc = local_plan_document()
    inputs = prepare_plan(doc)
    assert inputs.dropped == {"tx": 1, "rx": 1}  # the grid point at the bollard's centre
    before = BollardKind.calls
    with SerialExecutor() as ex:
        result = run_plan(doc, executor=ex)
    assert BollardKind.calls > before  # the plan's visibility asked the bollard
    plan = json.loads(json.dumps(result.to_json()))  # plan.json
    assert [e["ris_count"] for e in plan["by_count"]] == [1]


def _frame() -> Any:
    from ris_planner.io.frames import Frame

    return Frame(ORIGIN)


def geographic(doc: dict[str, Any]) -> dict[str, Any]:
    """The local document's environment in WGS84 around :data:`ORIGIN`."""
    frame = _frame()

    def ll(xy: Any) -> list[Any]:
        return frame.to_geographic(np.asarray(xy, dtype=float)).tolist()

    obstacles = []
    for ob in doc["environment"]["obstacles"]:
        ob = dict(ob)
        if "footprint" in ob:
            ob["footprint"] = ll(ob["footprint"])
        for key in ("center", "start", "end"):
            if key in ob:
                ob[key] = ll([ob[key]])[0]
        obstacles.append(ob)
    return {"frame": {"origin": list(ORIGIN)}, "environment": {"obstacles": obstacles}}


def test_geojson_export_and_reimport_give_the_same_obstacles(bollards: BollardKind) -> None:
    pytest.importorskip("pyproj")
    pytest.importorskip("shapely")
    from ris_planner.io.frames import to_local
    from ris_planner.io.geojson_read import import_features
    from ris_planner.io.geojson_write import plan_geojson

    local = local_plan_document()
    wall = {"kind": "wall", "start": [0, 3], "end": [2, 3], "base_m": 1, "height_m": 2}
    local["environment"]["obstacles"].append({**wall, "material": "glass"})
    doc = geographic(local)
    fc = plan_geojson({"candidates": []}, doc)
    feats = [f for f in fc["features"] if f["properties"]["role"] == "obstacle"]
    assert [f["geometry"]["type"] for f in feats] == ["Polygon", "Point", "LineString"]
    props = feats[1]["properties"]
    assert props["kind"] == NAME and props["radius_m"] == RADIUS and props["height_m"] == 3
    assert feats[1]["geometry"]["coordinates"] == pytest.approx(
        doc["environment"]["obstacles"][1]["center"], abs=1e-9
    )
    # the exported file read back: the same obstacles (a frame at the same origin)
    fragment, _ = import_features(json.loads(json.dumps(fc)), origin=ORIGIN)
    back, _ = to_local(fragment)
    want, _ = to_local(doc)
    got_env = Environment.model_validate(back["environment"])
    want_env = Environment.model_validate(want["environment"])
    assert [type(o) for o in got_env.obstacles] == [type(o) for o in want_env.obstacles]
    for got, exp in zip(got_env.obstacles, want_env.obstacles, strict=True):
        g, e = got.model_dump(mode="json"), exp.model_dump(mode="json")
        assert g.keys() == e.keys()
        for key in g:
            if isinstance(e[key], list):  # positions through WGS84 and back: 1 mm
                assert np.allclose(g[key], e[key], atol=1e-3), key
            elif isinstance(e[key], float):
                assert g[key] == pytest.approx(e[key], rel=BOUND_ACCURACY), key
            else:
                assert g[key] == e[key], key


def test_geotiff_has_no_data_inside_it(bollards: BollardKind, tmp_path: Path) -> None:
    rasterio = pytest.importorskip("rasterio")
    pytest.importorskip("shapely")
    from ris_planner.io.geotiff import NODATA, write_geotiff

    points = [
        {"index": i, "position": [x, y, 1.5], "weight": 1.0, "bound_m": {"1": 0.1}}
        for i, (x, y) in enumerate((x, y) for x in range(2, 11) for y in range(-4, 5))
    ]
    path = write_geotiff(
        tmp_path / "heatmap.tif", points, {"environment": {"obstacles": [BOLLARD]}}
    )
    with rasterio.open(path) as ds:
        band = ds.read(1)
        nodata = []
        for p in points:
            x, y = p["position"][:2]
            row, col = ds.index(x, y)
            if band[row, col] == NODATA:
                nodata.append((x, y))
    # pixel centres strictly inside the circle (radius 1 m around (6, 0)): only the centre
    assert nodata == [CENTRE]


@pytest.mark.skipif(NO_BROWSER is not None, reason=str(NO_BROWSER))
def test_the_page_draws_it_from_its_spec(
    bollards: BollardKind, page: tuple[Any, Any], server: str, shots: Any
) -> None:
    """The page draws a kind it has never heard of from ``GET /v1/obstacle-kinds``: a circle of
    the bollard's radius at its centre, filled (solid), and a candidate dragged onto it would be
    inside a building. The served page runs in its own process without the toy kind, so the
    two requests that read it are answered here, by the service's own functions in this
    process (where the fixture registered it)."""
    from api.routes.meta import obstacle_kinds
    from api.routes.web import preview_answer
    from api.settings import Settings

    pg, _ = page
    memory_mb = Settings().job_memory_mb

    def kinds(route: Any) -> None:
        route.fulfill(
            status=200, content_type="application/json", body=obstacle_kinds().model_dump_json()
        )

    def validate(route: Any) -> None:
        answer = preview_answer(route.request.post_data_buffer, memory_mb)
        route.fulfill(status=answer.status, content_type="application/json", body=answer.body)

    pg.route("**/v1/obstacle-kinds", kinds)
    pg.route("**/v1/plans/validate", validate)
    open_page(pg, server)
    upload(pg, local_plan_document(), "bollard.json")
    expect(pg.locator("#validation-status")).to_contain_text("Valid: 2 candidate sites")
    drawn = pg.locator("path.obstacle.bollard")
    expect(drawn).to_have_count(1)
    expect(pg.locator("path.obstacle.prism")).to_have_count(1)
    k = pg.evaluate("window.risPlanner.pxPerMetre()")
    xs, ys = path_vertices(drawn)
    assert max(xs) - min(xs) == pytest.approx(2 * RADIUS * k, abs=1.01)
    assert max(ys) - min(ys) == pytest.approx(2 * RADIUS * k, abs=1.01)
    box = drawn.bounding_box()  # (it holds the outline's stroke around the vertices)
    assert box is not None
    centre = (box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    assert centre == pytest.approx(screen_of(pg, *CENTRE), abs=1.01)
    assert "b1" in (drawn.locator("title").text_content() or "")
    # solid: a candidate at its centre is inside a building on the page too
    pg.evaluate(
        "(() => { const s = window.risPlanner.state;"
        f" s.cands.push({{position: [{CENTRE[0]}, {CENTRE[1]}, 1], orientation: [0, 0, 0],"
        " name: 'in'}); })()"
    )
    pg.evaluate("window.dispatchEvent(new Event('resize'))")  # the page redraws on a resize
    expect(pg.locator("#cand-inside")).to_contain_text("in [2] in b1")  # name [index]
    shots.take(pg, "obstacle-extension")


def test_the_guide_cites_existing_files_and_members() -> None:
    """docs/guides/adding-an-obstacle-kind.md names only files that exist and protocol members
    that ``kinds/base.py`` (or the registry's functions, ``kinds/__init__.py``) defines."""
    root = Path(__file__).resolve().parent.parent
    page = (root / "docs/guides/adding-an-obstacle-kind.md").read_text(encoding="utf-8")
    cited = set(re.findall(r"`((?:ris_planner|api|tests)/[\w/.]+\.(?:py|js))`", page))
    assert len(cited) >= 12
    missing = sorted(p for p in cited if not (root / p).is_file())
    assert not missing, f"the guide cites missing files: {missing}"
    kinds = root / "ris_planner/environment/kinds"
    source = (kinds / "base.py").read_text(encoding="utf-8")
    source += (kinds / "__init__.py").read_text(encoding="utf-8")
    # the members it names: the tables' first column and every `name(...)` call
    members = set(re.findall(r"^\| `(\w+)`", page, flags=re.M))
    members |= set(re.findall(r"`(\w+)\(", page))
    unknown = sorted(
        m for m in members if not re.search(rf"^\s*def {m}\(|^\s+{m}: ", source, flags=re.M)
    )
    assert len(members) >= 16 and not unknown, unknown
    # the toy lives only here: no code, page or doc names it
    named = [
        str(f.relative_to(root))
        for top in ("ris_planner", "api", "docs")
        for f in (root / top).rglob("*")
        if f.suffix in (".py", ".js", ".html", ".md") and NAME in f.read_text(encoding="utf-8")
    ]
    assert named == []
