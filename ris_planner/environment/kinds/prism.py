"""Obstacle kind ``prism``: a vertical extrusion of a simple polygon ``footprint`` ([x, y] vertices
in metres, any winding, convex or not) between z = ``base_m`` and z = ``base_m + height_m``
(docs/concepts/environment.md, "Obstacles"): its model, its faces and its exact float64 narrow
phase (the rules of :mod:`ris_planner.environment.scene`).

Footprints are packed into groups of a common padded vertex count (powers of two, at least 4)
by repeating their last vertex: a repeated vertex makes a zero-length edge, which never
straddles a line and whose capsule is the vertex's disk, so it changes nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator, model_validator

from ris_planner.core.document import finite_point
from ris_planner.environment.kinds.base import (
    BoolArray,
    Faces,
    FloatArray,
    GeoJSON,
    GeometryError,
    IntArray,
    ObstacleModel,
    ToOutput,
    coordinates,
    label,
    position_xy,
)

MIN_FOOTPRINT_AREA_M2 = 1e-6
"""A footprint with a smaller area (1 mm²) is degenerate (collinear or repeated vertices)."""

MIN_EDGE_M = 1e-6
"""Footprint edges and walls shorter than 1 µm are degenerate."""

MAX_FOOTPRINT_VERTICES = 10_000
"""Vertices per footprint (OSM buildings have tens; a city block outline a few hundred)."""

XY_DEGENERATE_M = 1e-9
"""A leg whose horizontal extent is below this (1 nm) is treated as vertical: its xy is the
midpoint's, an error of at most 0.5 nm, far inside the contract's 1 µm–1 cm band."""

Point2 = Annotated[
    list[float],
    Field(min_length=2, max_length=2, description="[x, y] in metres (global frame)"),
]


def segments_cross(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray) -> NDArray[np.bool_]:
    """Whether 2-D segments a–b and c–d intersect (touching included), batched [..., 2]."""

    def orient(p: FloatArray, q: FloatArray, r: FloatArray) -> FloatArray:
        return np.asarray(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    def on_segment(p: FloatArray, q: FloatArray, r: FloatArray) -> NDArray[np.bool_]:
        """r within the bounding box of p–q (used when p, q, r are collinear)."""
        return np.asarray(
            (np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
            & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
            & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
            & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1]))
        )

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    proper = (np.sign(o1) * np.sign(o2) < 0) & (np.sign(o3) * np.sign(o4) < 0)
    touch = (
        ((o1 == 0) & on_segment(a, b, c))
        | ((o2 == 0) & on_segment(a, b, d))
        | ((o3 == 0) & on_segment(c, d, a))
        | ((o4 == 0) & on_segment(c, d, b))
    )
    return np.asarray(proper | touch)


def footprint_problem(vertices: FloatArray) -> str | None:
    """Why a footprint [n, 2] is not a simple polygon with area, or ``None``."""
    n = vertices.shape[0]
    if n < 3:
        return f"a footprint needs at least 3 vertices, got {n}"
    edges = np.roll(vertices, -1, axis=0) - vertices
    short = np.hypot(edges[:, 0], edges[:, 1]) < MIN_EDGE_M
    if np.any(short):
        k = int(np.argmax(short))
        return f"footprint vertices {k} and {(k + 1) % n} coincide ({vertices[k].tolist()})"
    if n > 3:
        a, b = vertices, np.roll(vertices, -1, axis=0)
        i, j = np.triu_indices(n, k=2)
        keep = ~((i == 0) & (j == n - 1))  # the first and last edges are adjacent
        i, j = i[keep], j[keep]
        hit = segments_cross(a[i], b[i], a[j], b[j])
        if np.any(hit):
            k = int(np.argmax(hit))
            return (
                f"footprint is self-intersecting: edge {int(i[k])}–{int(i[k]) + 1} crosses"
                f" edge {int(j[k])}–{(int(j[k]) + 1) % n}"
            )
    x, y = vertices[:, 0], vertices[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    if area < MIN_FOOTPRINT_AREA_M2:
        return f"footprint has zero area ({area:.3g} m²): its vertices are collinear"
    return None


def signed_area(vertices: FloatArray) -> float:
    """The signed area of a polygon [n, 2] (positive counter-clockwise)."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def closed_ccw_ring(vertices: FloatArray) -> list[list[float]]:
    """An open vertex list [n, 2] → a closed, counter-clockwise GeoJSON ring."""
    v = np.asarray(vertices, dtype=float)
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    if signed_area(v) < 0:
        v = v[::-1]
    ring = v.tolist()
    return [*ring, ring[0]]


class Prism(ObstacleModel):
    """A vertical extrusion of a simple polygon between ``base_m`` and ``base_m + height_m``."""

    kind_name: ClassVar[str] = "prism"
    kind: Literal["prism"] = Field("prism", description="Obstacle kind (discriminator)")
    footprint: list[Point2] = Field(
        min_length=1,
        max_length=MAX_FOOTPRINT_VERTICES,
        description="Polygon vertices [x, y] in metres, any winding, not closed",
    )

    @field_validator("footprint")
    @classmethod
    def _finite(cls, v: list[list[float]]) -> list[list[float]]:
        pts = [finite_point(p, "footprint vertex") for p in v]
        if len(pts) > 3 and pts[0] == pts[-1]:  # a closed ring (GeoJSON habit): open it
            pts = pts[:-1]
        return pts

    @model_validator(mode="after")
    def _simple(self) -> Prism:
        problem = footprint_problem(np.asarray(self.footprint, dtype=float))
        if problem is not None:
            raise ValueError(f"{label('prism', self.name)}: {problem}")
        return self

    @property
    def vertices(self) -> FloatArray:
        """[n, 2] footprint vertices."""
        return np.asarray(self.footprint, dtype=float)

    def faces(self) -> Faces:
        """One outward-facing face per footprint edge (edge k from vertex k to k + 1)."""
        v = self.vertices
        w = np.roll(v, -1, axis=0)
        e = w - v
        side = 1.0 if signed_area(v) > 0 else -1.0  # counter-clockwise: the outside is on the right
        length = np.hypot(e[:, 0], e[:, 1])
        normal = side * np.column_stack([e[:, 1], -e[:, 0]]) / length[:, None]
        return Faces(v, w, normal, False)

    def outline(self) -> FloatArray:
        return self.vertices

    def work_units(self) -> int:
        return len(self.footprint)


# ---- the narrow phase -------------------------------------------------------------------


def point_depth(p: FloatArray, verts: FloatArray, base: FloatArray, top: FloatArray) -> FloatArray:
    """How far points p [K, 3] lie inside prisms (footprints verts [K, n, 2], slabs base, top
    [K]): the distance to the nearest face inside, 0 on or outside the footprint."""
    v0 = verts
    v1 = np.roll(verts, -1, axis=1)
    px, py = p[:, None, 0], p[:, None, 1]
    # [K, n] even-odd crossing number of a ray towards +x
    straddle = (v0[..., 1] > py) != (v1[..., 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = v0[..., 0] + (py - v0[..., 1]) * (v1[..., 0] - v0[..., 0]) / (
            v1[..., 1] - v0[..., 1]
        )
    inside = np.count_nonzero(straddle & (px < x_cross), axis=1) % 2 == 1
    # [K, n] distance to each edge segment
    e = v1 - v0
    wx, wy = px - v0[..., 0], py - v0[..., 1]
    ee = e[..., 0] ** 2 + e[..., 1] ** 2
    s = np.clip((wx * e[..., 0] + wy * e[..., 1]) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    qx, qy = wx - s * e[..., 0], wy - s * e[..., 1]
    dist = np.sqrt((qx * qx + qy * qy).min(axis=1))
    dz = np.minimum(p[:, 2] - base, top - p[:, 2])
    return np.asarray(np.where(inside, np.minimum(dist, dz), 0.0))


def _slab_interval(
    az: FloatArray, dz: FloatArray, lo_z: FloatArray, hi_z: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """[K] the parameter range within [0, 1] where lo_z < az + t·dz < hi_z (empty: lo ≥ hi)."""
    flat = dz == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo_z - az) / dz
        t2 = (hi_z - az) / dz
    inside = (az > lo_z) & (az < hi_z)
    lo = np.where(flat, np.where(inside, 0.0, 1.0), np.maximum(0.0, np.minimum(t1, t2)))
    hi = np.where(flat, np.where(inside, 1.0, 0.0), np.minimum(1.0, np.maximum(t1, t2)))
    return np.asarray(lo), np.asarray(hi)


def _linear_range(c0: FloatArray, c1: FloatArray, lo: float, hi: float) -> tuple[FloatArray, ...]:
    """The t range where lo ≤ c0 + c1·t ≤ hi (elementwise; ±inf when c1 = 0 and inside)."""
    flat = c1 == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (lo - c0) / c1
        tb = (hi - c0) / c1
    ok = (c0 >= lo) & (c0 <= hi)
    start = np.where(flat, np.where(ok, -np.inf, np.inf), np.minimum(ta, tb))
    stop = np.where(flat, np.where(ok, np.inf, -np.inf), np.maximum(ta, tb))
    return start, stop


def _has_gap(q0: FloatArray, q1: FloatArray, start: FloatArray, stop: FloatArray) -> BoolArray:
    """[K] whether the closed intervals [start, stop] ([K, m]) leave part of (q0, q1) uncovered."""
    order = np.argsort(start, axis=1)
    s = np.take_along_axis(start, order, axis=1)
    e = np.take_along_axis(stop, order, axis=1)
    # [K, m + 1] furthest point covered before each interval starts
    reach = np.maximum.accumulate(np.concatenate([q0[:, None], e], axis=1), axis=1)
    gap_before = np.any((s > reach[:, :-1]) & (reach[:, :-1] < q1[:, None]), axis=1)
    return np.asarray((q0 < q1) & (gap_before | (reach[:, -1] < q1)))


def _deep_in_piece(
    a: FloatArray,
    d: FloatArray,
    verts: FloatArray,
    base: FloatArray,
    top: FloatArray,
    p0: FloatArray,
    p1: FloatArray,
    tol: float,
) -> BoolArray:
    """[K] whether a leg piece a + t·d, t ∈ (p0, p1), that lies inside the footprint contains a
    point more than tol from every face: the piece, shortened to base + tol < z < top − tol,
    is not covered by the tol-capsules of the footprint edges (disks at the vertices and
    rectangles along the edges, each meeting the leg's line in one interval)."""
    zlo, zhi = _slab_interval(a[:, 2], d[:, 2], base + tol, top - tol)
    q0, q1 = np.maximum(p0, zlo), np.minimum(p1, zhi)
    dxy = d[:, :2]
    dd = np.sum(dxy * dxy, axis=1)
    norm = np.sqrt(dd)
    rel = verts - a[:, None, :2]  # [K, n, 2] V − a
    # [K, n] position of each vertex along the line (in t) and its signed distance from it
    along = (rel[..., 0] * dxy[:, None, 0] + rel[..., 1] * dxy[:, None, 1]) / dd[:, None]
    perp = (dxy[:, None, 0] * rel[..., 1] - dxy[:, None, 1] * rel[..., 0]) / norm[:, None]
    half = np.sqrt(np.maximum(tol * tol - perp * perp, 0.0)) / norm[:, None]
    near = np.abs(perp) <= tol
    disk0 = np.where(near, along - half, np.inf)
    disk1 = np.where(near, along + half, -np.inf)
    # [K, n] rectangles: 0 ≤ s(t) ≤ 1 along the edge and |r(t)| ≤ tol across it
    e = np.roll(verts, -1, axis=1) - verts
    elen2 = np.sum(e * e, axis=2)
    elen = np.sqrt(elen2)
    good = elen2 > 0
    safe2, safe = np.where(good, elen2, 1.0), np.where(good, elen, 1.0)
    s0 = -(rel[..., 0] * e[..., 0] + rel[..., 1] * e[..., 1]) / safe2
    s1 = (dxy[:, None, 0] * e[..., 0] + dxy[:, None, 1] * e[..., 1]) / safe2
    r0 = (e[..., 1] * rel[..., 0] - e[..., 0] * rel[..., 1]) / safe
    r1 = (e[..., 0] * dxy[:, None, 1] - e[..., 1] * dxy[:, None, 0]) / safe
    sa, sb = _linear_range(s0, s1, 0.0, 1.0)
    ra, rb = _linear_range(r0, r1, -tol, tol)
    rect0 = np.where(good, np.maximum(sa, ra), np.inf)
    rect1 = np.where(good, np.minimum(sb, rb), -np.inf)
    start = np.concatenate([disk0, rect0], axis=1)
    stop = np.concatenate([disk1, rect1], axis=1)
    empty = ~(start <= stop)
    start = np.where(empty, np.inf, start)  # empty intervals sort last
    stop = np.where(empty, -np.inf, stop)
    return _has_gap(q0, q1, start, stop)


def prism_blocks(
    a: FloatArray,
    b: FloatArray,
    verts: FloatArray,
    base: FloatArray,
    top: FloatArray,
    tol: float,
) -> BoolArray:
    """[K] whether leg a[k]–b[k] ([K, 3]) has a point more than tol inside prism k (footprint
    verts [K, n, 2], slab base–top [K]): max over the leg of the point depth > tol.

    The leg's line is cut at its crossings with the footprint edges (even-odd, so the pieces
    between crossings alternate outside/inside) and clipped to the open slab. An inside piece
    is decided at once when it is short (a piece with an end on a face, no longer than tol, has
    depth ≤ tol everywhere: the depth is 1-Lipschitz) or its midpoint is deeper than tol;
    otherwise exactly by :func:`_deep_in_piece`.
    """
    k, n = verts.shape[0], verts.shape[1]
    out = np.zeros(k, dtype=bool)
    if k == 0:
        return out
    d = b - a
    dxy = d[:, :2]
    dd = np.sum(dxy * dxy, axis=1)
    vertical = dd <= XY_DEGENERATE_M**2
    if np.any(vertical):
        # depth along a vertical leg: min(xy depth, z depth); the z depth peaks mid-slab
        iv = np.nonzero(vertical)[0]
        zmin = np.minimum(a[iv, 2], b[iv, 2])
        zmax = np.maximum(a[iv, 2], b[iv, 2])
        z = np.clip(0.5 * (base[iv] + top[iv]), zmin, zmax)
        p = np.column_stack([0.5 * (a[iv, :2] + b[iv, :2]), z])
        out[iv] = point_depth(p, verts[iv], base[iv], top[iv]) > tol
    ig = np.nonzero(~vertical)[0]
    if ig.size == 0:
        return out
    a, d, verts, base, top, dxy, dd = a[ig], d[ig], verts[ig], base[ig], top[ig], dxy[ig], dd[ig]
    lo, hi = _slab_interval(a[:, 2], d[:, 2], base, top)
    rel = verts - a[:, None, :2]
    # [K, n] side of each vertex (cross(d, V − a) > 0) and its projection along the line (t)
    o = dxy[:, None, 0] * rel[..., 1] - dxy[:, None, 1] * rel[..., 0]
    along = (rel[..., 0] * dxy[:, None, 0] + rel[..., 1] * dxy[:, None, 1]) / dd[:, None]
    o1, along1 = np.roll(o, -1, axis=1), np.roll(along, -1, axis=1)
    straddle = (o > 0) != (o1 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cross = along + (along1 - along) * (o / (o - o1))
    # [K, n] sorted crossings; pieces (t_2i, t_2i+1) lie inside the footprint
    ts = np.sort(np.where(straddle, t_cross, np.inf), axis=1)
    m = n // 2
    p0 = np.maximum(ts[:, 0 : 2 * m : 2], lo[:, None])
    p1 = np.minimum(ts[:, 1 : 2 * m : 2], hi[:, None])
    length = (p1 - p0) * np.linalg.norm(d, axis=1)[:, None]
    short = (length <= tol) & ((p0 > 0.0) | (p1 < 1.0))
    todo = (p1 > p0) & ~short
    rows, cols = np.nonzero(todo)
    if rows.size == 0:
        return out
    q0, q1 = p0[rows, cols], p1[rows, cols]
    mid = a[rows] + (0.5 * (q0 + q1))[:, None] * d[rows]
    deep = point_depth(mid, verts[rows], base[rows], top[rows]) > tol
    hit = np.zeros(ig.size, dtype=bool)
    hit[rows[deep]] = True
    open_ = ~deep & ~hit[rows]
    if np.any(open_):
        r2 = rows[open_]
        exact = _deep_in_piece(
            a[r2], d[r2], verts[r2], base[r2], top[r2], q0[open_], q1[open_], tol
        )
        hit[r2[exact]] = True
    out[ig] = hit
    return out


def _bucket(n: int) -> int:
    """Padded vertex count for a footprint of n vertices (powers of two, at least 4)."""
    return max(4, 1 << (n - 1).bit_length())


@dataclass(frozen=True)
class PackedPrisms:
    """Footprints grouped by padded size: obstacle r is row ``row[r]`` of ``verts[bucket[r]]``
    ([Nb, nb, 2]); ``base``, ``top`` [N]."""

    bucket: IntArray
    row: IntArray
    verts: list[FloatArray]
    base: FloatArray
    top: FloatArray


class PrismKind:
    """The ``prism`` kind (solid; compiled engine: yes; a GeoJSON Polygon)."""

    name: str = "prism"
    model: type[ObstacleModel] = Prism
    solid: bool = True
    compiled: bool = True
    point_fields: tuple[tuple[str, ...], ...] = (("footprint", "*"),)
    draw: dict[str, Any] = {"shape": "polygon", "points": "footprint", "label": "building"}  # noqa: RUF012

    def to_geojson(self, obstacle: Prism, xy: ToOutput) -> tuple[GeoJSON, GeoJSON]:
        """A Polygon: the footprint as a closed counter-clockwise ring."""
        return {"type": "Polygon", "coordinates": [closed_ccw_ring(xy(obstacle.vertices))]}, {}

    def from_geojson(self, geometry: GeoJSON, properties: GeoJSON) -> dict[str, Any]:
        """``footprint`` from a Polygon without holes (its ring's closing position dropped)."""
        rings = coordinates(geometry, self.name, "Polygon")
        if not isinstance(rings, list) or len(rings) != 1 or not isinstance(rings[0], list):
            raise GeometryError("a prism feature's Polygon has one ring (no holes)")
        ring = [position_xy(p) for p in rings[0]]
        if len(ring) > 3 and ring[0] == ring[-1]:
            ring = ring[:-1]
        return {"footprint": ring}

    def pack(self, obstacles: list[Any]) -> PackedPrisms:
        n = len(obstacles)
        bucket, row = np.full(n, -1), np.zeros(n, dtype=int)
        sizes: list[int] = []
        groups: list[list[FloatArray]] = []
        for k, o in enumerate(obstacles):
            v = o.vertices
            size = _bucket(v.shape[0])
            if size not in sizes:
                sizes.append(size)
                groups.append([])
            g = sizes.index(size)
            bucket[k], row[k] = g, len(groups[g])
            groups[g].append(np.concatenate([v, np.repeat(v[-1:], size - v.shape[0], 0)]))
        return PackedPrisms(
            bucket,
            row,
            [np.stack(g) for g in groups],
            np.array([o.base_m for o in obstacles], dtype=float),
            np.array([o.top_m for o in obstacles], dtype=float),
        )

    def blocks(
        self, packed: PackedPrisms, rows: IntArray, a: FloatArray, b: FloatArray, tol: float
    ) -> BoolArray:
        out = np.zeros(rows.size, dtype=bool)
        bucket = packed.bucket[rows]
        for g, verts in enumerate(packed.verts):
            sel = bucket == g
            if np.any(sel):
                o = rows[sel]
                out[sel] = prism_blocks(
                    a[sel], b[sel], verts[packed.row[o]], packed.base[o], packed.top[o], tol
                )
        return out

    def depth(self, packed: PackedPrisms, rows: IntArray, points: FloatArray) -> FloatArray:
        out = np.zeros(rows.size)
        bucket = packed.bucket[rows]
        for g, verts in enumerate(packed.verts):
            sel = np.nonzero(bucket == g)[0]
            if sel.size:
                o = rows[sel]
                out[sel] = point_depth(
                    points[sel], verts[packed.row[o]], packed.base[o], packed.top[o]
                )
        return out


KIND = PrismKind()
