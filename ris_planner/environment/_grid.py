"""Broad phase: a uniform 2-D grid of obstacle boxes, walked by every leg in order (DDA).

Each obstacle's box (padded by :data:`BOX_PAD_M`) is registered in every cell it overlaps,
with twice the pad, so rounding in the walk can never miss it. A leg visits its cells in
order from its start (Amanatides–Woo, vectorised over legs); in each cell it meets the
obstacles whose padded 3-D box it enters inside that cell's stretch of the leg – so each
(leg, obstacle) pair with overlapping boxes is tested exactly once, and a leg leaves the walk
as soon as it is blocked.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

BOX_PAD_M = 1e-2
"""Obstacle boxes are grown by this (1 cm ≥ any visibility tolerance) before broad-phase tests."""

MAX_CELLS = 1 << 20
"""Largest grid (cells); coarser cells beyond it."""

MAX_REGISTRATIONS_PER_OBSTACLE = 64
"""Cells per obstacle on average at most (a few huge boxes among small ones coarsen the grid)."""

CHUNK_LEGS = 1 << 17
"""Legs walked together (bounds the temporary arrays to tens of MB)."""

PairTest = Callable[[IntArray, IntArray], BoolArray]
"""(leg indices [K], obstacle indices [K]) → [K] blocked."""


@dataclass(frozen=True)
class Grid:
    """Obstacle boxes box_lo, box_hi [N, 3] (padded) in cells of size h from (x0, y0)."""

    box_lo: FloatArray
    box_hi: FloatArray
    x0: float
    y0: float
    h: float
    nx: int
    ny: int
    cell_start: IntArray  # [nx·ny + 1] CSR offsets into cell_items
    cell_items: IntArray  # obstacle indices, cell by cell

    @classmethod
    def build(cls, box_lo: FloatArray, box_hi: FloatArray) -> Grid:
        pad = np.array([BOX_PAD_M, BOX_PAD_M, BOX_PAD_M])
        lo, hi = box_lo - pad, box_hi + pad
        reg_lo, reg_hi = lo[:, :2] - BOX_PAD_M, hi[:, :2] + BOX_PAD_M
        x0, y0 = reg_lo.min(axis=0)
        width, height = reg_hi.max(axis=0) - np.array([x0, y0])
        size = np.median(np.max(reg_hi - reg_lo, axis=1))
        h = float(max(size, np.sqrt(width * height / MAX_CELLS), 1e-3))
        while True:  # coarser cells until the registrations fit
            nx = max(1, int(np.ceil(width / h)))
            ny = max(1, int(np.ceil(height / h)))
            i0 = np.clip(np.floor((reg_lo[:, 0] - x0) / h).astype(int), 0, nx - 1)
            i1 = np.clip(np.floor((reg_hi[:, 0] - x0) / h).astype(int), 0, nx - 1)
            j0 = np.clip(np.floor((reg_lo[:, 1] - y0) / h).astype(int), 0, ny - 1)
            j1 = np.clip(np.floor((reg_hi[:, 1] - y0) / h).astype(int), 0, ny - 1)
            wi, wj = i1 - i0 + 1, j1 - j0 + 1
            counts = wi * wj
            if counts.sum() <= MAX_REGISTRATIONS_PER_OBSTACLE * lo.shape[0] or nx * ny == 1:
                break
            h *= 2.0
        ob = np.repeat(np.arange(lo.shape[0]), counts)
        k = np.arange(ob.size) - np.repeat(np.cumsum(counts) - counts, counts)
        cell = (i0[ob] + k // wj[ob]) * ny + (j0[ob] + k % wj[ob])
        order = np.argsort(cell, kind="stable")
        start = np.zeros(nx * ny + 1, dtype=int)
        np.add.at(start, cell + 1, 1)
        return cls(lo, hi, float(x0), float(y0), h, nx, ny, np.cumsum(start), ob[order].astype(int))

    def box_entry(
        self, a: FloatArray, d: FloatArray, ob: IntArray
    ) -> tuple[FloatArray, FloatArray]:
        """[K] parameters where legs a + t·d, t ∈ [0, 1], enter and leave obstacle boxes."""
        lo, hi = self.box_lo[ob], self.box_hi[ob]
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo - a) / d
            t2 = (hi - a) / d
        flat = d == 0
        inside = (a >= lo) & (a <= hi)
        tmin = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        tmax = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        return np.maximum(tmin.max(axis=1), 0.0), np.minimum(tmax.min(axis=1), 1.0)

    def walk(self, a: FloatArray, b: FloatArray, test: PairTest) -> BoolArray:
        """[M] whether ``test`` reports a blocking obstacle for leg a[i]–b[i] ([M, 3])."""
        m = a.shape[0]
        out = np.zeros(m, dtype=bool)
        for c0 in range(0, m, CHUNK_LEGS):
            sl = slice(c0, min(m, c0 + CHUNK_LEGS))
            out[sl] = self._walk_chunk(a[sl], b[sl], c0, test)
        return out

    def _walk_chunk(self, a: FloatArray, b: FloatArray, offset: int, test: PairTest) -> BoolArray:
        m = a.shape[0]
        blocked = np.zeros(m, dtype=bool)
        d = b - a
        # [M] the leg's stretch inside the grid's xy rectangle and the obstacles' z range
        gx1, gy1 = self.x0 + self.nx * self.h, self.y0 + self.ny * self.h
        lo3 = np.array([self.x0, self.y0, self.box_lo[:, 2].min()])
        hi3 = np.array([gx1, gy1, self.box_hi[:, 2].max()])
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo3 - a) / d
            t2 = (hi3 - a) / d
        flat = d == 0
        inside = (a >= lo3) & (a <= hi3)
        tmin = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        tmax = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        tg0 = np.maximum(tmin.max(axis=1), 0.0)
        tg1 = np.minimum(tmax.min(axis=1), 1.0)
        act = np.nonzero(tg0 <= tg1)[0]
        if act.size == 0:
            return blocked
        a, d, tg0, tg1 = a[act], d[act], tg0[act], tg1[act]
        h = self.h
        p = a[:, :2] + tg0[:, None] * d[:, :2]
        i = np.clip(np.floor((p[:, 0] - self.x0) / h).astype(int), 0, self.nx - 1)
        j = np.clip(np.floor((p[:, 1] - self.y0) / h).astype(int), 0, self.ny - 1)
        sx = np.where(d[:, 0] > 0, 1, -1)
        sy = np.where(d[:, 1] > 0, 1, -1)

        live = np.arange(act.size)  # rows of the walk still running
        tx = next_t_rows(i, sx, live, self.x0, h, a, d, 0)
        ty = next_t_rows(j, sy, live, self.y0, h, a, d, 1)
        t_enter = np.full(act.size, -np.inf)
        while live.size:
            t_exit = np.minimum(tx, ty)
            last = t_exit >= tg1[live]
            t_stop = np.where(last, np.inf, t_exit)
            cell = i * self.ny + j
            s, e = self.cell_start[cell], self.cell_start[cell + 1]
            counts = e - s
            if counts.sum():
                row = np.repeat(np.arange(live.size), counts)
                k = np.arange(row.size) - np.repeat(np.cumsum(counts) - counts, counts)
                ob = self.cell_items[s[row] + k]
                src = live[row]
                tin, tout = self.box_entry(a[src], d[src], ob)
                keep = (tin <= tout) & (tin >= t_enter[row]) & (tin < t_stop[row])
                if np.any(keep):
                    legs = act[src[keep]]
                    hit = test(legs + offset, ob[keep])
                    blocked[legs[hit]] = True
            # advance: along x where its next grid line comes first, else along y
            move_x = tx < ty
            i = np.where(move_x, i + sx[live], i)
            j = np.where(move_x, j, j + sy[live])
            stay = ~last & ~blocked[act[live]] & (i >= 0) & (i < self.nx) & (j >= 0)
            stay &= j < self.ny
            t_enter = t_exit
            i, j, t_enter = i[stay], j[stay], t_enter[stay]
            live = live[stay]
            tx = np.where(move_x[stay], next_t_rows(i, sx, live, self.x0, h, a, d, 0), tx[stay])
            ty = np.where(move_x[stay], ty[stay], next_t_rows(j, sy, live, self.y0, h, a, d, 1))
        return blocked


def next_t_rows(
    idx: IntArray,
    step: IntArray,
    rows: IntArray,
    origin: float,
    h: float,
    a: FloatArray,
    d: FloatArray,
    axis: int,
) -> FloatArray:
    """[R] parameter where legs ``rows`` cross the next grid line after cell ``idx``."""
    st = step[rows]
    edge = origin + (idx + (st > 0)) * h
    dk = d[rows, axis]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (edge - a[rows, axis]) / dk
    return np.asarray(np.where(dk == 0, np.inf, t))
