"""Candidate RIS sites generated from an imported site: facade mounts on the buildings and poles
along the roads, kept only where they see a UE point (``ris-planner sites``, ``POST /v1/sites``;
docs/guides/candidates.md).

The input is a site in WGS84: a GeoJSON FeatureCollection of buildings and roads (imported
first with :func:`~ris_planner.io.geojson_read.import_features`; one in a projected CRS
named by a ``crs`` member is converted first, :func:`~ris_planner.io.crs.
wgs84_collection`, and a note says so), or an imported document with
a ``frame`` (``environment`` prisms and a ``ue_map`` – or a plan document's ``tx_map`` /
``rx_map``). The output is an editable GeoJSON FeatureCollection of Point features in WGS84 that
:func:`~ris_planner.io.site_points.import_sites` (``ris-planner import sites``, the plan
document's ``candidates``) takes as it is.

Rules (:class:`CandidateOptions` holds every default):

* Facades: every footprint edge of every prism is a facade
(:func:`~ris_planner.planning.inputs.sites.
  facade_walls`: the outward normal from the footprint's winding, moved ``offset_m`` out of the
  wall). ``corner_clearance_m`` is cut off both ends; an edge not longer than twice the
  clearance carries nothing; the rest carries n = max(1, round(usable / spacing_m)) sites at
  the centres of n equal parts (:func:`~ris_planner.planning.inputs.sites.wall_poses`), at every
  mounting height (above the building's base) strictly below the building's top and every
  tilt; the RIS faces the outward normal (``azimuth_deg``).
* Poles: along each road centre line (length ℓ), n = round(ℓ / pole_spacing_m) poles at the
  centres of n equal parts of the line (none on a road shorter than half a spacing), standing
  ``pole_setback_m`` beyond the road's edge, alternately on the left and the right side (the
  staggered layout of street lights), at ``pole_height_m`` above the ground (z = 0 of the
  frame), facing across the road (towards its centre line), so the whole carriageway is in
  front of them.
* A site whose RIS centre lies more than 1 cm inside a prism (a party wall shared with the
  next building, a pole beside a narrow road) is dropped (:meth:`Scene.inside`).
* A site is kept only when it serves at least one UE point (the map's points, outside the
  buildings): the point is within its field of view (``max_angle_deg`` from the normal) and
  the leg is not blocked (:func:`~ris_planner.planning.scoring.visibility.serve_matrix`, batched
  over
  every site and point; the rules of :mod:`ris_planner.environment.scene`). ``sees_points``
  counts them. The default field of view is the plan's
  (:data:`~ris_planner.model.plan_physics.PLAN_MAX_ANGLE_DEG`, 84.26°, what a plan document
  and ``ris-planner import --plan`` use), so a kept site sees its points in the plan too.
* Above ``max_candidates``, the sites that serve the most points are kept (ties: input order).

``azimuth_deg`` is the compass direction the RIS faces in the output's ``frame`` (the local
transverse Mercator frame of ``frame.origin``; it differs from true north by the meridian
convergence, ≈ Δlon · sin(lat): 0.002° 100 m from the origin at 60° N), which is how
:func:`~ris_planner.io.site_points.import_sites` reads it with the same origin; ``height_m``
is the RIS centre's height above ``frame.origin``'s height.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import ConfigDict, Field, ValidationError, field_validator

from ris_planner.core.document import DocumentModel
from ris_planner.core.errors import DocumentFieldError, LimitExceededError, RisPlannerError
from ris_planner.core.io_json import validation_problems
from ris_planner.environment import Scene
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment
from ris_planner.io import require
from ris_planner.io.crs import crs_note, wgs84_collection
from ris_planner.io.frames import WGS84, Frame, to_local
from ris_planner.io.geojson_read import NO_BUILDINGS_WARNING, import_features
from ris_planner.io.import_options import ImportOptions
from ris_planner.model.limits import MAX_MAP_POINTS, MAX_SITES, Sizes, check_sizes, count
from ris_planner.model.plan import Facades, RISDefaults, UEMap, WallSites, map_points
from ris_planner.model.plan_physics import PLAN_MAX_ANGLE_DEG
from ris_planner.model.scenario import RIS
from ris_planner.planning.inputs.sites import Site, facade_walls, wall_poses
from ris_planner.planning.inputs.ue_maps import build_map
from ris_planner.planning.scoring.visibility import (
    SitesInsideError,
    local_position_text,
    serve_matrix,
)

FloatArray = NDArray[np.float64]

Kind = Literal["facade", "pole"]

KINDS: tuple[Kind, ...] = ("facade", "pole")

Row = tuple[list[float], float, float, str, int | None, int | None, int | None]
"""One generated site: (position, yaw, tilt [rad], name, obstacle, facade edge, road)."""

DEFAULT_POLE_ROAD_CLASSES: tuple[str, ...] = (
    "trunk",
    "primary",
    "secondary",
    "tertiary",
    "unclassified",
    "residential",
    "living_street",
    "pedestrian",
)
"""OSM ``highway`` classes that carry poles by default: streets (not motorways, service ways,
footways, cycleways, paths or steps, whose many short pieces would give poles in yards)."""

MAX_CANDIDATES_LIMIT = 10_000
"""The largest ``max_candidates``: the plan document's limit on explicit candidates."""

MAX_VISIBILITY_LEGS = 50_000_000
"""Site × UE point legs one generation may test (≈ 1 min of the visibility engine; refused
before any test above it)."""

SERVE_BATCH = 4_000_000
"""Site × point entries of one :func:`serve_matrix` call (bounds its [S, M] arrays)."""

ATTRIBUTION_KEYS = ("license", "licence", "attribution", "copyright", "source")
"""Top-level members of the input carried to the output (ODbL attribution of OSM data)."""


def _schema_defaults(schema: dict[str, Any], model: type[DocumentModel]) -> None:
    """Every option's default in the JSON schema, the lists too (pydantic leaves a factory's
    value out): the OpenAPI document then states them all, and the planner page fills its
    generation form from it, so the page starts from the defaults ``ris-planner sites`` uses."""
    defaults = model().model_dump(mode="json")
    for name, prop in schema.get("properties", {}).items():
        prop.setdefault("default", defaults[name])


class CandidateOptions(DocumentModel):
    """How candidate sites are laid out (module docstring; docs/guides/candidates.md)."""

    model_config = ConfigDict(json_schema_extra=_schema_defaults)

    kinds: list[Kind] = Field(
        default_factory=lambda: list(KINDS),
        min_length=1,
        max_length=2,
        description="Which sites to generate: facade (on building walls), pole (along roads)",
    )
    spacing_m: float = Field(
        10.0, gt=0, le=10_000, description="Distance between facade sites along a wall [m]"
    )
    heights_m: list[float] = Field(
        default_factory=lambda: [4.0, 8.0],
        min_length=1,
        max_length=20,
        description="Mounting heights of the RIS centre above the building's base [m]; heights"
        " not strictly below the building's top are skipped",
    )
    tilts_deg: list[float] = Field(
        default_factory=lambda: [0.0],
        min_length=1,
        max_length=20,
        description="Downward tilts (positive: face downwards) tried at every site [deg]",
    )
    corner_clearance_m: float = Field(
        2.0, ge=0, le=1000, description="Length kept free at both ends of each facade [m]"
    )
    offset_m: float = Field(
        0.05,
        ge=0,
        le=10,
        description="Distance of the RIS centre in front of the wall [m] (outside the prism)",
    )
    max_angle_deg: float = Field(
        PLAN_MAX_ANGLE_DEG,
        gt=0,
        le=180,
        description="Field of view used for 'sees a UE point' [deg from the normal]; default"
        " the plan's ris.max_angle_deg default (84.26°: cos θ > 0.1, model/plan_physics.py),"
        " which 'ris-planner import --plan' writes too",
    )
    max_candidates: int = Field(
        1000,
        ge=1,
        le=MAX_CANDIDATES_LIMIT,
        description="At most this many sites: those serving the most UE points are kept",
    )
    pole_spacing_m: float = Field(
        25.0, gt=0, le=10_000, description="Distance between poles along a road [m]"
    )
    pole_height_m: float = Field(
        6.0, gt=0, le=1000, description="Height of a pole's RIS centre above the ground [m]"
    )
    pole_setback_m: float = Field(
        0.5, ge=0, le=100, description="Distance of a pole beyond the road's edge [m]"
    )
    road_classes: list[str] | None = Field(
        default_factory=lambda: list(DEFAULT_POLE_ROAD_CLASSES),
        max_length=100,
        description="OSM highway classes that carry poles (a GeoJSON site; null: every"
        " imported road); an imported document's roads carry no class: all carry poles",
    )
    swap_check: bool = Field(
        True,
        description="Run the import's file-wide lat/lon swap test on a GeoJSON site (building"
        " corners square only when read as [lat, lon]): off for a site that fails it but is"
        " right, as ris-planner import --no-swap-check; the per-feature checks always run",
    )

    @field_validator("kinds")
    @classmethod
    def _unique_kinds(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError(f"kinds lists a kind twice: {v}")
        return v

    @field_validator("heights_m")
    @classmethod
    def _check_heights(cls, v: list[float]) -> list[float]:
        if not all(math.isfinite(h) and 0 <= h <= 1000 for h in v):
            raise ValueError(f"heights_m must lie within [0, 1000] m, got {v}")
        return v

    @field_validator("tilts_deg")
    @classmethod
    def _check_tilts(cls, v: list[float]) -> list[float]:
        if not all(math.isfinite(t) and abs(t) <= 90 for t in v):
            raise ValueError(f"tilts_deg must lie within ±90°, got {v}")
        return v


@dataclass
class CandidateSummary:
    """What a generation did (``ris-planner sites`` prints it on stderr; ``POST /v1/sites``
    returns it as ``summary``)."""

    candidates: int = 0
    by_kind: dict[str, int] = field(default_factory=dict)
    buildings: int = 0
    roads: int = 0
    ue_points: int = 0
    ue_points_inside: int = 0
    generated: int = 0
    dropped_inside: int = 0
    dropped_unseen: int = 0
    dropped_max_candidates: int = 0
    buildings_without_candidates: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class _Sites:
    """Generated sites before the visibility filter (local metres)."""

    position: FloatArray  # [S, 3]
    yaw: FloatArray  # [S]
    tilt: FloatArray  # [S] radians
    kind: list[str]
    name: list[str]
    obstacle: list[int | None]
    facade: list[int | None]
    road: list[int | None]

    @classmethod
    def of_rows(cls, rows: list[Row]) -> _Sites:
        return cls(
            np.array([r[0] for r in rows], dtype=float).reshape(-1, 3),
            np.array([r[1] for r in rows], dtype=float),
            np.array([r[2] for r in rows], dtype=float),
            ["facade" if r[4] is not None else "pole" for r in rows],
            _unique_names([r[3] for r in rows]),
            [r[4] for r in rows],
            [r[5] for r in rows],
            [r[6] for r in rows],
        )

    def take(self, idx: NDArray[np.int_]) -> _Sites:
        """The sites ``idx``, in that order."""
        i = idx.tolist()
        return _Sites(
            self.position[idx],
            self.yaw[idx],
            self.tilt[idx],
            [self.kind[k] for k in i],
            [self.name[k] for k in i],
            [self.obstacle[k] for k in i],
            [self.facade[k] for k in i],
            [self.road[k] for k in i],
        )


@dataclass(frozen=True)
class _Site:
    """The parsed site in local metres."""

    frame: Frame
    environment: Environment
    ue_points: FloatArray  # [M, 3] distinct, outside the prisms
    ue_inside: int
    roads: list[tuple[FloatArray, float]]  # pole roads: centre line [n, 2], width
    carried: dict[str, Any]
    notes: list[str]


def _maps_of(doc: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """(key, map) of the document's distinct UE maps (``ue_map``, ``tx_map``, ``rx_map``)."""
    maps: list[tuple[str, dict[str, Any]]] = []
    for key in ("ue_map", "tx_map", "rx_map"):
        m = doc.get(key)
        if isinstance(m, dict) and all(m != other for _, other in maps):
            maps.append((key, m))
    return maps


@contextmanager
def _site_field(prefix: str, local: str) -> Iterator[None]:
    """Errors about a part of the site named by its path in the input: ``site.<prefix>…``
    (the local document's path ``local`` replaced by it)."""
    try:
        yield
    except ValidationError as exc:
        raise DocumentFieldError(f"site.{prefix}", "; ".join(validation_problems(exc))) from None
    except DocumentFieldError as exc:
        where = exc.field.replace(local, prefix, 1) if exc.field.startswith(local) else exc.field
        raise DocumentFieldError(f"site.{where}", exc.reason) from None


def _local_map(frame_spec: Any, ue_map: dict[str, Any], key: str) -> UEMap:
    """A UE map of the site's frame → the validated local map (its points counted first)."""
    with _site_field(key, "tx_map"):
        local, _ = to_local({"frame": frame_spec, "tx_map": ue_map})
        spec = UEMap.model_validate(local["tx_map"])
    check_sizes(Sizes(tx_points=map_points(spec)), memory_mb=None)
    return spec


def _pole_roads(
    collection: dict[str, Any], origin: tuple[float, ...], classes: list[str] | None
) -> list[dict[str, Any]]:
    """The roads of a GeoJSON site that carry poles (their ``highway`` class is chosen), as an
    imported ``ue_map`` roads list in the site's frame."""
    if classes is None:
        feats = collection["features"]
    else:
        feats = [
            f
            for f in collection["features"]
            if isinstance(f, dict)
            and isinstance(f.get("geometry"), dict)
            and f["geometry"].get("type") in ("LineString", "MultiLineString")
            and str((f.get("properties") or {}).get("highway")) in classes
        ]
    if not feats:
        return []
    fragment, _ = import_features({"type": "FeatureCollection", "features": feats}, origin)
    roads: list[dict[str, Any]] = fragment.get("ue_map", {}).get("roads", [])
    return roads


def _parse_site(site: Any, options: CandidateOptions) -> _Site:
    """A GeoJSON site or an imported document → frame, prisms, UE points and pole roads."""
    if not isinstance(site, dict):
        raise RisPlannerError("site: expected a GeoJSON FeatureCollection or an imported document")
    carried = {k: site[k] for k in ATTRIBUTION_KEYS if isinstance(site.get(k), str)}
    notes: list[str] = []
    if site.get("type") == "FeatureCollection":
        with _site_field("features", "features"):
            site, crs = wgs84_collection(site)  # a crs member: converted once, for both
            notes += [crs_note(crs)] if crs is not None else []
            doc, _ = import_features(site, options=ImportOptions(swap_check=options.swap_check))
            origin = tuple(doc["frame"]["origin"])
            wanted = "pole" in options.kinds
            pole_roads = _pole_roads(site, origin, options.road_classes) if wanted else []
    elif "frame" in site:
        doc = site
        distinct: dict[str, Any] = {}  # tx_map and rx_map of a plan document repeat the roads
        for _, m in _maps_of(doc):
            roads = m.get("roads")
            for r in roads if isinstance(roads, list) else []:
                distinct.setdefault(json.dumps(r, sort_keys=True), r)
        pole_roads = list(distinct.values())
        if "pole" in options.kinds and options.road_classes != list(DEFAULT_POLE_ROAD_CLASSES):
            notes.append(
                "road_classes apply to a GeoJSON site only: an imported document's roads"
                " carry no class, every road carries poles"
            )
    else:
        raise RisPlannerError(
            "site: expected a GeoJSON FeatureCollection (WGS84) or an imported document with a"
            " frame (the output of ris-planner import)"
        )
    frame_spec = doc["frame"]
    with _site_field("environment", "environment"):
        env_doc = {"frame": frame_spec, "environment": doc.get("environment") or {}}
        env_local, frame = to_local(env_doc)
        environment = Environment.model_validate(env_local["environment"])
    assert frame is not None
    if not environment.obstacles:
        notes.append(NO_BUILDINGS_WARNING)
    maps = _maps_of(doc)
    if not maps:
        raise RisPlannerError(
            "site: no UE positions (roads or density areas; ue_map, tx_map or rx_map): a"
            " candidate is kept only where it sees one"
        )
    parts = [build_map(_local_map(frame_spec, m, key), f"site.{key}").points for key, m in maps]
    points = np.unique(np.concatenate(parts), axis=0)
    if len(points) > MAX_MAP_POINTS:
        raise LimitExceededError(
            f"the site has {len(points)} UE points, above the limit of {MAX_MAP_POINTS}",
            MAX_MAP_POINTS,
        )
    inside = Scene.from_environment(environment).inside(points) >= 0
    roads = []
    if pole_roads:
        local = _local_map(frame_spec, {"roads": pole_roads}, "roads")
        assert local.roads is not None
        roads = [(np.asarray(r.points, dtype=float), float(r.width_m)) for r in local.roads]
    return _Site(
        frame,
        environment,
        points[~inside],
        int(np.count_nonzero(inside)),
        roads,
        carried,
        notes,
    )


def _label_index(label: str) -> int:
    """12 of 'B12 (name)'."""
    return int(label[1:].split()[0])


def _label(environment: Environment, k: int) -> str:
    name = environment.obstacles[k].name
    return f"B{k} ({name})" if name else f"B{k}"


def _facade_heights(prism: Prism, options: CandidateOptions) -> list[float]:
    """The mounting heights (above the base) strictly below the prism's top."""
    return [h for h in options.heights_m if prism.base_m + h < prism.top_m]


def _facade_counts(prism: Prism, options: CandidateOptions) -> NDArray[np.int_]:
    """Sites along each footprint edge: max(1, round((ℓ − 2c) / spacing)) for ℓ > 2c, else 0
    (as :func:`wall_poses` lays out the clipped wall)."""
    v = prism.vertices
    lengths = np.hypot(*(np.roll(v, -1, axis=0) - v).T)
    usable = lengths - 2 * options.corner_clearance_m
    n = np.maximum(1.0, np.round(np.minimum(usable / options.spacing_m, 1e9)))
    return np.where(usable > 0, n, 0.0).astype(np.int64)


def estimate_sites(site: _Site, options: CandidateOptions) -> int:
    """How many sites the layout generates before any filter (arithmetic only)."""
    total = 0
    tilts = len(options.tilts_deg)
    if "facade" in options.kinds:
        for ob in site.environment.obstacles:
            if isinstance(ob, Prism):
                heights = len(_facade_heights(ob, options))
                total += int(_facade_counts(ob, options).sum()) * heights * tilts
    if "pole" in options.kinds:
        for line, _ in site.roads:
            length = float(np.hypot(*np.diff(line, axis=0).T).sum())
            total += count(length / options.pole_spacing_m + 0.5) * tilts
    return total


def _facade_sites(site: _Site, options: CandidateOptions, summary: CandidateSummary) -> list[Row]:
    """(position, yaw, tilt, name, obstacle, facade, road) of every facade site: each edge a
    :func:`facade_walls` wall, clipped by the corner clearance, laid out by :func:`wall_poses`."""
    out: list[Row] = []
    tilts = [math.radians(t) for t in options.tilts_deg]
    c = options.corner_clearance_m
    for k, ob in enumerate(site.environment.obstacles):
        if not isinstance(ob, Prism):
            continue
        summary.buildings += 1
        heights = _facade_heights(ob, options)
        if not heights:
            summary.buildings_without_candidates[_label(site.environment, k)] = (
                f"{ob.height_m:g} m tall: no mounting height below its top"
            )
            continue
        fac = Facades(
            of=[ob.name or f"obstacle {k}"],
            heights_m=heights,
            spacing_m=options.spacing_m,
            tilts_rad=tilts,
            offset_m=options.offset_m,
        )
        counts = _facade_counts(ob, options)
        if not counts.any():
            summary.buildings_without_candidates[_label(site.environment, k)] = (
                f"every facade is at most 2 × {c:g} m (corner clearance) long"
            )
            continue
        per_point = len(heights) * len(tilts)
        for e, wall in enumerate(facade_walls(fac, ob)):
            if counts[e] == 0:
                continue
            a, b = np.asarray(wall.start), np.asarray(wall.end)
            u = (b - a) / float(np.hypot(*(b - a)))
            clipped = WallSites(
                start=(a + c * u).tolist(),
                end=(b - c * u).tolist(),
                side=wall.side,
                heights_m=wall.heights_m,
                spacing_m=wall.spacing_m,
                tilts_rad=wall.tilts_rad,
            )
            poses = wall_poses(clipped)
            assert len(poses) == counts[e] * per_point
            for i, (pos, ori, _) in enumerate(poses):
                h = heights[(i // len(tilts)) % len(heights)]
                name = f"B{k}-f{e}-{i // per_point}-h{h:g}"
                if len(tilts) > 1:
                    name += f"-t{options.tilts_deg[i % len(tilts)]:g}"
                out.append((pos, ori[0], ori[1], name, k, e, None))
    return out


def _along(line: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Points [K, 2] at arc lengths s [K] of a polyline [n, 2], and the unit tangents there."""
    seg = np.diff(line, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    keep = length > 0
    seg, length, start = seg[keep], length[keep], line[:-1][keep]
    cum = np.concatenate([[0.0], np.cumsum(length)])
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(length) - 1)
    t = seg[j] / length[j, None]
    return start[j] + (s - cum[j])[:, None] * t, t


def _pole_sites(site: _Site, options: CandidateOptions, summary: CandidateSummary) -> list[Row]:
    """(position, yaw, tilt, name, obstacle, facade, road) of every pole (module docstring)."""
    out: list[Row] = []
    short = 0
    for r, (line, width) in enumerate(site.roads):
        summary.roads += 1
        length = float(np.hypot(*np.diff(line, axis=0).T).sum())
        n = count(length / options.pole_spacing_m + 0.5)
        if n == 0:
            short += 1
            continue
        s = np.asarray((np.arange(n) + 0.5) * (length / n), dtype=float)
        centre, t = _along(line, s)
        left = np.column_stack([-t[:, 1], t[:, 0]])
        side = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]
        xy = centre + side * (width / 2 + options.pole_setback_m) * left
        facing = -side * left
        yaw = np.arctan2(facing[:, 1], facing[:, 0])
        for j in range(n):
            for tilt_deg in options.tilts_deg:
                name = f"R{r}-p{j}" + (f"-t{tilt_deg:g}" if len(options.tilts_deg) > 1 else "")
                pos = [float(xy[j, 0]), float(xy[j, 1]), options.pole_height_m]
                out.append((pos, float(yaw[j]), math.radians(tilt_deg), name, None, None, r))
    if short:
        summary.notes.append(
            f"{short} road piece(s) shorter than half the pole spacing"
            f" ({options.pole_spacing_m / 2:g} m): no pole"
        )
    return out


def _serves(site: _Site, sites: _Sites, options: CandidateOptions) -> NDArray[np.int_]:
    """[S] UE points each site serves (field of view and a clear leg), in batches."""
    grid = RISDefaults(max_angle_deg=options.max_angle_deg).model_dump()
    scene = Scene.from_environment(site.environment)
    pts = site.ue_points
    counts = np.zeros(len(sites.name), dtype=int)
    if len(pts) == 0:
        return counts
    batch = max(1, SERVE_BATCH // len(pts))
    for lo in range(0, len(sites.name), batch):
        chunk = [
            Site(
                RIS(
                    position=sites.position[i].tolist(),
                    orientation=[float(sites.yaw[i]), float(sites.tilt[i]), 0.0],
                    **grid,
                ),
                sites.name[i],
            )
            for i in range(lo, min(lo + batch, len(sites.name)))
        ]
        counts[lo : lo + len(chunk)] = serve_matrix(scene, chunk, pts).sum(axis=1)
    return counts


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for n in names:
        k = seen.get(n, 0)
        seen[n] = k + 1
        out.append(n if k == 0 else f"{n}~{k}")
    return out


def azimuth_of_yaw(yaw: FloatArray) -> FloatArray:
    """Compass azimuth [deg, 0–360) (clockwise from north) of engine yaws (radians from east,
    counter-clockwise): the inverse of :func:`~ris_planner.io.site_points.yaw_from_azimuth`."""
    return np.asarray(np.mod(90.0 - np.degrees(yaw), 360.0))


def candidate_sites(
    site: Any,
    options: CandidateOptions | None = None,
    *,
    max_legs: int = MAX_VISIBILITY_LEGS,
) -> tuple[dict[str, Any], CandidateSummary]:
    """(the candidate FeatureCollection, the summary) of a site (module docstring).

    ``max_legs`` bounds the site × UE point legs, checked on the layout's arithmetic before any
    site is built or tested (:class:`LimitExceededError`): the visibility engine's uniform grid
    makes a leg's cost grow with the cells it crosses, not with the site's obstacle edges, so
    the legs are what drive the time (a 45-building OSM cut, 2.4 M legs × 833 edges: about 3 s).
    Bad input raises :class:`RisPlannerError` naming the feature or field."""
    opts = options or CandidateOptions()
    summary = CandidateSummary()
    parsed = _parse_site(site, opts)
    summary.notes += parsed.notes
    summary.ue_points = len(parsed.ue_points)
    summary.ue_points_inside = parsed.ue_inside
    raw = estimate_sites(parsed, opts)
    if raw > MAX_SITES:
        raise LimitExceededError(
            f"the layout gives {raw} sites before the visibility filter, above the limit of"
            f" {MAX_SITES}; use a larger spacing_m / pole_spacing_m or fewer heights or tilts",
            MAX_SITES,
        )
    legs = raw * len(parsed.ue_points)
    if legs > max_legs:
        raise LimitExceededError(
            f"{raw} sites × {len(parsed.ue_points)} UE points = {legs} visibility legs, above"
            f" the limit of {max_legs}; use a larger spacing or a coarser UE map",
            max_legs,
        )
    rows: list[Row] = []
    if "facade" in opts.kinds:
        rows += _facade_sites(parsed, opts, summary)
    if "pole" in opts.kinds:
        rows += _pole_sites(parsed, opts, summary)
    summary.generated = len(rows)
    sites = _Sites.of_rows(rows)
    outside = Scene.from_environment(parsed.environment).inside(sites.position) < 0
    summary.dropped_inside = int(np.count_nonzero(~outside))
    sees = np.zeros(len(rows), dtype=int)
    idx = np.nonzero(outside)[0]
    sees[idx] = _serves(parsed, sites.take(idx), opts)
    seen = outside & (sees > 0)
    summary.dropped_unseen = int(np.count_nonzero(outside & (sees == 0)))
    keep = np.nonzero(seen)[0]
    if len(keep) > opts.max_candidates:
        order = keep[np.argsort(-sees[keep], kind="stable")]
        keep = np.sort(order[: opts.max_candidates])
        summary.dropped_max_candidates = int(np.count_nonzero(seen)) - len(keep)
    _reasons(summary, parsed, sites, outside, sees, set(keep.tolist()))
    kept = sites.take(keep)
    summary.candidates = len(keep)
    summary.by_kind = {k: kept.kind.count(k) for k in KINDS if k in kept.kind}
    return _collection(parsed, kept, sees[keep]), summary


def _reasons(
    summary: CandidateSummary,
    site: _Site,
    sites: _Sites,
    outside: NDArray[np.bool_],
    sees: NDArray[np.int_],
    kept: set[int],
) -> None:
    """Why each building with generated sites has none left."""
    by_building: dict[int, list[int]] = {}
    for i, k in enumerate(sites.obstacle):
        if k is not None:
            by_building.setdefault(k, []).append(i)
    for k, rows in by_building.items():
        if any(i in kept for i in rows):
            continue
        if not any(outside[i] for i in rows):
            why = "every facade site lies inside another building (shared walls)"
        elif not any(outside[i] and sees[i] > 0 for i in rows):
            why = "no facade site sees a UE point (facing a blocked or empty side)"
        else:
            why = "its sites see fewer UE points than the max_candidates kept"
        summary.buildings_without_candidates[_label(site.environment, k)] = why
    summary.buildings_without_candidates = dict(
        sorted(summary.buildings_without_candidates.items(), key=lambda kv: _label_index(kv[0]))
    )


def _collection(site: _Site, sites: _Sites, sees: NDArray[np.int_]) -> dict[str, Any]:
    """The candidates file of the kept sites (:func:`candidates_geojson`, full precision)."""
    obstacles = site.environment.obstacles
    cands = [
        {
            "position": sites.position[j].tolist(),
            "orientation": [float(sites.yaw[j]), float(sites.tilt[j]), 0.0],
            "name": sites.name[j],
        }
        for j in range(len(sites.name))
    ]
    props = [
        {
            "kind": sites.kind[j],
            "building": None if k is None else (obstacles[k].name or f"obstacle {k}"),
            "obstacle": k,
            "facade": sites.facade[j],
            "road": sites.road[j],
            "sees_points": int(sees[j]),
        }
        for j, k in enumerate(sites.obstacle)
    ]
    return candidates_geojson(site.frame, cands, site.carried, props)


SITE_PROPERTIES = ("kind", "building", "obstacle", "facade", "road", "sees_points")
"""What the generator says of each site beside its pose (``kind``: facade | pole; the
``building`` and ``obstacle`` index it is mounted on, its ``facade`` edge or ``road``; the UE
points it ``sees_points``): kept in a candidates file as long as they describe the site."""

POSE_PROPERTIES = ("name", "azimuth_deg", "tilt_deg", "roll_deg", "height_m", "cost")
"""The properties a candidates file derives from a candidate itself (never from ``properties``)."""


def candidates_geojson(
    frame: Frame,
    candidates: Sequence[Mapping[str, Any]],
    members: Mapping[str, str] | None = None,
    properties: Sequence[Mapping[str, Any] | None] | None = None,
) -> dict[str, Any]:
    """The candidates file: the one writer of ``ris-planner sites``, ``POST /v1/sites`` and the
    planner page's ``candidates.geojson`` (``POST /v1/candidates/geojson``), so every route
    writes the same document for the same candidates.

    ``candidates`` are plan candidates in the local metres of ``frame`` (``position`` [x, y,
    z], ``orientation`` [yaw, pitch, roll] in radians, optional ``name`` and ``cost``). The
    answer is a GeoJSON FeatureCollection: the licence and attribution ``members`` at the top
    (:data:`ATTRIBUTION_KEYS`), ``frame`` = ``{"origin": [lon, lat, h]}`` – the frame that
    ``azimuth_deg`` and ``height_m`` refer to, which the import of the file takes as its own
    (:func:`~ris_planner.io.site_import.collection_origin`), so it reads the same local poses
    back – and one Point per candidate at [lon, lat, h] (WGS84; h = z + the origin's height)
    with ``name``, the entries of ``properties[i]`` (the generator's :data:`SITE_PROPERTIES`;
    never one of :data:`POSE_PROPERTIES`), ``azimuth_deg`` (compass, clockwise from north, in
    the frame), ``tilt_deg`` (downwards), ``height_m`` (z above the origin's height), and
    ``roll_deg`` and ``cost`` where they are not 0."""
    if properties is not None and len(properties) != len(candidates):
        raise RisPlannerError(
            f"{len(properties)} property sets for {len(candidates)} candidates: give one per"
            " candidate (null for none)"
        )
    n = len(candidates)
    pos = np.array([c["position"] for c in candidates], dtype=float).reshape(n, 3)
    ori = np.array(
        [c.get("orientation") or [0.0, 0.0, 0.0] for c in candidates], dtype=float
    ).reshape(n, 3)
    lonlath = frame.to_geographic(pos).reshape(n, 3) if n else pos
    azimuth = azimuth_of_yaw(ori[:, 0])
    features = []
    for j, c in enumerate(candidates):
        props: dict[str, Any] = {} if c.get("name") is None else {"name": str(c["name"])}
        extra = (properties[j] if properties is not None else None) or {}
        props.update((k, v) for k, v in extra.items() if k not in POSE_PROPERTIES)
        props["azimuth_deg"] = float(azimuth[j])
        props["tilt_deg"] = math.degrees(float(ori[j, 1]))
        if ori[j, 2] != 0:
            props["roll_deg"] = math.degrees(float(ori[j, 2]))
        props["height_m"] = float(pos[j, 2])
        if c.get("cost"):
            props["cost"] = float(c["cost"])
        geometry = {"type": "Point", "coordinates": lonlath[j].tolist()}
        features.append({"type": "Feature", "properties": props, "geometry": geometry})
    return {
        "type": "FeatureCollection",
        **{k: str(v) for k, v in (members or {}).items() if k in ATTRIBUTION_KEYS},
        "frame": frame.to_json(),
        "features": features,
    }


def document_positions(frame: Frame, points: Any) -> FloatArray:
    """Local points [N, 3] → the coordinates of a document with ``frame`` (the inverse of
    :func:`~ris_planner.io.frames.to_local` for positions): WGS84 [lon, lat, h] for a WGS84
    frame (:meth:`~ris_planner.io.frames.Frame.to_geographic`), the CRS's [x, y, h] for a
    projected one; heights in the frame's datum (z + the origin's height)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if frame.source_crs == WGS84:
        return np.asarray(frame.to_geographic(pts))
    pyproj = require("pyproj")
    t = pyproj.Transformer.from_crs(frame.proj4, frame.source_crs, always_xy=True)
    x, y = t.transform(pts[:, 0], pts[:, 1], errcheck=True)
    return np.column_stack([x, y, pts[:, 2] + frame.origin[2]])


def generate_candidates(site: Any, options: CandidateOptions | None = None) -> dict[str, Any]:
    """The candidate FeatureCollection of a site (:func:`candidate_sites` without the
    summary): Point features with ``name``, ``kind``, ``azimuth_deg``, ``tilt_deg``,
    ``height_m``, ``building``, ``sees_points``; top-level ``frame`` and the input's
    licence/attribution."""
    return candidate_sites(site, options)[0]


def position_text(frame: Frame | None, position: Any) -> str:
    """A local position as the document states it: ``[lon, lat, h] = [24.9487123, 60.1651234,
    6.00]`` (WGS84 degrees to 1e-7°, about 1 cm; heights in the frame's datum) with a WGS84
    frame, ``[x, y, h] = [385123.45, 6672123.45, 6.00] (EPSG:3067)`` with a projected one, the
    local metres without a frame."""
    if frame is None:
        return local_position_text(tuple(float(v) for v in position))  # type: ignore[arg-type]
    p = document_positions(frame, [position])[0]
    if frame.source_crs == WGS84:
        return f"[lon, lat, h] = [{p[0]:.7f}, {p[1]:.7f}, {p[2]:.2f}]"
    crs = frame.source_crs if len(frame.source_crs) <= 40 else "the document's CRS"
    return f"[x, y, h] = [{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}] ({crs})"


@contextmanager
def in_document_coordinates(frame: Frame | None) -> Iterator[None]:
    """Errors that place candidate sites (:class:`~ris_planner.planning.scoring.visibility.
    SitesInsideError`: RIS centres inside buildings) restated in the coordinates of the
    document as given (:func:`position_text`): the planning stages work in local metres, the
    boundary that converted the document (``ris-planner plan``, a job, ``POST
    /v1/plans/validate``) knows its frame."""
    try:
        yield
    except SitesInsideError as exc:
        if frame is None:
            raise
        raise exc.at(tuple(position_text(frame, s.position) for s in exc.sites)) from None


__all__ = [
    "DEFAULT_POLE_ROAD_CLASSES",
    "SITE_PROPERTIES",
    "CandidateOptions",
    "CandidateSummary",
    "azimuth_of_yaw",
    "candidate_sites",
    "candidates_geojson",
    "document_positions",
    "generate_candidates",
    "in_document_coordinates",
    "position_text",
]
