"""Which paths exist: field of view, blocked legs and the RIS pattern factor
(docs/concepts/environment.md, "Visibility rules").

* A RIS serves a UE when the angle between its normal (global R·e_x) and the direction from
  its centre to the UE is strictly below ``max_angle_deg`` and the leg between them is clear.
* A RIS path exists for a pair iff the RIS serves both UEs; the LOS path iff ``system.los``
  and the TX–RX leg is clear.

Visibility is a property of (point, site), so callers that score many layouts compute
:func:`ris_serves` once per UE point and candidate site and combine the masks per pair.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ris_planner.environment.scene import Scene
from ris_planner.model.scenario import RIS
from ris_planner.physics.geometry import rotation_matrix

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def normal_cosines(ris: RIS, points: ArrayLike) -> FloatArray:
    """cos θ of the angle between the RIS normal and the direction RIS centre → point, [M]
    (0 for a point at the centre)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    normal = rotation_matrix(ris.orientation)[:, 0]
    v = pts - np.asarray(ris.position, dtype=float)
    d = np.linalg.norm(v, axis=1)
    return np.asarray(np.where(d > 0, (v @ normal) / np.where(d > 0, d, 1.0), 0.0))


def in_field_of_view(ris: RIS, points: ArrayLike) -> BoolArray:
    """[M] angle to the normal strictly below ``max_angle_deg`` (90°: the open front half-space)."""
    cos = normal_cosines(ris, points)
    if ris.max_angle_deg == 90.0:
        return np.asarray(cos > 0.0)  # exact: cos(π/2) rounds to 6e-17
    return np.asarray(cos > math.cos(math.radians(ris.max_angle_deg)))


def pattern_factor(ris: RIS, tx: ArrayLike, rx: ArrayLike) -> FloatArray:
    """(cos θ_T · cos θ_R)^q on the path gain |ρ_ℓ|, [P]; exactly 1 for q = 0 (the paper's
    isotropic model). Cosines behind the RIS (possible with ``max_angle_deg`` > 90) count as 0."""
    q = ris.pattern_exponent
    n = np.asarray(tx, dtype=float).reshape(-1, 3).shape[0]
    if q == 0.0:
        return np.ones(n)
    cos_t = np.maximum(normal_cosines(ris, tx), 0.0)
    cos_r = np.maximum(normal_cosines(ris, rx), 0.0)
    return np.asarray((cos_t * cos_r) ** q)


def ris_serves(scene: Scene, ris: RIS, points: ArrayLike) -> BoolArray:
    """[M] whether the RIS serves each point: in its field of view and the leg is clear."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return serves_each(scene, [ris], np.zeros(pts.shape[0], dtype=np.int64), pts)


def serves_each(
    scene: Scene, rises: Sequence[RIS], which: NDArray[np.int_], points: ArrayLike
) -> BoolArray:
    """[K] whether ``rises[which[k]]`` serves ``points[k]`` (the rule of :func:`ris_serves`),
    every leg in one visibility query: a caller with a few points for each of many RISs (a
    district layout's design positions) pays one query, not one per RIS and point."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    which = np.asarray(which, dtype=np.int64).reshape(-1)
    ok = np.zeros(pts.shape[0], dtype=bool)
    order = np.argsort(which, kind="stable")
    ends = np.searchsorted(which[order], np.arange(len(rises) + 1))
    for i, ris in enumerate(rises):
        rows = order[ends[i] : ends[i + 1]]
        if rows.size:
            ok[rows] = in_field_of_view(ris, pts[rows])
    if not scene.empty and np.any(ok):
        idx = np.nonzero(ok)[0]
        centres = np.array([r.position for r in rises], dtype=float).reshape(-1, 3)
        ok[idx] = ~scene.blocked(pts[idx], centres[which[idx]])
    return ok


def los_clear(scene: Scene, tx: ArrayLike, rx: ArrayLike) -> BoolArray:
    """[P] whether the TX–RX leg is clear."""
    a = np.asarray(tx, dtype=float).reshape(-1, 3)
    if scene.empty:
        return np.ones(a.shape[0], dtype=bool)
    return np.asarray(~scene.blocked(a, np.asarray(rx, dtype=float).reshape(-1, 3)))


def path_presence(
    scene: Scene, ris: list[RIS], tx: ArrayLike, rx: ArrayLike, los: bool
) -> dict[str, BoolArray]:
    """``{"los": [P], "ris1": [P], …}``: which paths exist for each pair (environment.md rules);
    ``"los"`` only when the system has a LOS path (``los`` False: absent from the dict)."""
    a = np.asarray(tx, dtype=float).reshape(-1, 3)
    slots = np.broadcast_to(np.arange(len(ris)), (a.shape[0], len(ris)))
    return path_presence_per_pair(scene, ris, slots, a, rx, los)


def path_presence_per_pair(
    scene: Scene,
    rises: Sequence[RIS],
    slots: NDArray[np.int_],
    tx: ArrayLike,
    rx: ArrayLike,
    los: bool,
) -> dict[str, BoolArray]:
    """:func:`path_presence` where each pair has RISs of its own: pair p's path ``ris{j+1}``
    is ``rises[slots[p, j]]``'s (``slots`` [P, W]). Every RIS leg of every pair in one
    visibility query (:func:`serves_each`), the LOS legs in another."""
    a = np.asarray(tx, dtype=float).reshape(-1, 3)
    b = np.asarray(rx, dtype=float).reshape(-1, 3)
    slots = np.asarray(slots, dtype=np.int64).reshape(a.shape[0], -1)
    n, width = slots.shape
    out: dict[str, BoolArray] = {}
    if los:
        out["los"] = los_clear(scene, a, b)
    which = np.concatenate([slots.ravel(), slots.ravel()])
    ends = np.concatenate([np.repeat(a, width, axis=0), np.repeat(b, width, axis=0)])
    ok = serves_each(scene, rises, which, ends)
    both = (ok[: n * width] & ok[n * width :]).reshape(n, width)
    for j in range(width):
        out[f"ris{j + 1}"] = np.ascontiguousarray(both[:, j])
    return out
