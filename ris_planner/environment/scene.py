"""Visibility of legs against prisms and walls, batched over legs.

Rules (DESIGN.md contract; ``tol`` = :data:`VISIBILITY_TOLERANCE_M`):

* wall: a leg A→B is blocked when A and B lie on strictly opposite sides of the wall's
  vertical plane, each more than ``tol`` from it, and the crossing point lies inside the wall
  rectangle by more than ``tol`` (from its ends, its bottom and its top).
* prism: the leg is clipped to the open slab base < z < top and split at its crossings with
  the footprint's edges; it is blocked when one of the pieces is longer than ``tol`` and its
  midpoint lies inside the prism more than ``tol`` from every face. A leg that touches a face,
  runs along it, or starts on a facade and leaves it (even a few ulps inside) is clear.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.obstacles import Environment, Prism, WallObstacle

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

VISIBILITY_TOLERANCE_M = 1e-3
"""Legs that enter a prism or cross a wall by no more than this (1 mm) are clear; the contract
allows any tolerance between 1 µm and 1 cm."""

INSIDE_MARGIN_M = 1e-2
"""A UE or RIS centre more than this (1 cm) inside a prism is inside it (DESIGN.md)."""


def _point_segment_distance(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """2-D distance from points p [..., 2] to segments a–b [..., 2] (broadcast)."""
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.asarray(np.linalg.norm(p - closest, axis=-1))


def _inside_polygon(p: FloatArray, a: FloatArray, b: FloatArray) -> BoolArray:
    """Even-odd point-in-polygon for points p [M, 2] against edges a, b [n, 2]."""
    px, py = p[:, 0:1], p[:, 1:2]
    ay, by = a[None, :, 1], b[None, :, 1]
    ax, bx = a[None, :, 0], b[None, :, 0]
    straddle = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = ax + (py - ay) * (bx - ax) / (by - ay)
    return np.asarray(np.sum(straddle & (px < x_cross), axis=1) % 2 == 1)


def prism_depth(points: FloatArray, prism: Prism) -> FloatArray:
    """How far points [M, 3] lie inside the prism [M] (distance to its nearest face; ≤ 0
    outside: 0 on or outside the footprint, z distance below/above it otherwise)."""
    v = prism.vertices
    a, b = v, np.roll(v, -1, axis=0)
    xy = points[:, :2]
    inside = _inside_polygon(xy, a, b)
    d2 = _point_segment_distance(xy[:, None, :], a[None], b[None]).min(axis=1)
    dz = np.minimum(points[:, 2] - prism.base_m, prism.top_m - points[:, 2])
    return np.asarray(np.where(inside, np.minimum(d2, dz), 0.0))


def _wall_blocks(a: FloatArray, b: FloatArray, wall: WallObstacle, tol: float) -> BoolArray:
    s = np.asarray(wall.start, dtype=float)
    e = np.asarray(wall.end, dtype=float)
    d = e - s
    length = float(np.hypot(*d))
    u = d / length
    n = np.array([-u[1], u[0]])
    sa = (a[:, :2] - s) @ n
    sb = (b[:, :2] - s) @ n
    cand = (sa * sb < 0) & (np.abs(sa) > tol) & (np.abs(sb) > tol)
    t = np.where(cand, sa / np.where(cand, sa - sb, 1.0), 0.0)
    p = a + t[:, None] * (b - a)
    along = (p[:, :2] - s) @ u
    return np.asarray(
        cand
        & (along > tol)
        & (along < length - tol)
        & (p[:, 2] > wall.base_m + tol)
        & (p[:, 2] < wall.top_m - tol)
    )


def _prism_blocks(a: FloatArray, b: FloatArray, prism: Prism, tol: float) -> BoolArray:
    m = a.shape[0]
    d = b - a
    # [M] the leg's parameter range inside the open slab base < z < top
    with np.errstate(divide="ignore", invalid="ignore"):
        t_base = (prism.base_m - a[:, 2]) / d[:, 2]
        t_top = (prism.top_m - a[:, 2]) / d[:, 2]
    flat = d[:, 2] == 0
    in_slab = (a[:, 2] > prism.base_m) & (a[:, 2] < prism.top_m)
    lo = np.where(flat, np.where(in_slab, 0.0, 1.0), np.maximum(0.0, np.minimum(t_base, t_top)))
    hi = np.where(flat, np.where(in_slab, 1.0, 0.0), np.minimum(1.0, np.maximum(t_base, t_top)))
    lo, hi = np.nan_to_num(lo, nan=1.0), np.nan_to_num(hi, nan=0.0)
    v = prism.vertices
    ea, eb = v, np.roll(v, -1, axis=0)
    # [M, n] crossing parameters of the 2-D leg with each footprint edge
    r = d[:, None, :2]
    q = (eb - ea)[None]
    w = ea[None] - a[:, None, :2]
    denom = r[..., 0] * q[..., 1] - r[..., 1] * q[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * q[..., 1] - w[..., 1] * q[..., 0]) / denom
        s = (w[..., 0] * r[..., 1] - w[..., 1] * r[..., 0]) / denom
    ok = (denom != 0) & (s >= 0) & (s <= 1) & (t > lo[:, None]) & (t < hi[:, None])
    t = np.where(ok, t, hi[:, None])
    # [M, n + 2] sorted cut points; pieces between consecutive cuts
    cuts = np.sort(np.concatenate([lo[:, None], t, hi[:, None]], axis=1), axis=1)
    t0, t1 = cuts[:, :-1], cuts[:, 1:]
    length = (t1 - t0) * np.linalg.norm(d, axis=1)[:, None]
    long = length > tol
    if not np.any(long):
        return np.zeros(m, dtype=bool)
    rows, cols = np.nonzero(long)
    mid_t = 0.5 * (t0[rows, cols] + t1[rows, cols])
    mid = a[rows] + mid_t[:, None] * d[rows]
    deep = prism_depth(mid, prism) > tol
    out = np.zeros(m, dtype=bool)
    out[rows[deep]] = True
    return out


@dataclass(frozen=True)
class Scene:
    """The obstacles of one site, ready for batched visibility queries."""

    environment: Environment

    @classmethod
    def from_environment(cls, environment: Environment | None) -> Scene:
        return cls(environment if environment is not None else Environment())

    @property
    def empty(self) -> bool:
        return not self.environment.obstacles

    def blocked(
        self, a: FloatArray, b: FloatArray, tol: float = VISIBILITY_TOLERANCE_M
    ) -> BoolArray:
        """[M] whether each leg a[i]–b[i] ([M, 3] each) is blocked by an obstacle."""
        a = np.asarray(a, dtype=float).reshape(-1, 3)
        b = np.asarray(b, dtype=float).reshape(-1, 3)
        out = np.zeros(a.shape[0], dtype=bool)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        for ob in self.environment.obstacles:
            if isinstance(ob, Prism):
                v = ob.vertices
                box_lo = np.array([*v.min(axis=0), ob.base_m])
                box_hi = np.array([*v.max(axis=0), ob.top_m])
            else:
                ends = np.array([ob.start, ob.end], dtype=float)
                box_lo = np.array([*ends.min(axis=0), ob.base_m])
                box_hi = np.array([*ends.max(axis=0), ob.top_m])
            near = ~out & np.all((lo <= box_hi) & (hi >= box_lo), axis=1)
            if not np.any(near):
                continue
            idx = np.nonzero(near)[0]
            if isinstance(ob, Prism):
                hit = _prism_blocks(a[idx], b[idx], ob, tol)
            else:
                hit = _wall_blocks(a[idx], b[idx], ob, tol)
            out[idx[hit]] = True
        return out

    def inside(self, points: FloatArray, margin: float = INSIDE_MARGIN_M) -> IntArray:
        """[M] index of the first prism each point [M, 3] lies more than ``margin`` inside,
        −1 for none."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.full(pts.shape[0], -1, dtype=int)
        for i, ob in enumerate(self.environment.obstacles):
            if isinstance(ob, Prism):
                free = out < 0
                if not np.any(free):
                    break
                idx = np.nonzero(free)[0]
                hit = prism_depth(pts[idx], ob) > margin
                out[idx[hit]] = i
        return out
