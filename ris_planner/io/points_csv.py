"""``points.csv`` (:func:`points_csv`): a plan's per-point results as CSV (guide:
``docs/guides/gis.md``).

One row per point: index, local x/y/z, lon/lat/h with a frame, weight, and per count the bound,
the serving RISs and the blind reason. The document's ``license`` / ``attribution`` are comment
lines ``# license: …`` / ``# attribution: …`` before the header (read with
``pandas.read_csv(..., comment="#")``; :mod:`ris_planner.io.gis_outputs`).
"""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np

from ris_planner.io.frames import Converted, license_of_document, to_local
from ris_planner.io.geojson_write import LONLAT_DIGITS


def points_csv(
    points: list[dict[str, Any]], document: dict[str, Any], converted: Converted | None = None
) -> str:
    """The per-point CSV text (module docstring); ``converted``: the document in local metres
    and its frame when the caller converted it already."""
    _, frame = to_local(document) if converted is None else converted
    counts = sorted({k for p in points for k in (p.get("bound_m") or {})}, key=int)
    geo = ["lon", "lat", "h_m"] if frame is not None else []
    head = ["index", "x_m", "y_m", "z_m", *geo, "weight"]
    for c in counts:
        head += [f"bound_m_{c}", f"serving_{c}", f"reason_{c}"]
    buf = io.StringIO()
    for k, v in license_of_document(document).items():
        buf.write(f"# {k}: {' '.join(v.split())}\n")
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(head)
    pos = np.array([p["position"] for p in points], dtype=float).reshape(-1, 3)
    ll = frame.to_geographic(pos) if frame is not None and len(pos) else None
    for i, p in enumerate(points):
        row: list[Any] = [p.get("index", i), *pos[i].tolist()]
        if ll is not None:
            row += [round(ll[i, 0], LONLAT_DIGITS), round(ll[i, 1], LONLAT_DIGITS), ll[i, 2]]
        row.append(p.get("weight"))
        for c in counts:
            b = (p.get("bound_m") or {}).get(c)
            serving = (p.get("serving") or {}).get(c)
            row += [
                "" if b is None else b,
                "" if serving is None else " ".join(map(str, serving)),
                (p.get("reason") or {}).get(c) or "",
            ]
        wr.writerow(row)
    return buf.getvalue()
