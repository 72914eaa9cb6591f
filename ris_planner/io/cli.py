"""``ris-planner import {geojson,osm,sites,dxf} FILE …``: site data → document fragments.

Prints the fragment (JSON) on stdout or writes it to ``--out``; the import summary (counts,
buildings given the default height, courtyards kept open, repaired and skipped outlines, tags
that are not lengths, the licence) goes to stderr (``docs/guides/import.md``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ris_planner.errors import RisPlannerError


def _read_bytes(path: str) -> bytes:
    if path == "-":
        if sys.stdin is None or sys.stdin.closed:
            raise RisPlannerError("-: standard input is closed")
        return sys.stdin.buffer.read()
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise RisPlannerError(f"{path}: cannot read ({exc.strerror or exc})") from None


def options_of(args: argparse.Namespace) -> Any:
    """The :class:`ImportOptions` of the command's arguments."""
    from ris_planner.io.geojson_import import ImportOptions

    return ImportOptions(
        metres_per_level=args.metres_per_level,
        default_height_m=args.default_height,
        road_step_m=args.road_step,
        ue_height_m=args.ue_height,
        density_key=args.density_key,
        area_step_m=args.area_step,
        site_spacing_m=args.site_spacing,
        highways=tuple(args.highways.split(",")) if args.highways else None,
        invalid=args.invalid,
        swap_check=not args.no_swap_check,
    )


def _cmd_import(args: argparse.Namespace) -> int:
    from ris_planner.io.dxf_import import parse_layer_spec
    from ris_planner.io.site_import import import_data, parse_origin, plan_from_import

    opts = options_of(args)
    layers = dict(parse_layer_spec(s) for s in args.layer or [])
    fragment, summary = import_data(
        _read_bytes(args.file),
        args.format,
        opts,
        parse_origin(args.origin),
        layers,
        args.units,
        what=args.file,
    )
    if args.plan:
        fragment, report = plan_from_import(fragment, args.format, summary, opts)
        summary = report.to_json()
    text = json.dumps(fragment, indent=1, allow_nan=False)
    if args.out:
        Path(args.out).write_text(text + "\n")
    else:
        sys.stdout.write(text + "\n")
    print("import summary: " + json.dumps(summary), file=sys.stderr)
    return 0


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``import`` subcommand."""
    from ris_planner.io.geojson_import import (
        DEFAULT_AREA_STEP_M,
        DEFAULT_BUILDING_HEIGHT_M,
        DEFAULT_ROAD_STEP_M,
        DEFAULT_SITE_SPACING_M,
        DEFAULT_UE_HEIGHT_M,
        INVALID_POLICIES,
        METRES_PER_LEVEL,
    )

    p = sub.add_parser(
        "import",
        help="GeoJSON / OSM buildings, roads, UE areas, mounting sites, DXF floor plans →"
        " document fragments (environment, UE maps, candidates)",
    )
    p.add_argument(
        "format",
        choices=("geojson", "osm", "sites", "dxf"),
        help="geojson: buildings/roads/density areas (Points with azimuth_deg: mounting"
        " sites); osm: the same from .osm XML; sites: mounting points/lines →"
        " candidates/walls; dxf: floor plan layers → walls/prisms",
    )
    p.add_argument("file", help="input file ('-' for stdin)")
    p.add_argument("--out", help="write the fragment here instead of stdout")
    p.add_argument(
        "--plan",
        action="store_true",
        help="write a starting plan document (UE map as tx_map/rx_map, candidates, the"
        " defaults of ris_planner.io.site_import.PLAN_DEFAULTS) instead of the fragment",
    )
    p.add_argument("--origin", help="frame origin LON,LAT[,H] (default: bounding-box centre)")
    p.add_argument("--metres-per-level", type=float, default=METRES_PER_LEVEL)
    p.add_argument("--default-height", type=float, default=DEFAULT_BUILDING_HEIGHT_M)
    p.add_argument("--road-step", type=float, default=DEFAULT_ROAD_STEP_M)
    p.add_argument("--ue-height", type=float, default=DEFAULT_UE_HEIGHT_M)
    p.add_argument("--density-key", default="density")
    p.add_argument("--area-step", type=float, default=DEFAULT_AREA_STEP_M)
    p.add_argument("--site-spacing", type=float, default=DEFAULT_SITE_SPACING_M)
    p.add_argument("--highways", help="road classes to import, comma-separated (default: all)")
    p.add_argument(
        "--invalid",
        choices=INVALID_POLICIES,
        default="repair",
        help="invalid outlines (self-intersecting, unclosed, degenerate): repair them"
        " (shapely make_valid, listed in the summary; default), skip them (listed) or stop"
        " with an error",
    )
    p.add_argument(
        "--no-swap-check",
        action="store_true",
        help="skip the file-wide lat/lon swap test (building corners square only when read as"
        " [lat, lon]); the per-feature and origin checks stay",
    )
    p.add_argument(
        "--layer",
        action="append",
        help="dxf: LAYER=wall:HEIGHT_M or LAYER=prism:HEIGHT_M[:BASE_M] (repeatable)",
    )
    p.add_argument("--units", choices=("mm", "cm", "m", "in", "ft"), help="dxf: override $INSUNITS")
    p.set_defaults(func=_cmd_import)
