"""``ris-planner import {geojson,osm,sites,dxf} FILE …``: site data → document fragments;
``ris-planner sites SITE.geojson …``: candidate RIS sites on its facades and along its roads
(:mod:`ris_planner.io.candidates`, docs/guides/candidates.md).

Both print their JSON on stdout or write it to ``--out``; the summary goes to stderr: for an
import the counts, buildings given the default height, courtyards kept open, repaired and
skipped outlines, tags that are not lengths, the licence and a converted ``crs``
(``docs/guides/import.md``), then each of its warnings on a line of its own (no buildings); for
candidates the counts per kind and the buildings left without candidates, with why.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import readable_json


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
    from ris_planner.io.import_options import ImportOptions

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
    from ris_planner.io.dxf import parse_layer_spec
    from ris_planner.io.site_import import import_data, parse_origin, plan_from_import

    opts = options_of(args)
    layers = dict(parse_layer_spec(s) for s in args.layer or [])
    origin = parse_origin(args.origin)
    extra: dict[str, Any] | None = None
    if args.candidates is not None:
        # the candidates' azimuths belong to the frame they were generated in: the site is
        # imported in that frame too (unless --origin names one)
        extra, _ = import_data(
            _read_bytes(args.candidates), "sites", opts, origin, what=args.candidates
        )
        origin = tuple(extra["frame"]["origin"]) if origin is None else origin
    fragment, summary = import_data(
        _read_bytes(args.file),
        args.format,
        opts,
        origin,
        layers,
        args.units,
        what=args.file,
    )
    if extra is not None:
        fragment["candidates"] = [*fragment.get("candidates", []), *extra["candidates"]]
        summary["candidates"] = len(fragment["candidates"])
    if args.plan:
        fragment, report = plan_from_import(fragment, args.format, summary, opts)
        summary = report.to_json()
    text = readable_json(fragment)
    if args.out:
        Path(args.out).write_text(text + "\n")
    else:
        sys.stdout.write(text + "\n")
    print("import summary: " + json.dumps(summary), file=sys.stderr)
    for warning in summary.get("warnings", []):
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _numbers(text: str, flag: str) -> list[float]:
    """``4,8`` → [4.0, 8.0], or an error naming the flag."""
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise RisPlannerError(f"{flag} {text!r}: expected comma-separated numbers") from None


def candidate_options_of(args: argparse.Namespace) -> Any:
    """The :class:`CandidateOptions` of the ``sites`` command's arguments (defaults for the
    flags not given); a bad value is one line naming the option."""
    from pydantic import ValidationError

    from ris_planner.core.io_json import validation_problems
    from ris_planner.io.candidates import CandidateOptions

    given: dict[str, Any] = {}
    for name in ("spacing_m", "corner_clearance_m", "offset_m", "max_angle_deg"):
        if getattr(args, name) is not None:
            given[name] = getattr(args, name)
    for name in ("pole_spacing_m", "pole_height_m", "pole_setback_m", "max_candidates"):
        if getattr(args, name) is not None:
            given[name] = getattr(args, name)
    for name in ("heights_m", "tilts_deg"):
        text = getattr(args, name)
        if text is not None:
            given[name] = _numbers(text, "--" + name.replace("_", "-"))
    if args.kinds is not None:
        given["kinds"] = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if args.road_classes is not None:
        classes = [c.strip() for c in args.road_classes.split(",") if c.strip()]
        given["road_classes"] = None if classes == ["all"] else classes
    if args.no_swap_check:
        given["swap_check"] = False
    try:
        return CandidateOptions.model_validate(given)
    except ValidationError as exc:
        raise RisPlannerError("invalid options: " + "; ".join(validation_problems(exc))) from None


def _cmd_sites(args: argparse.Namespace) -> int:
    from ris_planner.core.io_json import parse_json_object
    from ris_planner.io.candidates import candidate_sites

    options = candidate_options_of(args)
    site = parse_json_object(_read_bytes(args.file), args.file)
    collection, summary = candidate_sites(site, options)
    text = readable_json(collection)
    if args.out:
        Path(args.out).write_text(text + "\n")
    else:
        sys.stdout.write(text + "\n")
    s = summary.to_json()
    kinds = ", ".join(f"{n} {k}" for k, n in s["by_kind"].items()) or "none"
    print(
        f"sites: {s['candidates']} candidates ({kinds}) of {s['generated']} generated",
        end="",
        file=sys.stderr,
    )
    print(
        f"; dropped: {s['dropped_inside']} inside a building, {s['dropped_unseen']} seeing no"
        f" UE point, {s['dropped_max_candidates']} beyond max_candidates;"
        f" {s['ue_points']} UE points",
        file=sys.stderr,
    )
    for building, why in s["buildings_without_candidates"].items():
        print(f"  {building}: no candidate: {why}", file=sys.stderr)
    for note in s["notes"]:
        print(f"  note: {note}", file=sys.stderr)
    return 0


def _add_sites(sub: argparse._SubParsersAction) -> None:
    from ris_planner.cli.app import finite_float, int_in
    from ris_planner.io.candidates import MAX_CANDIDATES_LIMIT, CandidateOptions

    d = CandidateOptions()
    p = sub.add_parser(
        "sites",
        help="candidate RIS sites on the facades and along the roads of a site (GeoJSON or an"
        " imported document) → an editable GeoJSON of mounting points",
        description="Facade sites every --spacing-m along each building wall (corner clearance"
        " at both ends, every mounting height below the roof, facing outward) and poles every"
        " --pole-spacing-m along the roads, kept where they see a UE point. The output is what"
        " 'ris-planner import sites' reads (docs/guides/candidates.md).",
    )
    p.add_argument(
        "file",
        help="site: GeoJSON FeatureCollection (WGS84, or the CRS its crs member names) or an"
        " imported document",
    )
    p.add_argument("--out", help="write the candidates here instead of stdout")
    p.add_argument("--kinds", help=f"facade,pole (default {','.join(d.kinds)})")
    p.add_argument("--spacing-m", type=finite_float, help=f"facade spacing [m] ({d.spacing_m:g})")
    p.add_argument(
        "--heights-m",
        help="mounting heights above the building base [m], comma-separated"
        f" ({','.join(f'{h:g}' for h in d.heights_m)})",
    )
    p.add_argument(
        "--tilts-deg",
        help=f"downward tilts [deg], comma-separated ({','.join(f'{t:g}' for t in d.tilts_deg)})",
    )
    p.add_argument(
        "--corner-clearance-m",
        type=finite_float,
        help=f"kept free at both facade ends [m] ({d.corner_clearance_m:g})",
    )
    p.add_argument(
        "--offset-m",
        type=finite_float,
        help=f"RIS centre in front of the wall [m] ({d.offset_m:g})",
    )
    p.add_argument(
        "--max-angle-deg",
        type=finite_float,
        help=f"field of view from the normal [deg] ({d.max_angle_deg:g})",
    )
    p.add_argument(
        "--max-candidates",
        type=int_in(1, MAX_CANDIDATES_LIMIT),
        help=f"keep at most this many, those seeing most UE points ({d.max_candidates})",
    )
    p.add_argument(
        "--pole-spacing-m",
        type=finite_float,
        help=f"pole spacing along roads [m] ({d.pole_spacing_m:g})",
    )
    p.add_argument(
        "--pole-height-m", type=finite_float, help=f"pole RIS height [m] ({d.pole_height_m:g})"
    )
    p.add_argument(
        "--pole-setback-m",
        type=finite_float,
        help=f"pole distance beyond the road edge [m] ({d.pole_setback_m:g})",
    )
    p.add_argument(
        "--road-classes",
        help="highway classes carrying poles, comma-separated, or 'all'"
        f" ({','.join(d.road_classes or [])})",
    )
    p.add_argument(
        "--no-swap-check",
        action="store_true",
        help="skip the file-wide lat/lon swap test of a GeoJSON site (as ris-planner import"
        " --no-swap-check); the per-feature checks stay",
    )
    p.set_defaults(func=_cmd_sites)


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register the ``import`` and ``sites`` subcommands."""
    from ris_planner.io.import_options import (
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
    p.add_argument(
        "--candidates",
        metavar="SITES.geojson",
        help="add the candidate sites of this file (e.g. what `ris-planner sites` wrote) to the"
        " fragment or plan; the site is imported in the candidates' frame",
    )
    p.add_argument("--origin", help="frame origin LON,LAT[,H] (default: bounding-box centre)")
    p.add_argument(
        "--metres-per-level",
        type=float,
        default=METRES_PER_LEVEL,
        help="storey height for building:levels and building:min_level [m] (%(default)s)",
    )
    p.add_argument(
        "--default-height",
        type=float,
        default=DEFAULT_BUILDING_HEIGHT_M,
        help="height of a building with no usable height or building:levels tag [m]"
        " (%(default)s; such buildings are listed in the summary)",
    )
    p.add_argument(
        "--road-step",
        type=float,
        default=DEFAULT_ROAD_STEP_M,
        help="UE sampling step along and across imported roads [m] (%(default)s)",
    )
    p.add_argument(
        "--ue-height",
        type=float,
        default=DEFAULT_UE_HEIGHT_M,
        help="height of the imported UE positions (roads, areas) [m] (%(default)s)",
    )
    p.add_argument(
        "--density-key",
        default="density",
        help="property of a polygon that makes it a UE density area [UEs per m²] (%(default)s)",
    )
    p.add_argument(
        "--area-step",
        type=float,
        default=DEFAULT_AREA_STEP_M,
        help="grid step of the UE points inside a density area [m] (%(default)s)",
    )
    p.add_argument(
        "--site-spacing",
        type=float,
        default=DEFAULT_SITE_SPACING_M,
        help="spacing of candidate sites along a mounting line (sites: LineStrings) [m]"
        " (%(default)s)",
    )
    p.add_argument("--highways", help="road classes to import, comma-separated (default: all)")
    p.add_argument(
        "--invalid",
        choices=INVALID_POLICIES,
        default="repair",
        help="invalid outlines (self-intersecting, unclosed, degenerate): repair them"
        " (shapely make_valid, listed in the summary), skip them (listed) or stop with an"
        " error (%(default)s)",
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
    p.add_argument(
        "--units",
        choices=("mm", "cm", "m", "in", "ft"),
        help="dxf: the drawing's length unit (default: its $INSUNITS; unitless: metres)",
    )
    p.set_defaults(func=_cmd_import)
    _add_sites(sub)
