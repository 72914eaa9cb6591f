"""Candidate RIS sites: explicit poses, walls and prism facades expanded to poses."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ris_planner.environment.kinds.prism import Prism
from ris_planner.model.plan import Candidate, Facades, PlanDocument, RISDefaults, WallSites
from ris_planner.model.scenario import RIS


@dataclass(frozen=True)
class Site:
    """One candidate: a RIS pose with the plan's element grid, and a label."""

    ris: RIS
    name: str
    cost: float = 0.0


def wall_poses(wall: WallSites) -> list[tuple[list[float], list[float], str]]:
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
                    label = f"{side_txt}at ({xy[0]:.1f}, {xy[1]:.1f}, {h:g}) tilt {tilt:.2f} rad"
                    out.append(([float(xy[0]), float(xy[1]), float(h)], [yaw, tilt, 0.0], label))
    return out


def signed_area(vertices: NDArray[np.float64]) -> float:
    """Shoelace area of a footprint [n, 2]: > 0 counter-clockwise, < 0 clockwise."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def facade_walls(facades: Facades, prism: Prism) -> list[WallSites]:
    """One outward-facing :class:`WallSites` segment per footprint edge of the prism (in vertex
    order), moved ``offset_m`` outward; heights from the base, clipped to the top, deduplicated.

    The outward normal of edge a→b is on its right for a counter-clockwise footprint (positive
    :func:`signed_area`) and on its left for a clockwise one."""
    v = prism.vertices
    side: Literal["left", "right"] = "right" if signed_area(v) > 0 else "left"
    heights = list(dict.fromkeys(min(prism.base_m + h, prism.top_m) for h in facades.heights_m))
    out = []
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
        d = b - a
        outward = np.array([d[1], -d[0]]) / float(np.hypot(*d))  # right-hand normal
        if side == "left":
            outward = -outward
        shift = facades.offset_m * outward
        out.append(
            WallSites(
                start=(a + shift).tolist(),
                end=(b + shift).tolist(),
                side=side,
                heights_m=heights,
                spacing_m=facades.spacing_m,
                tilts_rad=facades.tilts_rad,
            )
        )
    return out


def _ris(position: list[float], orientation: list[float], grid: RISDefaults) -> RIS:
    # every RISGrid field of the plan's shared ``ris`` (one list: the model itself)
    return RIS(position=position, orientation=orientation, **grid.model_dump())


def expand_sites(doc: PlanDocument) -> list[Site]:
    """Explicit candidates first (input order), then each wall's sites (wall order), then each
    facade entry's sites (prisms in ``of`` order, edges in footprint order)."""
    sites = [
        Site(_ris(c.position, c.orientation, doc.ris), c.name or f"candidate {i}", c.cost)
        for i, c in enumerate(doc.candidates)
    ]
    for w_i, wall in enumerate(doc.walls):
        for pos, ori, label in wall_poses(wall):
            sites.append(Site(_ris(pos, ori, doc.ris), f"wall {w_i} {label}", wall.cost))
    for f_i, (fac, prisms) in enumerate(zip(doc.facades, doc.facade_prisms(), strict=True)):
        for ob_i, prism in prisms:
            name = prism.name or f"obstacle {ob_i}"
            for e_i, wall in enumerate(facade_walls(fac, prism)):
                for pos, ori, label in wall_poses(wall):
                    label = f"facades {f_i} {name} edge {e_i} {label}"
                    sites.append(Site(_ris(pos, ori, doc.ris), label, wall.cost))
    return sites


def candidate_json(site: Site) -> dict[str, object]:
    """A site as the JSON of a :class:`Candidate` plus its label."""
    return Candidate(
        position=site.ris.position, orientation=site.ris.orientation, name=site.name, cost=site.cost
    ).model_dump()
