"""Visibility of legs against prisms and walls, batched over legs.

Rules (concepts/environment.md; ``tol`` = :data:`VISIBILITY_TOLERANCE_M`, the depth of a point in a
prism = its distance to the nearest face when inside, ≤ 0 outside):

* wall: a leg A→B is blocked when A and B lie on strictly opposite sides of the wall's
  vertical plane, each more than ``tol`` from it, and the crossing point lies inside the wall
  rectangle by more than ``tol`` (from its ends, its bottom and its top).
* prism: a leg is blocked when some point of it lies more than ``tol`` inside the prism (the
  maximum depth along the leg exceeds ``tol``), evaluated exactly: the leg's line is cut at
  the footprint edges into inside pieces, clipped to the slab, and a piece blocks when it is
  not covered by the ``tol``-neighbourhood of the faces (disks at the footprint vertices,
  strips along its edges, the slab shrunk by ``tol``). So a leg that touches a face, runs along
  it within ``tol``, starts on a facade and leaves it (even a few ulps inside), or grazes the
  reflex corner of a notch from the notch is clear; one that is deeper than ``tol`` anywhere
  is blocked, also when the middle of its inside piece lies on a reflex corner.
  The rule is symmetric in A and B.
* inside: a point is inside a prism when its depth exceeds ``margin`` (:data:`INSIDE_MARGIN_M`).

The engine (exact float64): a uniform 2-D grid of padded obstacle boxes
(:mod:`~ris_planner.environment._grid`); every leg walks its cells in order and meets each
obstacle whose box it enters once, leaving the walk when blocked; the narrow phase is
:mod:`~ris_planner.environment.kinds` (each obstacle kind's own module: ``prism``, ``wall``;
an obstacle of an unregistered kind is an error naming the known kinds). The same algorithm
runs compiled (:mod:`~ris_planner.environment._jit`, numba, which implements the ``prism``
and ``wall`` kinds) for large queries, with the same answers; a scene holding a kind the
compiled engine does not implement uses the numpy engine.
Many points to one or a few sites: :meth:`Scene.blocked_to`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import cache, cached_property
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ris_planner.environment._grid import Grid
from ris_planner.environment.kinds import kind_of
from ris_planner.environment.kinds.base import ObstacleKind
from ris_planner.environment.model import Environment
from ris_planner.runtime.kernels import compiled_code_loaded, parallel_kernel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

Engine = Literal["auto", "numba", "numpy"]

AUTO_COMPILED_MIN_WORK = 10_000_000
"""``engine="auto"`` compiles (numba) from this many legs × obstacles per query on while the
process has loaded no compiled code: below it the numpy engine answers faster than setting numba
up (≈ 1–2 s once per process; the first compilation after an install takes 10–40 s and is
cached)."""

AUTO_COMPILED_WARM_MIN_WORK = 50_000
"""The same threshold once the process has loaded compiled code
(:func:`ris_planner.runtime.kernels.compiled_code_loaded`: a plan after its search, a service
that answered a plan): the walk then loads from the cache in ≈ 20 ms and runs 30–40× faster
than the numpy engine (29 obstacles of a city block: 1000 legs 0.5 against 12 ms, 200 000 legs
28 against 1100 ms, ``benchmarks/bounds/bench_visibility.py --warm``); below this numpy's ≈ 10 ms
beats the first load."""

VISIBILITY_TOLERANCE_M = 1e-3
"""Legs that enter a prism or cross a wall by no more than this (1 mm) are clear; the contract
allows any tolerance between 1 µm and 1 cm."""

INSIDE_MARGIN_M = 1e-2
"""A UE or RIS centre more than this (1 cm) inside a prism is inside it (environment.md)."""


def _points(p: FloatArray, name: str) -> FloatArray:
    """p as [M, 3] finite coordinates, or a ValueError naming the argument."""
    if p.ndim == 0 or p.shape[-1] != 3:
        raise ValueError(f"{name}: points must be [x, y, z] ([M, 3] or [3]), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name}: coordinates must be finite")
    return p.reshape(-1, 3)


@cache
def _compiled_engine_available() -> bool:
    """Whether the numba engine imports (``engine="auto"`` falls back to numpy otherwise)."""
    try:
        importlib.import_module("ris_planner.environment._jit")
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class _Index:
    """Obstacle arrays [N, …] in document order: each obstacle's kind (:data:`kinds`, position in
    ``kinds.KINDS`` order of first appearance) and its row in that kind's packed arrays."""

    kinds: tuple[ObstacleKind, ...]
    kind_id: IntArray  # [N] index into kinds
    row: IntArray  # [N] row in that kind's packed arrays
    packed: tuple[Any, ...]  # per kind, its ``pack`` of its obstacles
    grid: Grid
    obstacles: tuple[Any, ...]

    @classmethod
    def build(cls, env: Environment) -> _Index:
        obs = env.obstacles
        n = len(obs)
        found = [kind_of(o) for o in obs]  # unknown kinds fail here, loudly
        kinds: list[ObstacleKind] = []
        members: list[list[Any]] = []
        kind_id, row = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
        lo, hi = np.zeros((n, 3)), np.zeros((n, 3))
        for k, (o, kind) in enumerate(zip(obs, found, strict=True)):
            if kind not in kinds:
                kinds.append(kind)
                members.append([])
            g = kinds.index(kind)
            kind_id[k], row[k] = g, len(members[g])
            members[g].append(o)
            v = o.outline()
            lo[k] = [*v.min(axis=0), o.base_m]
            hi[k] = [*v.max(axis=0), o.top_m]
        packed = tuple(kind.pack(m) for kind, m in zip(kinds, members, strict=True))
        return cls(tuple(kinds), kind_id, row, packed, Grid.build(lo, hi), tuple(obs))

    @property
    def compiled(self) -> bool:
        """Whether the compiled engine implements every kind present."""
        return all(k.compiled for k in self.kinds)

    @cached_property
    def _compiled_arrays(
        self,
    ) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, IntArray, FloatArray]:
        """The compiled engine's obstacle arrays (it implements the ``wall`` and ``prism``
        kinds): wall flags, slabs, wall ends [N, 4], footprint vertices in CSR form."""
        obs = self.obstacles
        is_wall = np.array([o.kind == "wall" for o in obs], dtype=bool)
        base = np.array([o.base_m for o in obs], dtype=float)
        top = np.array([o.top_m for o in obs], dtype=float)
        ends = np.zeros((len(obs), 4))
        own = []
        for k, o in enumerate(obs):
            if is_wall[k]:
                ends[k] = [*o.start, *o.end]
                own.append(np.zeros((0, 2)))
            else:
                own.append(o.vertices)
        vert_start = np.concatenate([[0], np.cumsum([v.shape[0] for v in own])]).astype(int)
        flat = np.ascontiguousarray(np.concatenate(own)) if own else np.zeros((0, 2))
        return is_wall, base, top, np.ascontiguousarray(ends), vert_start, flat

    def walk_compiled(self, a: FloatArray, b: FloatArray, tol: float) -> BoolArray:
        """[M] the same answers as ``grid.walk`` with :meth:`pairs_blocked`, compiled."""
        from ris_planner.environment import _jit

        g = self.grid
        is_wall, base, top, ends, vert_start, flat = self._compiled_arrays
        with parallel_kernel():
            blocked = _jit.walk(
                a,
                b,
                tol,
                g.x0,
                g.y0,
                g.h,
                g.nx,
                g.ny,
                g.cell_start,
                g.cell_items,
                g.box_lo,
                g.box_hi,
                is_wall,
                base,
                top,
                ends,
                vert_start,
                flat,
            )
        return np.asarray(blocked)

    def pairs_blocked(
        self, a: FloatArray, b: FloatArray, legs: IntArray, ob: IntArray, tol: float
    ) -> BoolArray:
        """[K] exact test of leg legs[k] (rows of a, b) against obstacle ob[k], each kind by its
        own narrow phase."""
        out = np.zeros(ob.size, dtype=bool)
        kind_id = self.kind_id[ob]
        for g, kind in enumerate(self.kinds):
            sel = kind_id == g
            if np.any(sel):
                w = legs[sel]
                out[sel] = kind.blocks(self.packed[g], self.row[ob[sel]], a[w], b[w], tol)
        return out

    def depth(self, points: FloatArray, ob: IntArray) -> FloatArray:
        """[K] how far points[k] lie inside obstacle ob[k] (0 for non-solid kinds)."""
        out = np.zeros(ob.size)
        kind_id = self.kind_id[ob]
        for g, kind in enumerate(self.kinds):
            sel = np.nonzero(kind_id == g)[0]
            if sel.size and kind.solid:
                out[sel] = kind.depth(self.packed[g], self.row[ob[sel]], points[sel])
        return out

    def solid(self, ob: IntArray) -> BoolArray:
        """[K] whether obstacle ob[k] is of a solid kind (has an inside)."""
        solid = np.array([k.solid for k in self.kinds], dtype=bool)
        return np.asarray(solid[self.kind_id[ob]])


@dataclass(frozen=True)
class Scene:
    """The obstacles of one site, ready for batched visibility queries (the index is built on
    the first query and kept)."""

    environment: Environment
    engine: Engine = "auto"
    """``"numba"`` (compiled), ``"numpy"``, or ``"auto"`` (numba for large queries, see
    :data:`AUTO_COMPILED_MIN_WORK` and :data:`AUTO_COMPILED_WARM_MIN_WORK`); all give the same
    answers."""

    @classmethod
    def from_environment(cls, environment: Environment | None) -> Scene:
        return cls(environment if environment is not None else Environment())

    @property
    def empty(self) -> bool:
        return not self.environment.obstacles

    @cached_property
    def _index(self) -> _Index:
        return _Index.build(self.environment)

    def _compiled(self, legs: int) -> bool:
        if self.engine == "numba" and not self._index.compiled:
            raise ValueError(
                "engine='numba': the compiled engine does not implement the obstacle kinds "
                + ", ".join(k.name for k in self._index.kinds if not k.compiled)
                + "; use engine='numpy' or 'auto'"
            )
        if self.engine != "auto":
            return self.engine == "numba"
        floor = AUTO_COMPILED_WARM_MIN_WORK if compiled_code_loaded() else AUTO_COMPILED_MIN_WORK
        if legs * len(self.environment.obstacles) < floor:
            return False
        return self._index.compiled and _compiled_engine_available()

    def blocked(self, a: ArrayLike, b: ArrayLike, tol: float = VISIBILITY_TOLERANCE_M) -> BoolArray:
        """[M] whether each leg a[i]–b[i] ([M, 3] each, or one of them [3], broadcast) is
        blocked by an obstacle."""
        if not 0.0 <= tol <= INSIDE_MARGIN_M:
            raise ValueError(f"visibility tolerance must lie in [0, 1 cm], got {tol} m")
        a_ = np.asarray(a, dtype=float)
        b_ = np.asarray(b, dtype=float)
        a_, b_ = np.broadcast_arrays(_points(a_, "a"), _points(b_, "b"))
        if a_.shape[0] == 0 or self.empty:
            return np.zeros(a_.shape[0], dtype=bool)
        a_, b_ = np.ascontiguousarray(a_), np.ascontiguousarray(b_)
        index = self._index

        if self._compiled(a_.shape[0]):
            return index.walk_compiled(a_, b_, tol)

        def test(legs: IntArray, ob: IntArray) -> BoolArray:
            return index.pairs_blocked(a_, b_, legs, ob, tol)

        return index.grid.walk(a_, b_, test)

    def blocked_to(
        self, points: ArrayLike, targets: ArrayLike, tol: float = VISIBILITY_TOLERANCE_M
    ) -> BoolArray:
        """Whether the legs from points [M, 3] to a target [3] (a RIS centre, a TX) are blocked,
        [M]; for targets [S, 3], every point to every target in one query, [S, M] – the
        planner's "many points × few sites" pattern. The same rule as :meth:`blocked` (which
        is symmetric in the two ends)."""
        pts = _points(np.asarray(points, dtype=float), "points")
        t = np.asarray(targets, dtype=float)
        single = t.ndim == 1
        t = _points(t, "targets")
        a = np.repeat(t, pts.shape[0], axis=0)  # [S·M, 3] legs target → point
        b = np.tile(pts, (t.shape[0], 1))
        out = self.blocked(a, b, tol).reshape(t.shape[0], pts.shape[0])
        return out[0] if single else out

    def inside(self, points: ArrayLike, margin: float = INSIDE_MARGIN_M) -> IntArray:
        """[M] index (in ``environment.obstacles``) of the first prism each point [M, 3] lies
        more than ``margin`` inside, −1 for none."""
        pts = _points(np.asarray(points, dtype=float), "points")
        out = np.full(pts.shape[0], -1, dtype=int)
        if pts.shape[0] == 0 or self.empty:
            return out
        index = self._index
        grid = index.grid
        i = np.floor((pts[:, 0] - grid.x0) / grid.h)
        j = np.floor((pts[:, 1] - grid.y0) / grid.h)
        ok = (i >= 0) & (i < grid.nx) & (j >= 0) & (j < grid.ny)
        rows = np.nonzero(ok)[0]
        cell = (i[rows] * grid.ny + j[rows]).astype(int)
        s, e = grid.cell_start[cell], grid.cell_start[cell + 1]
        counts = e - s
        row = np.repeat(rows, counts)
        k = np.arange(row.size) - np.repeat(np.cumsum(counts) - counts, counts)
        ob = grid.cell_items[np.repeat(s, counts) + k]
        p = pts[row]
        keep = index.solid(ob) & np.all((p >= grid.box_lo[ob]) & (p <= grid.box_hi[ob]), axis=1)
        row, ob, p = row[keep], ob[keep], p[keep]
        deep = index.depth(p, ob) > margin
        first = np.full(pts.shape[0], np.iinfo(int).max)
        np.minimum.at(first, row[deep], ob[deep])
        hit = first < np.iinfo(int).max
        out[hit] = first[hit]
        return out
