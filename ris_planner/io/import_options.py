"""What the GeoJSON / OSM readers share (guide: ``docs/guides/import.md``): their options and
defaults (:class:`ImportOptions`), the report of an import (:class:`ImportSummary`), errors and
summary entries naming a feature (:class:`FeatureError`, :func:`feature_label`,
:func:`feature_entry`), length tags (:func:`parse_length`, :func:`parse_tag_length`) and the
data licence (:func:`license_of`).

A feature is named by its index, its ``id`` / ``@id`` / ``osm_id``, its ``name`` and the
lon/lat of its first position.

Licence: the collection's top-level ``license`` and ``attribution`` are copied into the
fragment; OSM data (an ``.osm`` file, or features with OSM ids such as ``way/42`` and no
licence of their own) gets :data:`OSM_LICENSE`. The exports carry it
(:mod:`ris_planner.io.gis_outputs`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from ris_planner.core.errors import DocumentFieldError, RisPlannerError

METRES_PER_LEVEL = 3.0
"""Storey height used for ``building:levels`` and ``building:min_level`` [m]."""


DEFAULT_BUILDING_HEIGHT_M = 10.0
"""Height of a building with no ``height`` and no ``building:levels`` [m] (reported)."""


DEFAULT_ROAD_STEP_M = 5.0
"""Default UE sampling step along and across imported roads [m]."""


DEFAULT_UE_HEIGHT_M = 1.5
"""Default height of imported UE positions (roads, areas) [m]."""


DEFAULT_AREA_STEP_M = 5.0
"""Default grid step inside density polygons [m]."""


DEFAULT_SITE_SPACING_M = 5.0
"""Default spacing of candidate sites along an imported mounting line [m]."""


INVALID_POLICIES = ("repair", "skip", "error")
"""What :func:`import_features` does with an invalid outline (``ImportOptions.invalid``)."""


OSM_LICENSE = "© OpenStreetMap contributors, ODbL 1.0"
"""Licence of OpenStreetMap data (https://www.openstreetmap.org/copyright)."""


_OSM_ID = re.compile(r"^(node|way|relation)/\d+$")


@dataclass
class ImportOptions:
    """Defaults of :func:`import_features` (see the module docstring)."""

    metres_per_level: float = METRES_PER_LEVEL
    default_height_m: float = DEFAULT_BUILDING_HEIGHT_M
    road_step_m: float = DEFAULT_ROAD_STEP_M
    ue_height_m: float = DEFAULT_UE_HEIGHT_M
    density_key: str = "density"
    area_step_m: float = DEFAULT_AREA_STEP_M
    site_spacing_m: float = DEFAULT_SITE_SPACING_M
    highways: tuple[str, ...] | None = None
    """Road classes to import (default: every class of :data:`HIGHWAY_WIDTH_M`)."""
    invalid: str = "repair"
    """Invalid outlines: ``repair`` | ``skip`` | ``error`` (:data:`INVALID_POLICIES`)."""
    swap_check: bool = True
    """Run the file-wide lat/lon swap test (square corners; module docstring)."""

    def __post_init__(self) -> None:
        if self.invalid not in INVALID_POLICIES:
            raise DocumentFieldError(
                "invalid", f"choose one of {', '.join(INVALID_POLICIES)}, got {self.invalid!r}"
            )


@dataclass
class ImportSummary:
    """What an import did (printed by ``ris-planner import`` on stderr). Entries of
    ``repaired``, ``skipped_invalid`` and ``tag_problems`` name the feature (``feature``
    index, ``id``, ``name``, ``lonlat`` of its first position)."""

    buildings: int = 0
    prisms: int = 0
    heights_from_levels: int = 0
    default_height: list[str] = field(default_factory=list)
    courtyards: int = 0
    """Inner rings kept open (their buildings cut into simple pieces)."""
    roads: int = 0
    roads_skipped: dict[str, int] = field(default_factory=dict)
    areas: int = 0
    area_points: int = 0
    candidates: int = 0
    walls: int = 0
    obstacle_features: int = 0
    """Features read as obstacles of the kind their properties name (an exported
    ``plan.geojson``'s obstacles)."""
    skipped: int = 0
    repaired: list[dict[str, Any]] = field(default_factory=list)
    skipped_invalid: list[dict[str, Any]] = field(default_factory=list)
    tag_problems: list[dict[str, Any]] = field(default_factory=list)
    license: str | None = None
    crs: dict[str, Any] | None = None
    """The collection's ``crs`` member and what was done with it (:func:`wgs84_collection`)."""
    warnings: list[str] = field(default_factory=list)
    """What makes the import a poor model of the site (:data:`NO_BUILDINGS_WARNING`)."""
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if v not in (0, [], {}, None)}


class FeatureError(DocumentFieldError):
    """An error in one feature of a collection: the message names the feature (index, id,
    name, lon/lat; :func:`feature_label`), ``field`` is its path in the collection
    (``features.3``), which the service's 422 lists."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(f"features.{index}", message)
        self.index = index
        self.args = (message,)  # the message already names the feature

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return type(self), (self.index, self.reason)


@contextmanager
def feature_errors(index: int) -> Iterator[None]:
    """Re-raise an error about feature ``index`` as a :class:`FeatureError`."""
    try:
        yield
    except DocumentFieldError:
        raise
    except RisPlannerError as exc:
        raise FeatureError(index, str(exc)) from None


def _first_position(coords: Any) -> list[float] | None:
    """The first [x, y] number pair of nested GeoJSON coordinates, or None."""
    while isinstance(coords, list) and coords:
        if all(isinstance(v, int | float) and not isinstance(v, bool) for v in coords[:2]):
            return [float(coords[0]), float(coords[1])] if len(coords) >= 2 else None
        coords = coords[0]
    return None


def feature_anchor(feature: Any) -> list[float] | None:
    geom = feature.get("geometry") if isinstance(feature, dict) else None
    return _first_position(geom.get("coordinates")) if isinstance(geom, dict) else None


def feature_ident(feature: Any) -> tuple[Any, Any]:
    """(id, name) of a feature as the user gave them (None when absent)."""
    props = (feature.get("properties") or {}) if isinstance(feature, dict) else {}
    props = props if isinstance(props, dict) else {}
    fid = feature.get("id") if isinstance(feature, dict) else None
    if fid is None:
        fid = props.get("@id", props.get("osm_id", props.get("id")))
    return fid, props.get("name") or None


def lonlat_text(p: list[float]) -> str:
    return f"[{p[0]:.6f}, {p[1]:.6f}]"


def feature_label(index: int, feature: Any) -> str:
    """'feature 3 (id way/42, name 'Kirjasto') at [24.949120, 60.165510]' – how errors name a
    feature (the position is its first one, as given)."""
    fid, name = feature_ident(feature)
    parts = [f"id {fid}"] if fid is not None else []
    if name:
        parts.append(f"name {name!r}")
    at = feature_anchor(feature)
    return (
        f"feature {index}"
        + (f" ({', '.join(parts)})" if parts else "")
        + (f" at {lonlat_text(at)}" if at is not None else "")
    )


def feature_entry(index: int, feature: Any, **extra: Any) -> dict[str, Any]:
    """A summary entry naming a feature: index, id, name, lon/lat of its first position."""
    fid, name = feature_ident(feature)
    at = feature_anchor(feature)
    entry: dict[str, Any] = {"feature": index}
    if fid is not None:
        entry["id"] = fid if isinstance(fid, int | str) else str(fid)
    if name:
        entry["name"] = str(name)
    if at is not None:
        entry["lonlat"] = [round(at[0], 7), round(at[1], 7)]
    return {**entry, **extra}


_NUMBER = re.compile(r"^\s*([-+]?\d+(?:[.,]\d+)?)\s*(m|meters?|metres?|ft|feet|')?\s*$", re.I)


def parse_length(value: Any) -> float | None:
    """Metres from ``12``, ``"12.5"``, ``"12 m"``, ``"40 ft"``, ``"40'"``; ``None`` if not."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value) if math.isfinite(value) else None
    if not isinstance(value, str):
        return None
    m = _NUMBER.match(value)
    if m is None:
        return None
    x = float(m.group(1).replace(",", "."))
    unit = (m.group(2) or "m").lower()
    return x * 0.3048 if unit in ("ft", "feet", "'") else x


def parse_tag_length(value: Any, positive: bool = False) -> tuple[float | None, str | None]:
    """(metres, note) of an OSM length tag: a number with an optional unit
    (:func:`parse_length`), ≥ 0 (> 0 when ``positive``); a ``;``-separated list of such
    values gives the largest with a note; anything else gives (None, why)."""
    v = parse_length(value)
    ok = v is not None and (v > 0 if positive else v >= 0)
    if ok:
        return v, None
    if isinstance(value, str) and ";" in value:
        vals = [parse_length(s) for s in value.split(";")]
        good = [x for x in vals if x is not None and (x > 0 if positive else x >= 0)]
        if good and len(good) == len(vals):
            return max(good), f"several values {value!r}: the largest, {max(good):g}, used"
    if v is not None:
        return None, f"{value!r} is not {'> 0' if positive else '≥ 0'}"
    return None, f"{value!r} is not a number with an optional unit (m, ft)"


def license_of(collection: Any) -> tuple[str | None, str | None, str | None]:
    """(license, attribution, note) of a FeatureCollection: its top-level ``license`` and
    ``attribution``; without either, :data:`OSM_LICENSE` when its features carry OSM ids
    (``way/42``, ``@id``, ``osm_id``), with a note saying so."""
    if not isinstance(collection, dict):
        return None, None, None
    lic, attr = collection.get("license"), collection.get("attribution")
    lic = str(lic) if lic not in (None, "") else None
    attr = str(attr) if attr not in (None, "") else None
    if lic is None and attr is None:
        feats = collection.get("features") or []
        osm = any(
            isinstance(f, dict)
            and (
                _OSM_ID.match(str(feature_ident(f)[0] or ""))
                or "osm_id" in (f.get("properties") or {})
            )
            for f in feats[:1000]
        )
        if osm:
            return OSM_LICENSE, None, f"license: {OSM_LICENSE!r} (features carry OpenStreetMap ids)"
    return lic, attr, None


def add_license(fragment: dict[str, Any], collection: Any, summary: ImportSummary) -> None:
    lic, attr, note = license_of(collection)
    if lic is not None:
        fragment["license"] = lic
        summary.license = lic
    if attr is not None:
        fragment["attribution"] = attr
    if note is not None:
        summary.notes.append(note)
