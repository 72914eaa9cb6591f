"""Real sites in, GIS out: one module per format or concept – GeoJSON / OSM / sites / DXF
import, the CRS and lat/lon checks, GeoJSON / GeoTIFF / CSV export – plus frames, candidate
generation and the plan path of real sites (layering: above :mod:`ris_planner.planning`; the
engine never imports this package).

* :mod:`ris_planner.io.frames` – ``frame`` of a document (WGS84 lon/lat or a projected CRS)
  ↔ the local east-north-up metres the engine works in (:func:`to_local`, :class:`Frame`).
* Import (guide: ``docs/guides/import.md``):

  * :mod:`ris_planner.io.geojson_read` – GeoJSON buildings → prisms, roads → UE roads,
    density areas → weighted UE points;
  * :mod:`ris_planner.io.osm_xml` – ``.osm`` XML → a GeoJSON collection;
  * :mod:`ris_planner.io.site_points` – the ``sites`` format: mounting points / lines →
    candidates and walls;
  * :mod:`ris_planner.io.dxf` – DXF floor plans → walls and prisms;
  * :mod:`ris_planner.io.crs` – a collection's ``crs`` member → WGS84 (pyproj);
  * :mod:`ris_planner.io.swap_check` – lat/lon swap detection;
  * :mod:`ris_planner.io.feature_positions` – features' positions → local metres and the
    import's frame;
  * :mod:`ris_planner.io.import_options` – options, defaults, the import summary, feature
    errors and labels, length tags, the data licence.

* :mod:`ris_planner.io.candidates` – candidate sites generated on an imported site.
* Export: :mod:`ris_planner.io.gis_outputs` writes :mod:`~ris_planner.io.geojson_write`
  (``plan.geojson``), :mod:`~ris_planner.io.geotiff` (``heatmap.tif``) and
  :mod:`~ris_planner.io.points_csv` (``points.csv``).
* :mod:`ris_planner.io.geoplan` – a document as given → plan.json, PNGs and GIS files (the one
  path of ``ris-planner plan --out`` and the service's plan jobs).
* :mod:`ris_planner.io.site_import` – a file's bytes → an import fragment or a starting plan
  document (``ris-planner import`` and ``POST /v1/import``; dispatches by format).

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
