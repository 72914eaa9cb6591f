"""Candidate RIS sites: explicit poses and walls expanded to poses."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ris_planner.planning.document import Candidate, PlanDocument, RISDefaults, Wall
from ris_planner.scenario import RIS


@dataclass(frozen=True)
class Site:
    """One candidate: a RIS pose with the plan's element grid, and a label."""

    ris: RIS
    name: str
    cost: float = 0.0


def wall_poses(wall: Wall) -> list[tuple[list[float], list[float], str]]:
    """(position, orientation, label) for every site of a wall.

    Along a wall of length ℓ, n = max(1, round(ℓ / spacing)) sites sit at the centres of n
    equal parts; yaw points along the outward (or ``side``) normal, pitch = tilt, roll = 0.
    """
    if wall.rectangle is not None:
        x0, y0, x1, y1 = wall.rectangle
        # counter-clockwise corners: the right-hand normal of each edge points outward
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        segs = [(corners[i], corners[(i + 1) % 4], "right") for i in range(4)]
    else:
        assert wall.start is not None and wall.end is not None
        segs = [((wall.start[0], wall.start[1]), (wall.end[0], wall.end[1]), wall.side)]
    out = []
    for w_idx, (a, b, side) in enumerate(segs):
        pa, pb = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        d = pb - pa
        length = float(np.hypot(*d))
        n = max(1, round(length / wall.spacing_m))
        normal = np.array([-d[1], d[0]]) / length
        if side == "right":
            normal = -normal
        yaw = math.atan2(normal[1], normal[0])
        for k in range(n):
            xy = pa + (k + 0.5) / n * d
            for h in wall.heights_m:
                for tilt in wall.tilts_rad:
                    side_txt = f"side {w_idx} " if wall.rectangle is not None else ""
                    label = f"{side_txt}at ({xy[0]:.1f}, {xy[1]:.1f}, {h:g}) tilt {tilt:.2f}"
                    out.append(([float(xy[0]), float(xy[1]), float(h)], [yaw, tilt, 0.0], label))
    return out


def _ris(position: list[float], orientation: list[float], grid: RISDefaults) -> RIS:
    return RIS(
        position=position,
        orientation=orientation,
        rows=grid.rows,
        cols=grid.cols,
        spacing_m=grid.spacing_m,
    )


def expand_sites(doc: PlanDocument) -> list[Site]:
    """Explicit candidates first (input order), then each wall's sites (wall order)."""
    sites = [
        Site(_ris(c.position, c.orientation, doc.ris), c.name or f"candidate {i}", c.cost)
        for i, c in enumerate(doc.candidates)
    ]
    for w_i, wall in enumerate(doc.walls):
        for pos, ori, label in wall_poses(wall):
            sites.append(Site(_ris(pos, ori, doc.ris), f"wall {w_i} {label}", wall.cost))
    return sites


def candidate_json(site: Site) -> dict[str, object]:
    """A site as the JSON of a :class:`Candidate` plus its label."""
    return Candidate(
        position=site.ris.position, orientation=site.ris.orientation, name=site.name, cost=site.cost
    ).model_dump()
