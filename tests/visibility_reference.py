"""A deliberately simple per-leg visibility reference (docs/concepts/environment.md).

One leg at a time, one obstacle at a time, no index, no shared code with the engine:

* prism: the signed depth (distance to the nearest face inside, minus the distance to the
  prism outside; 1-Lipschitz) sampled densely along the leg, every :data:`SAMPLE_STEP_M`.
  The true maximum lies within half a step above the sampled one, so a leg is certainly
  blocked when the sampled maximum exceeds :data:`CONTRACT_BAND_M` (1 cm) and certainly
  clear when the sampled maximum plus half a step stays below 1 µm; anything between is the
  contract's unspecified band.
* wall: the crossing of the leg with the wall's plane, decided by the contract's margins
  (legs ending within 1 cm of the plane or crossing within 1 cm of an edge are unspecified).

``None`` means unspecified by the contract: callers skip such legs.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.kinds.wall import WallObstacle
from ris_planner.environment.model import Environment

SAMPLE_STEP_M = 1e-3
"""Spacing of the depth samples along a leg (1 mm)."""

CONTRACT_BAND_M = 1e-2
"""Legs entering by less than this, or crossing a wall this close to its edges, are unspecified."""

CONTRACT_MIN_TOL_M = 1e-6
"""Smallest tolerance an implementation may use (1 µm): a leg no deeper than this is clear."""


def signed_depth(p: NDArray, prism: Prism) -> NDArray:
    """[S] signed depth of points p [S, 3] in the prism: distance to the nearest face inside,
    −(distance to the prism) outside."""
    v = prism.vertices
    n = v.shape[0]
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    inside = np.zeros(p.shape[0], dtype=bool)
    dxy = np.full(p.shape[0], np.inf)
    for k in range(n):
        (x0, y0), (x1, y1) = v[k], v[(k + 1) % n]
        up = (y0 > y) != (y1 > y)  # even-odd test with a ray towards +x
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= up & (x < xc)
        ex, ey = x1 - x0, y1 - y0
        s = np.clip(((x - x0) * ex + (y - y0) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        dxy = np.minimum(dxy, np.hypot(x - x0 - s * ex, y - y0 - s * ey))
    in_slab = (z > prism.base_m) & (z < prism.top_m)
    dz_in = np.minimum(z - prism.base_m, prism.top_m - z)
    dz_out = np.maximum(np.maximum(prism.base_m - z, z - prism.top_m), 0.0)
    outside_dist = np.hypot(np.where(inside, 0.0, dxy), dz_out)
    return np.where(inside & in_slab, np.minimum(dxy, dz_in), -outside_dist)


def _prism_reference(a: NDArray, b: NDArray, prism: Prism) -> bool | None:
    v = prism.vertices
    lo = np.array([*v.min(axis=0), prism.base_m]) - 2 * CONTRACT_BAND_M
    hi = np.array([*v.max(axis=0), prism.top_m]) + 2 * CONTRACT_BAND_M
    d = b - a
    t0, t1 = 0.0, 1.0
    for k in range(3):  # clip to the grown box: outside it the depth is below −2 cm
        if d[k] == 0.0:
            if not lo[k] <= a[k] <= hi[k]:
                return False
            continue
        ta, tb = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, ta), min(t1, tb)
    if t0 > t1:
        return False
    length = float(np.linalg.norm(d)) * (t1 - t0)
    count = max(2, math.ceil(length / SAMPLE_STEP_M) + 1)
    t = np.linspace(t0, t1, count)
    depth = float(signed_depth(a + t[:, None] * d, prism).max())
    if depth > CONTRACT_BAND_M:
        return True
    if depth + 0.5 * SAMPLE_STEP_M < CONTRACT_MIN_TOL_M:
        return False
    return None


def _wall_reference(a: NDArray, b: NDArray, wall: WallObstacle) -> bool | None:
    s = np.asarray(wall.start, dtype=float)
    e = np.asarray(wall.end, dtype=float)
    length = float(np.hypot(*(e - s)))
    u = (e - s) / length
    normal = np.array([-u[1], u[0]])
    sa, sb = float((a[:2] - s) @ normal), float((b[:2] - s) @ normal)
    if min(abs(sa), abs(sb)) < CONTRACT_BAND_M:
        return None
    if (sa > 0) == (sb > 0):
        return False
    x = a + sa / (sa - sb) * (b - a)
    along, z = float((x[:2] - s) @ u), float(x[2])
    margin = min(along, length - along, z - wall.base_m, wall.top_m - z)
    if margin > CONTRACT_BAND_M:
        return True
    if margin < -CONTRACT_BAND_M:
        return False
    return None


def reference_blocked(a: NDArray, b: NDArray, env: Environment) -> bool | None:
    """Whether the leg a–b ([3] each) is blocked: True, False, or None (unspecified)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    unsure = False
    for ob in env.obstacles:
        r = _prism_reference(a, b, ob) if isinstance(ob, Prism) else _wall_reference(a, b, ob)
        if r is True:
            return True
        unsure |= r is None
    return None if unsure else False


def reference_inside(points: NDArray, env: Environment, margin: float) -> list[int | None]:
    """Per point [S, 3]: the index of the first prism it lies more than margin inside, −1 for
    none, None when a depth is within 1 nm of the margin."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    first: list[int | None] = [-1] * pts.shape[0]
    done = np.zeros(pts.shape[0], dtype=bool)
    for k, ob in enumerate(env.obstacles):
        if isinstance(ob, Prism):
            depth = signed_depth(pts, ob)
            for i in np.nonzero(~done & (np.abs(depth - margin) < 1e-9))[0]:
                first[i], done[i] = None, True
            for i in np.nonzero(~done & (depth > margin))[0]:
                first[i], done[i] = k, True
    return first
