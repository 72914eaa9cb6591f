"""DXF floor plans → environment obstacles, via ``ezdxf``.

Chosen layers become walls or prisms, each layer with its own height and base:

* ``wall`` layers: every LINE, and every segment of an LWPOLYLINE / POLYLINE (the closing
  segment too when it is closed) → a ``wall`` obstacle from ``base_m`` to ``base_m +
  height_m``. Arc segments (bulges) are taken as their chords.
* ``prism`` layers: every closed LWPOLYLINE / POLYLINE → a ``prism`` with that footprint
  (an open one is an error naming its handle; LINEs are skipped and counted).

Coordinates are the drawing's x, y (the drawing origin becomes the local origin), scaled to
metres by the header's ``$INSUNITS`` (mm, cm, m, inch, foot, …); a unitless drawing
(``$INSUNITS`` = 0) is read as metres unless ``units`` says otherwise. Entities on other
layers are ignored (counted per layer in the summary).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from ris_planner.core.errors import RisPlannerError
from ris_planner.io import require

MIN_WALL_LENGTH_M = 1e-6
"""Segments shorter than this (the obstacle model's 1 µm) are dropped and counted."""

UNIT_NAMES = {"mm": 4, "cm": 5, "m": 6, "in": 1, "ft": 2}
"""``units`` override names → DXF $INSUNITS codes."""


@dataclass(frozen=True)
class LayerSpec:
    """How one DXF layer becomes obstacles."""

    kind: Literal["wall", "prism"]
    height_m: float
    base_m: float = 0.0


_POSITIVE = r"(?:[0-9]*[1-9][0-9]*(?:\.[0-9]*)?|[0-9]*\.[0-9]*[1-9][0-9]*)"
_NON_NEGATIVE = r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"
LAYER_SPEC_PATTERN = rf"^[^=]+=(?:wall|prism):{_POSITIVE}(?::{_NON_NEGATIVE})?$"
"""The text of one layer choice: ``NAME=wall:HEIGHT_M`` or ``NAME=prism:HEIGHT_M[:BASE_M]``
(a non-empty name; plain decimal metres, height > 0, base ≥ 0) – the service's OpenAPI
document states the same pattern."""


def parse_layer_spec(text: str) -> tuple[str, LayerSpec]:
    """``NAME=wall:2.5`` or ``NAME=prism:3[:base]`` → (layer name, spec)
    (:data:`LAYER_SPEC_PATTERN`)."""
    if re.fullmatch(LAYER_SPEC_PATTERN, text) is None:
        raise RisPlannerError(
            f"layer {text!r}: expected LAYER=wall:HEIGHT_M or LAYER=prism:HEIGHT_M[:BASE_M]"
            " (decimal metres, height > 0, base ≥ 0)"
        )
    name, sep, rest = text.partition("=")
    parts = rest.split(":")
    if not sep or not name or len(parts) not in (2, 3) or parts[0] not in ("wall", "prism"):
        raise RisPlannerError(
            f"layer {text!r}: expected LAYER=wall:HEIGHT_M or LAYER=prism:HEIGHT_M[:BASE_M]"
        )
    try:
        nums = [float(p) for p in parts[1:]]
    except ValueError:
        raise RisPlannerError(f"layer {text!r}: heights must be numbers (metres)") from None
    if not nums[0] > 0 or (len(nums) == 3 and nums[1] < 0):
        raise RisPlannerError(f"layer {text!r}: height must be > 0 and base ≥ 0")
    kind: Literal["wall", "prism"] = "wall" if parts[0] == "wall" else "prism"
    return name, LayerSpec(kind, nums[0], nums[1] if len(nums) == 2 else 0.0)


def import_dxf(
    source: str | Path | Any,
    layers: dict[str, LayerSpec],
    units: str | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """A DXF file (path or an ``ezdxf`` document) → (``{"environment": {"obstacles": …}}`` in
    metres, summary). ``units`` (``mm``, ``cm``, ``m``, ``in``, ``ft``) overrides $INSUNITS."""
    ezdxf = require("ezdxf")
    if not layers:
        raise RisPlannerError(
            "no layers chosen: give NAME=wall:HEIGHT or NAME=prism:HEIGHT[:BASE] (--layer on the"
            " command line, ?layer= over REST)"
        )
    if isinstance(source, str | Path):
        try:
            doc = ezdxf.readfile(str(source))
        except (OSError, ezdxf.DXFStructureError) as exc:
            raise RisPlannerError(f"{source}: not a readable DXF file ({exc})") from None
    else:
        doc = source
    if units is not None:
        if units not in UNIT_NAMES:
            raise RisPlannerError(f"units {units!r}: choose one of {', '.join(UNIT_NAMES)}")
        code = UNIT_NAMES[units]
    else:
        code = int(doc.header.get("$INSUNITS", 0))
    if code == 0:
        scale = 1.0
    else:
        try:
            scale = float(ezdxf.units.conversion_factor(code, ezdxf.units.M))
        except (KeyError, IndexError, ValueError):
            raise RisPlannerError(f"$INSUNITS {code}: not a length unit") from None
    known = {layer.dxf.name for layer in doc.layers}
    absent = [name for name in layers if name not in known]
    if absent:
        raise RisPlannerError(
            f"layer(s) {', '.join(map(repr, absent))} not in the drawing (layers:"
            f" {', '.join(sorted(known))})"
        )
    obstacles: list[dict[str, Any]] = []
    ignored: dict[str, int] = {}
    dropped = 0
    for e in doc.modelspace():
        layer = e.dxf.layer
        spec = layers.get(layer)
        kind = e.dxftype()
        if spec is None or kind not in ("LINE", "LWPOLYLINE", "POLYLINE"):
            ignored[f"{layer}:{kind}"] = ignored.get(f"{layer}:{kind}", 0) + 1
            continue
        label = f"{kind} {e.dxf.handle} on layer {layer!r}"
        if kind == "LINE":
            pts = [(e.dxf.start.x, e.dxf.start.y), (e.dxf.end.x, e.dxf.end.y)]
            closed = False
        elif kind == "LWPOLYLINE":
            pts = [(p[0], p[1]) for p in e.get_points("xy")]
            closed = bool(e.closed)
        else:
            pts = [(v.dxf.location.x, v.dxf.location.y) for v in e.vertices]
            closed = bool(e.is_closed)
        xy = [[float(x) * scale, float(y) * scale] for x, y in pts]
        if spec.kind == "prism":
            if kind == "LINE":
                ignored[f"{layer}:{kind}"] = ignored.get(f"{layer}:{kind}", 0) + 1
                continue
            if len(xy) > 3 and xy[0] == xy[-1]:
                xy, closed = xy[:-1], True
            if not closed:
                raise RisPlannerError(f"{label}: a prism layer needs closed polylines")
            obstacles.append(
                {
                    "kind": "prism",
                    "name": f"{layer} {e.dxf.handle}",
                    "footprint": xy,
                    "base_m": spec.base_m,
                    "height_m": spec.height_m,
                }
            )
            continue
        segs = list(itertools.pairwise(xy))
        if closed and xy[0] != xy[-1]:
            segs.append((xy[-1], xy[0]))
        for k, (a, b) in enumerate(segs):
            if ((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5 < MIN_WALL_LENGTH_M:
                dropped += 1
                continue
            obstacles.append(
                {
                    "kind": "wall",
                    "name": f"{layer} {e.dxf.handle}" + (f".{k}" if len(segs) > 1 else ""),
                    "start": a,
                    "end": b,
                    "base_m": spec.base_m,
                    "height_m": spec.height_m,
                }
            )
    summary = {
        "units_to_m": scale,
        "walls": sum(o["kind"] == "wall" for o in obstacles),
        "prisms": sum(o["kind"] == "prism" for o in obstacles),
        "zero_length_dropped": dropped,
        "ignored": ignored,
    }
    return {"environment": {"obstacles": obstacles}}, summary
