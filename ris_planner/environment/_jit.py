"""The compiled engine (numba): the grid walk of :mod:`~ris_planner.environment._grid` and the
exact tests of the kinds (:mod:`~ris_planner.environment.kinds.prism`,
:mod:`~ris_planner.environment.kinds.wall`), one leg at a time in machine code.

Same rules, same formulas, same operation order as the numpy engine (tests compare the two
answer for answer); a leg stops at its first blocking obstacle. Imported lazily by
:class:`~ris_planner.environment.scene.Scene` (numba takes ~1 s to import; compiled code is
cached next to this file).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ris_planner.environment.kinds.prism import XY_DEGENERATE_M
from ris_planner.runtime.allocator import ensure_numba_cache

ensure_numba_cache(__file__)  # before any @njit(cache=True): a writable cache folder

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

_INF = math.inf


@njit(cache=True, nogil=True)
def _slab(az: float, dz: float, lo_z: float, hi_z: float) -> tuple[float, float]:
    if dz == 0.0:
        if az > lo_z and az < hi_z:
            return 0.0, 1.0
        return 1.0, 0.0
    t1 = (lo_z - az) / dz
    t2 = (hi_z - az) / dz
    return max(0.0, min(t1, t2)), min(1.0, max(t1, t2))


@njit(cache=True, nogil=True)
def _point_depth(px: float, py: float, pz: float, v: FloatArray, base: float, top: float) -> float:
    n = v.shape[0]
    crossings = 0
    dist = _INF
    for k in range(n):
        x0, y0 = v[k, 0], v[k, 1]
        k1 = k + 1 if k + 1 < n else 0
        x1, y1 = v[k1, 0], v[k1, 1]
        if (y0 > py) != (y1 > py):
            xc = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
            if px < xc:
                crossings += 1
        ex, ey = x1 - x0, y1 - y0
        wx, wy = px - x0, py - y0
        ee = ex * ex + ey * ey
        s = (wx * ex + wy * ey) / (ee if ee > 0 else 1.0)
        s = min(max(s, 0.0), 1.0)
        qx, qy = wx - s * ex, wy - s * ey
        dist = min(dist, qx * qx + qy * qy)
    if crossings % 2 == 0:
        return 0.0
    return min(math.sqrt(dist), min(pz - base, top - pz))


@njit(cache=True, nogil=True)
def _linear_range(c0: float, c1: float, lo: float, hi: float) -> tuple[float, float]:
    if c1 == 0.0:
        if c0 >= lo and c0 <= hi:
            return -_INF, _INF
        return _INF, -_INF
    ta = (lo - c0) / c1
    tb = (hi - c0) / c1
    return min(ta, tb), max(ta, tb)


@njit(cache=True, nogil=True)
def _deep_in_piece(
    a: FloatArray,
    d: FloatArray,
    v: FloatArray,
    base: float,
    top: float,
    p0: float,
    p1: float,
    tol: float,
    start: FloatArray,
    stop: FloatArray,
) -> bool:
    zlo, zhi = _slab(a[2], d[2], base + tol, top - tol)
    q0, q1 = max(p0, zlo), min(p1, zhi)
    if not q0 < q1:
        return False
    n = v.shape[0]
    dx, dy = d[0], d[1]
    dd = dx * dx + dy * dy
    norm = math.sqrt(dd)
    for k in range(n):
        rx, ry = v[k, 0] - a[0], v[k, 1] - a[1]
        along = (rx * dx + ry * dy) / dd
        perp = (dx * ry - dy * rx) / norm
        if abs(perp) <= tol:
            half = math.sqrt(max(tol * tol - perp * perp, 0.0)) / norm
            start[k], stop[k] = along - half, along + half
        else:
            start[k], stop[k] = _INF, -_INF
        k1 = k + 1 if k + 1 < n else 0
        ex, ey = v[k1, 0] - v[k, 0], v[k1, 1] - v[k, 1]
        elen2 = ex * ex + ey * ey
        if elen2 > 0:
            elen = math.sqrt(elen2)
            s0 = -(rx * ex + ry * ey) / elen2
            s1 = (dx * ex + dy * ey) / elen2
            r0 = (ey * rx - ex * ry) / elen
            r1 = (ex * dy - ey * dx) / elen
            sa, sb = _linear_range(s0, s1, 0.0, 1.0)
            ra, rb = _linear_range(r0, r1, -tol, tol)
            start[n + k], stop[n + k] = max(sa, ra), min(sb, rb)
        else:
            start[n + k], stop[n + k] = _INF, -_INF
    m = 2 * n
    for k in range(m):
        if not start[k] <= stop[k]:
            start[k], stop[k] = _INF, -_INF
    order = np.argsort(start[:m])
    reach = q0
    for k in range(m):
        s = start[order[k]]
        if s > reach and reach < q1:
            return True
        reach = max(reach, stop[order[k]])
    return reach < q1


@njit(cache=True, nogil=True)
def _prism_blocks(
    a: FloatArray,
    d: FloatArray,
    v: FloatArray,
    base: float,
    top: float,
    tol: float,
    ts: FloatArray,
    start: FloatArray,
    stop: FloatArray,
) -> bool:
    dx, dy = d[0], d[1]
    dd = dx * dx + dy * dy
    if dd <= XY_DEGENERATE_M * XY_DEGENERATE_M:
        zmin = min(a[2], a[2] + d[2])
        zmax = max(a[2], a[2] + d[2])
        z = min(max(0.5 * (base + top), zmin), zmax)
        px, py = a[0] + 0.5 * dx, a[1] + 0.5 * dy
        return _point_depth(px, py, z, v, base, top) > tol
    lo, hi = _slab(a[2], d[2], base, top)
    if not lo < hi:
        return False
    n = v.shape[0]
    c = 0
    for k in range(n):
        rx, ry = v[k, 0] - a[0], v[k, 1] - a[1]
        k1 = k + 1 if k + 1 < n else 0
        rx1, ry1 = v[k1, 0] - a[0], v[k1, 1] - a[1]
        o = dx * ry - dy * rx
        o1 = dx * ry1 - dy * rx1
        if (o > 0) != (o1 > 0):
            along = (rx * dx + ry * dy) / dd
            along1 = (rx1 * dx + ry1 * dy) / dd
            ts[c] = along + (along1 - along) * (o / (o - o1))
            c += 1
    if c == 0:
        return False
    for q in range(1, c):  # insertion sort: c is small, and no allocation
        x = ts[q]
        r = q - 1
        while r >= 0 and ts[r] > x:
            ts[r + 1] = ts[r]
            r -= 1
        ts[r + 1] = x
    t = ts
    norm3 = math.sqrt(dd + d[2] * d[2])
    for q in range(c // 2):
        p0 = max(t[2 * q], lo)
        p1 = min(t[2 * q + 1], hi)
        if not p1 > p0:
            continue
        if (p1 - p0) * norm3 <= tol and (p0 > 0.0 or p1 < 1.0):
            continue
        tm = 0.5 * (p0 + p1)
        depth = _point_depth(a[0] + tm * dx, a[1] + tm * dy, a[2] + tm * d[2], v, base, top)
        if depth > tol:
            return True
        if _deep_in_piece(a, d, v, base, top, p0, p1, tol, start, stop):
            return True
    return False


@njit(cache=True, nogil=True)
def _wall_blocks(
    a: FloatArray, d: FloatArray, w: FloatArray, base: float, top: float, tol: float
) -> bool:
    sx, sy, ex, ey = w[0], w[1], w[2], w[3]
    length = math.hypot(ex - sx, ey - sy)
    ux, uy = (ex - sx) / length, (ey - sy) / length
    nx, ny = -uy, ux
    sa = (a[0] - sx) * nx + (a[1] - sy) * ny
    sb = (a[0] + d[0] - sx) * nx + (a[1] + d[1] - sy) * ny
    if not (sa * sb < 0 and abs(sa) > tol and abs(sb) > tol):
        return False
    t = sa / (sa - sb)
    px, py, pz = a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]
    along = (px - sx) * ux + (py - sy) * uy
    return along > tol and along < length - tol and pz > base + tol and pz < top - tol


@njit(cache=True, nogil=True)
def _walk_range(
    lo_leg: int,
    hi_leg: int,
    out: BoolArray,
    a_all: FloatArray,
    b_all: FloatArray,
    tol: float,
    x0: float,
    y0: float,
    h: float,
    nx: int,
    ny: int,
    cell_start: IntArray,
    cell_items: IntArray,
    box_lo: FloatArray,
    box_hi: FloatArray,
    is_wall: BoolArray,
    base: FloatArray,
    top: FloatArray,
    wall: FloatArray,
    vert_start: IntArray,
    verts: FloatArray,
) -> None:
    """out[lo_leg:hi_leg]: blocked legs a_all[i]–b_all[i] (the grid walk of _grid)."""
    max_n = 1
    for k in range(vert_start.shape[0] - 1):
        max_n = max(max_n, vert_start[k + 1] - vert_start[k])
    ts = np.empty(max_n)
    start = np.empty(2 * max_n)
    stop = np.empty(2 * max_n)
    glo = np.array([x0, y0, box_lo[:, 2].min()])
    ghi = np.array([x0 + nx * h, y0 + ny * h, box_hi[:, 2].max()])
    d = np.empty(3)
    for leg in range(lo_leg, hi_leg):
        a = a_all[leg]
        for k in range(3):
            d[k] = b_all[leg, k] - a[k]
        tg0, tg1 = 0.0, 1.0
        for k in range(3):
            if d[k] == 0.0:
                if not (a[k] >= glo[k] and a[k] <= ghi[k]):
                    tg0, tg1 = 1.0, 0.0
            else:
                t1 = (glo[k] - a[k]) / d[k]
                t2 = (ghi[k] - a[k]) / d[k]
                tg0 = max(tg0, min(t1, t2))
                tg1 = min(tg1, max(t1, t2))
        if not tg0 <= tg1:
            continue
        i = math.floor((a[0] + tg0 * d[0] - x0) / h)
        j = math.floor((a[1] + tg0 * d[1] - y0) / h)
        i = min(max(i, 0), nx - 1)
        j = min(max(j, 0), ny - 1)
        sx = 1 if d[0] > 0 else -1
        sy = 1 if d[1] > 0 else -1
        tx = (x0 + (i + (1 if sx > 0 else 0)) * h - a[0]) / d[0] if d[0] != 0 else _INF
        ty = (y0 + (j + (1 if sy > 0 else 0)) * h - a[1]) / d[1] if d[1] != 0 else _INF
        t_enter = -_INF
        while True:
            t_exit = min(tx, ty)
            last = t_exit >= tg1
            t_stop = _INF if last else t_exit
            cell = i * ny + j
            for q in range(cell_start[cell], cell_start[cell + 1]):
                k = cell_items[q]
                tin, tout = 0.0, 1.0
                for ax in range(3):
                    if d[ax] == 0.0:
                        if not (a[ax] >= box_lo[k, ax] and a[ax] <= box_hi[k, ax]):
                            tin, tout = _INF, -_INF
                    else:
                        t1 = (box_lo[k, ax] - a[ax]) / d[ax]
                        t2 = (box_hi[k, ax] - a[ax]) / d[ax]
                        tin = max(tin, min(t1, t2))
                        tout = min(tout, max(t1, t2))
                if not (tin <= tout and tin >= t_enter and tin < t_stop):
                    continue
                if is_wall[k]:
                    hit = _wall_blocks(a, d, wall[k], base[k], top[k], tol)
                else:
                    v = verts[vert_start[k] : vert_start[k + 1]]
                    hit = _prism_blocks(a, d, v, base[k], top[k], tol, ts, start, stop)
                if hit:
                    out[leg] = True
                    break
            if out[leg] or last:
                break
            if tx < ty:
                i += sx
                tx = (x0 + (i + (1 if sx > 0 else 0)) * h - a[0]) / d[0]
            else:
                j += sy
                ty = (y0 + (j + (1 if sy > 0 else 0)) * h - a[1]) / d[1]
            if i < 0 or i >= nx or j < 0 or j >= ny:
                break
            t_enter = t_exit


CHUNK = 4096
"""Legs per parallel task (each task has its own scratch arrays)."""


@njit(cache=True, nogil=True, parallel=True)
def walk(
    a_all: FloatArray,
    b_all: FloatArray,
    tol: float,
    x0: float,
    y0: float,
    h: float,
    nx: int,
    ny: int,
    cell_start: IntArray,
    cell_items: IntArray,
    box_lo: FloatArray,
    box_hi: FloatArray,
    is_wall: BoolArray,
    base: FloatArray,
    top: FloatArray,
    wall: FloatArray,
    vert_start: IntArray,
    verts: FloatArray,
) -> BoolArray:
    """[M] blocked legs a_all[i]–b_all[i] ([M, 3]), chunks of legs in parallel."""
    m = a_all.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    for c in prange((m + CHUNK - 1) // CHUNK):
        _walk_range(
            c * CHUNK,
            min(m, (c + 1) * CHUNK),
            out,
            a_all,
            b_all,
            tol,
            x0,
            y0,
            h,
            nx,
            ny,
            cell_start,
            cell_items,
            box_lo,
            box_hi,
            is_wall,
            base,
            top,
            wall,
            vert_start,
            verts,
        )
    return out
