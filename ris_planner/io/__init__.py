"""Real sites in, GIS out: geographic frames, GeoJSON / OSM / DXF import, GeoJSON / GeoTIFF /
CSV export (layering: above :mod:`ris_planner.planning`; the engine never imports
this package).

* :mod:`ris_planner.io.frames` – ``frame`` of a document (WGS84 lon/lat or a projected CRS)
  ↔ the local east-north-up metres the engine works in (:func:`to_local`, :class:`Frame`).
* :mod:`ris_planner.io.geojson_import` – buildings → prisms, roads → UE roads, density areas
  → weighted UE points, mounting points / lines → candidates (GeoJSON and ``.osm`` XML).
* :mod:`ris_planner.io.dxf_import` – DXF floor plans → walls and prisms.
* :mod:`ris_planner.io.export` – ``plan.geojson``, ``heatmap.tif``, ``points.csv``.
* :mod:`ris_planner.io.geoplan` – a document as given → plan.json, PNGs and GIS files (the one
  path of ``ris-planner plan --out`` and the service's plan jobs).
* :mod:`ris_planner.io.site_import` – a file's bytes → an import fragment or a starting plan
  document (``ris-planner import`` and ``POST /v1/import``).

The GIS libraries (pyproj, shapely, rasterio, ezdxf) are the optional extra ``gis``
(``pip install 'ris_planner[gis]'``); :func:`require` turns a missing one into a clear error.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from ris_planner.core.errors import RisPlannerError


class MissingExtraError(RisPlannerError):
    """A GIS library of the ``gis`` extra is not installed."""


def require(module: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtraError` naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(
            f"{module} is not installed: this feature needs the GIS extra"
            " (pip install 'ris_planner[gis]')"
        ) from None
