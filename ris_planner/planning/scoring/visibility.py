"""What each candidate site can serve, computed once per (UE point, site) and per LOS pair,
never per layout (docs/concepts/environment.md, "Visibility rules").

* A site serves a UE point when the point is in its field of view and the leg between them is
  clear (:func:`ris_planner.environment.ris_serves`, batched over all sites here); the RIS path
  of a site exists for a pair iff the site serves both of its UEs.
* The LOS path of a pair exists iff ``system.los`` and its TX–RX leg is clear.
* UE map points more than 1 cm inside a prism are dropped (and counted in ``plan.json``);
  a candidate RIS centre more than 1 cm inside a prism is an error.

Without a document ``environment`` none of this applies (free space, every path present).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.paths import in_field_of_view, los_clear
from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.planning.inputs.sites import Site
from ris_planner.planning.inputs.ue_maps import PairSet, PointMap

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SERVE_WARNING_FRACTION = 0.01
"""A candidate whose RIS path exists for less than this fraction (1 %) of the pair weight gets a
warning in ``plan.json``: few pairs have both UEs in its field of view with clear legs (it faces
away from the UEs, obstacles block it, or it sees too few points for the pairs to meet; a
plan's diagnosis tells which for the candidates that serve no pair at all)."""

LEG_BATCH = 1_000_000
"""Legs per visibility query (bounds the temporary arrays of :meth:`Scene.blocked`)."""


@dataclass(frozen=True)
class Visibility:
    """present : [S, P] the RIS path of each site exists for each pair;
    los : [P] the LOS path exists (``None`` when the system has no LOS)."""

    present: BoolArray
    los: BoolArray | None


def drop_inside(pm: PointMap, scene: Scene) -> tuple[PointMap, int]:
    """The map without its points more than 1 cm inside a prism, and how many were dropped."""
    inside = scene.inside(pm.points) >= 0
    n = int(np.count_nonzero(inside))
    if n == 0:
        return pm, 0
    return pm.subset(~inside), n


@dataclass(frozen=True)
class InsideSite:
    """A candidate site whose RIS centre lies inside a building (:func:`check_sites_outside`)."""

    index: int
    """Its index in the plan's expanded sites (explicit candidates first, in input order)."""
    name: str
    position: tuple[float, float, float]
    """The RIS centre in local metres."""
    building: str
    """The obstacle it lies in, as messages name it (``obstacle 3 (prism 'b1')``)."""


def local_position_text(position: tuple[float, float, float]) -> str:
    """``[x, y, z] = [-39.63, -40.32, 6.00] m``: a position in local metres, to 1 cm."""
    return "[x, y, z] = [" + ", ".join(f"{v:.2f}" for v in position) + "] m"


class SitesInsideError(RisPlannerError):
    """Candidate sites whose RIS centre lies more than 1 cm inside a prism: the message counts
    them and names every one with its position and building. Positions read in local metres;
    :meth:`at` restates them in the coordinates of the document as given (a boundary that
    knows its frame does, :mod:`ris_planner.io.geoplan`)."""

    def __init__(self, sites: tuple[InsideSite, ...], where: tuple[str, ...] | None = None) -> None:
        self.sites = tuple(sites)
        self.where = (
            tuple(where)
            if where is not None
            else tuple(local_position_text(s.position) for s in self.sites)
        )
        n = len(self.sites)
        named = "; ".join(
            f"candidate {s.index} ({s.name}) at {w} inside environment {s.building}"
            for s, w in zip(self.sites, self.where, strict=True)
        )
        super().__init__(
            f"{n} candidate site{'s lie' if n != 1 else ' lies'} inside a building (the RIS"
            f" centre more than 1 cm inside a prism): {named}. Move {'them' if n != 1 else 'it'}"
            " outside the buildings or remove " + ("them" if n != 1 else "it")
        )

    def at(self, where: tuple[str, ...]) -> SitesInsideError:
        """The same sites with their positions written as ``where`` (one text per site)."""
        return SitesInsideError(self.sites, where)

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        """Pickled with its sites (a job process's or a parse process's error arrives whole)."""
        return type(self), (self.sites, self.where)


def check_sites_outside(scene: Scene, sites: list[Site]) -> None:
    """Raise :class:`SitesInsideError` naming every candidate whose RIS centre lies more than
    1 cm inside a prism (how many, and each with its name, position and building)."""
    if not sites:
        return
    hit = scene.inside(np.array([s.ris.position for s in sites]))
    inside = np.nonzero(hit >= 0)[0]
    if inside.size:
        raise SitesInsideError(
            tuple(
                InsideSite(
                    int(i),
                    sites[i].name,
                    tuple(float(v) for v in sites[i].ris.position),  # type: ignore[arg-type]
                    scene.environment.label(int(hit[i])),
                )
                for i in inside
            )
        )


def serve_matrix(scene: Scene, sites: list[Site], points: FloatArray) -> BoolArray:
    """[S, M] whether each site serves each point [M, 3]: field of view per site, then the legs
    of all sites in batches of :data:`LEG_BATCH` (= ``ris_serves`` per site)."""
    fov = np.stack([in_field_of_view(s.ris, points) for s in sites])  # [S, M]
    if scene.empty:
        return fov
    centres = np.array([s.ris.position for s in sites])
    rows, cols = np.nonzero(fov)
    for k in range(0, rows.size, LEG_BATCH):
        r, c = rows[k : k + LEG_BATCH], cols[k : k + LEG_BATCH]
        hit = scene.blocked(points[c], centres[r])
        fov[r[hit], c[hit]] = False
    return fov


def _serves_pairs(
    scene: Scene, sites: list[Site], positions: FloatArray, index: NDArray[np.int_]
) -> BoolArray:
    """[S, P] serve flags of the pairs' UEs, evaluated once per distinct map point."""
    _, first, inverse = np.unique(index, return_index=True, return_inverse=True)
    return serve_matrix(scene, sites, positions[first])[:, inverse.ravel()]


def pair_visibility(scene: Scene, sites: list[Site], pairs: PairSet, los: bool) -> Visibility:
    """Which paths exist for every (site, pair), and the LOS path of every pair."""
    present = _serves_pairs(scene, sites, pairs.tx, pairs.tx_index)
    present &= _serves_pairs(scene, sites, pairs.rx, pairs.rx_index)
    los_ok = los_clear(scene, pairs.tx, pairs.rx) if los else None
    return Visibility(present, los_ok)


def serve_warnings(sites: list[Site], present: BoolArray, weights: FloatArray) -> list[str]:
    """A warning per candidate whose RIS path exists for less than
    :data:`SERVE_WARNING_FRACTION` of the pair weight ``weights`` [P]."""
    served = present.astype(float) @ weights  # [S]
    return [
        f"candidate {i} ({site.name}) serves {served[i]:.1%} of the pair weight (below"
        f" {SERVE_WARNING_FRACTION:.0%}): few pairs have both UEs in its field of view with"
        " clear legs"
        for i, site in enumerate(sites)
        if served[i] < SERVE_WARNING_FRACTION
    ]
