"""Site data as bytes (a file's content, a request body) → a document fragment or a starting
plan document: the one entry of ``ris-planner import`` and ``POST /v1/import``, over the
parsers of :mod:`~ris_planner.io.geojson_read`, :mod:`~ris_planner.io.osm_xml`,
:mod:`~ris_planner.io.site_points` and :mod:`~ris_planner.io.dxf`.

Formats (:data:`IMPORT_FORMATS`): ``geojson`` (buildings, roads, density areas:
:func:`import_features`), ``osm`` (the same from ``.osm`` XML), ``sites`` (mounting points and
lines → candidates, walls: :func:`import_sites`), ``dxf`` (floor-plan layers → walls, prisms).

:func:`plan_from_import` makes a plan document of an import: the fragment's ``frame``,
``environment``, candidates, and its UE map as both ``tx_map`` and ``rx_map``, plus
:data:`PLAN_DEFAULTS` – a starting point for the planner page (edit counts, objective, RIS).
"""

from __future__ import annotations

import copy
import io
import json
import math
from dataclasses import dataclass, field
from typing import Any

from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import parse_json_object
from ris_planner.io import require
from ris_planner.io.dxf import LayerSpec, import_dxf
from ris_planner.io.geojson_read import import_features
from ris_planner.io.import_options import ImportOptions
from ris_planner.io.osm_xml import osm_xml_features
from ris_planner.io.site_points import import_sites
from ris_planner.model.plan_physics import PLAN_MAX_ANGLE_DEG, PLAN_PATTERN_EXPONENT

IMPORT_FORMATS = ("geojson", "osm", "sites", "dxf")
"""What :func:`import_data` reads."""

SIDELINK_SEPARATION_M = 50.0
"""The largest TX–RX separation of an imported site's sidelink pairs [m] (docs/concepts/
district.md, "The default pair model"): this project's choice for a mmWave (FR2) sidelink pair
on one street – 3GPP's V2X service requirements (TS 22.186) set ranges of tens to hundreds of
metres per use case, and at 28 GHz a RIS path leaves PEB_R ≤ 1 m only within a few tens of
metres of its RIS."""

PLAN_DEFAULTS: dict[str, Any] = {
    "pairs": {"sample": 1000, "seed": 1, "max_separation_m": SIDELINK_SEPARATION_M},
    "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
    "ris_count": [2, 3],
    "known": ["height"],
    "ris": {"pattern_exponent": PLAN_PATTERN_EXPONENT, "max_angle_deg": PLAN_MAX_ANGLE_DEG},
}
"""Fields of a plan document made by :func:`plan_from_import` (the planner's to edit): 1000
sampled sidelink pairs at most :data:`SIDELINK_SEPARATION_M` apart (along the streets when the
UE map is roads), coverage Pr(PEB_R ≤ 1 m), 2 and 3 RISs (one RIS leaves both UEs
unlocated), UE heights known (street or
floor level), and the plan's physical RIS element written out (the unit-cell pattern
q = 1.5 and the 84.26° field of view of :mod:`ris_planner.model.plan_physics`, so the planner
sees and may edit them; docs/concepts/planning-physics.md)."""

MAX_DXF_GRID_POINTS = 10_000
"""A DXF plan's UE grid is coarsened (its step doubled) until it has at most this many points."""


def parse_origin(text: str | None) -> tuple[float, ...] | None:
    """``LON,LAT[,H]`` → the origin of an import (None: the features' bounding-box centre)."""
    if text is None:
        return None
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise RisPlannerError(f"origin {text!r}: expected LON,LAT[,H] numbers") from None
    if len(vals) not in (2, 3) or not all(math.isfinite(v) for v in vals):
        raise RisPlannerError(f"origin {text!r}: expected LON,LAT[,H] finite numbers")
    return vals


def collection_origin(collection: Any) -> tuple[float, ...] | None:
    """The ``frame.origin`` a FeatureCollection carries as a top-level member (the candidate
    files of ``ris-planner sites``: their azimuths are those of that frame), else ``None``."""
    frame = collection.get("frame") if isinstance(collection, dict) else None
    origin = frame.get("origin") if isinstance(frame, dict) else None
    if (
        isinstance(origin, list)
        and len(origin) in (2, 3)
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in origin)
        and all(math.isfinite(v) for v in origin)
    ):
        return tuple(float(v) for v in origin)
    return None


@dataclass
class ImportReport:
    """What an import did: the parser's summary, and what :func:`plan_from_import` added."""

    format: str
    summary: dict[str, Any]
    defaults: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": self.format,
            **self.summary,
            "defaults_applied": self.defaults,
            "notes": [*self.summary.get("notes", []), *self.notes],
        }


def read_dxf(data: bytes, what: str = "DXF") -> Any:
    """An ``ezdxf`` document from the bytes of a DXF file (ASCII or binary; the encoding from
    its header), or a :class:`RisPlannerError` naming ``what``."""
    ezdxf = require("ezdxf")
    from ezdxf import recover

    try:
        doc, _ = recover.read(io.BytesIO(data))
    except (ezdxf.DXFStructureError, ValueError, TypeError, EOFError, UnicodeError) as exc:
        raise RisPlannerError(f"{what}: not a readable DXF file ({exc})") from None
    return doc


def _sites_of_points(
    collection: dict[str, Any], origin: tuple[float, ...], options: ImportOptions
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The Point features of a GeoJSON site as mounting points (:func:`import_sites`, each
    keeping its index in the collection for the error messages)."""
    feats = collection.get("features") or []
    blank = {"type": "Feature", "geometry": {"type": "GeometryCollection"}, "properties": {}}
    points = [
        f
        if isinstance(f, dict)
        and isinstance(f.get("geometry"), dict)
        and f["geometry"].get("type") == "Point"
        else blank
        for f in feats
    ]
    if all(p is blank for p in points):
        return {}, {}
    crs = {"crs": collection["crs"]} if "crs" in collection else {}  # converted there
    fragment, summary = import_sites(
        {"type": "FeatureCollection", **crs, "features": points}, origin, options
    )
    return fragment, {"candidates": summary.candidates}


def import_data(
    data: bytes,
    fmt: str,
    options: ImportOptions | None = None,
    origin: tuple[float, ...] | None = None,
    layers: dict[str, LayerSpec] | None = None,
    units: str | None = None,
    what: str = "input",
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(document fragment, summary) of a file's bytes in format ``fmt``; errors are
    :class:`RisPlannerError` naming ``what``, the feature or the layer.

    ``geojson``: :func:`import_features`, and its Point features as mounting points
    (:func:`import_sites`: ``azimuth_deg`` and a height required), so one file can carry a
    whole site; ``sites``: :func:`import_sites`; ``osm``: :func:`osm_xml_features` then
    :func:`import_features`; ``dxf``: :func:`import_dxf` with ``layers`` and ``units``. Without
    ``origin``, a GeoJSON collection's top-level ``frame`` (:func:`collection_origin`) gives it,
    else the features' bounding-box centre."""
    opts = options or ImportOptions()
    if fmt == "dxf":
        return import_dxf(read_dxf(data, what), layers or {}, units)
    if fmt not in IMPORT_FORMATS:
        raise RisPlannerError(f"format {fmt!r}: choose one of {', '.join(IMPORT_FORMATS)}")
    notes: list[str] = []
    if fmt == "osm":
        collection, osm_summary = osm_xml_features(io.BytesIO(data), name=what)
        notes = osm_summary.notes
    else:
        collection = parse_json_object(data, what)
        origin = origin if origin is not None else collection_origin(collection)
    if fmt == "sites":
        fragment, s = import_sites(collection, origin, opts)
        return fragment, s.to_json()
    fragment, s = import_features(collection, origin, opts)
    s.notes = notes + s.notes
    summary = s.to_json()
    if fmt == "geojson":
        frame_origin = tuple(fragment["frame"]["origin"])
        sites, counts = _sites_of_points(collection, frame_origin, opts)
        if sites.get("candidates"):
            fragment["candidates"] = sites["candidates"]
            summary["skipped"] = summary.get("skipped", 0) - counts["candidates"]
            summary["candidates"] = counts["candidates"]
            if not summary["skipped"]:
                del summary["skipped"]
    return fragment, summary


def _dxf_grid(obstacles: list[dict[str, Any]], options: ImportOptions) -> dict[str, Any] | None:
    """A UE grid over a floor plan's bounding box at ``ue_height_m``, every ``area_step_m``
    (doubled until at most :data:`MAX_DXF_GRID_POINTS` points)."""
    xy = [
        p
        for ob in obstacles
        for p in (ob.get("footprint") or [ob.get("start"), ob.get("end")])
        if p is not None
    ]
    if not xy:
        return None
    x0, x1 = min(p[0] for p in xy), max(p[0] for p in xy)
    y0, y1 = min(p[1] for p in xy), max(p[1] for p in xy)
    step = options.area_step_m
    while (math.floor((x1 - x0) / step) + 1) * (math.floor((y1 - y0) / step) + 1) > (
        MAX_DXF_GRID_POINTS
    ):
        step *= 2
    z = options.ue_height_m
    return {"grid": {"x": [x0, x1, step], "y": [y0, y1, step], "z": [z, z, 1.0]}}


def plan_from_import(
    fragment: dict[str, Any],
    fmt: str,
    summary: dict[str, Any],
    options: ImportOptions | None = None,
) -> tuple[dict[str, Any], ImportReport]:
    """A plan document from an import fragment, and the report of what was added: the UE map
    (``ue_map``, or for a DXF plan a grid over its extent) as ``tx_map`` and ``rx_map``, the
    fragment's candidates / walls / environment / frame, and :data:`PLAN_DEFAULTS`. A
    fragment without candidates or without UE positions gives a document the planner refuses
    until they are added (the report says so)."""
    opts = options or ImportOptions()
    report = ImportReport(fmt, summary)
    doc: dict[str, Any] = {"description": f"Imported site ({fmt})"}
    for key in ("license", "attribution", "frame", "environment", "candidates", "walls"):
        if key in fragment:
            doc[key] = copy.deepcopy(fragment[key])
    ue = fragment.get("ue_map")
    if ue is None and fmt == "dxf":
        ue = _dxf_grid(fragment.get("environment", {}).get("obstacles", []), opts)
        if ue is not None:
            report.defaults.append(
                f"tx_map/rx_map: a grid over the plan every {ue['grid']['x'][2]:g} m at"
                f" {opts.ue_height_m:g} m (points inside prisms are dropped by the planner)"
            )
    if ue is not None:
        doc["tx_map"] = ue
        doc["rx_map"] = copy.deepcopy(ue)
    else:
        report.notes.append("no UE positions (roads, density areas): add tx_map and rx_map")
    if "candidates" not in doc and "walls" not in doc:
        report.notes.append(
            "no candidate sites: add candidates, walls or facades (e.g. import a sites file)"
        )
    for key, value in PLAN_DEFAULTS.items():
        doc[key] = copy.deepcopy(value)
    if ue is not None and ue.get("roads"):  # UEs on the streets: the separation along them
        doc["pairs"]["separation"] = "street"
    for key in PLAN_DEFAULTS:
        report.defaults.append(f"{key}: {json.dumps(doc[key])}")  # JSON, not Python repr
    return doc, report
