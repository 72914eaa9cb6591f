"""Which layouts are allowed: mutually exclusive candidates (one mounting point, or closer than
``min_separation_m``), required and excluded candidates, per-site cost and a budget.

Exhaustive search enumerates only the feasible layouts (:meth:`Feasibility.enumerate`:
layouts grow one site at a time in increasing index order, each extension restricted to the
sites compatible with every chosen one), so infeasible layouts cost neither memory nor scoring.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.model.plan import Constraints, CostSpec
from ris_planner.planning.inputs.sites import Site

IntArray = NDArray[np.int_]
FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ENUMERATE_BLOCK = 200_000
"""Partial layouts extended at once (a [block, S] boolean table: ≤ 100 MB for S = 500)."""

BUDGET_RTOL = 1e-12
"""Relative slack on the budget test (a sum of costs equal to the budget is within it)."""


@dataclass(frozen=True)
class Feasibility:
    """conflict : [S, S] symmetric, True where two candidates may not be chosen together;
    allowed : [S] candidates that may be used; required : sites every layout holds;
    cost : [S] cost of each site as a RIS (site cost + per_ris + per_element·N);
    budget : largest layout cost (``None``: unlimited)."""

    conflict: BoolArray
    allowed: BoolArray
    required: tuple[int, ...]
    cost: FloatArray
    budget: float | None

    @property
    def n_sites(self) -> int:
        return int(self.allowed.shape[0])

    @property
    def trivial(self) -> bool:
        """No constraint at all: every layout is feasible."""
        return (
            not self.conflict.any()
            and bool(self.allowed.all())
            and not self.required
            and self.budget is None
        )

    def layout_cost(self, layouts: IntArray) -> FloatArray:
        """[B] total cost of layouts [B, L]."""
        return np.asarray(self.cost[np.atleast_2d(layouts)].sum(axis=1))

    def ok(self, layouts: IntArray) -> BoolArray:
        """[B] whether each layout [B, L] (distinct sites) satisfies every constraint."""
        lay = np.atleast_2d(np.asarray(layouts, dtype=int))
        good = np.all(self.allowed[lay], axis=1)
        n = lay.shape[1]
        for i, j in itertools.combinations(range(n), 2):
            good &= ~self.conflict[lay[:, i], lay[:, j]]
        for r in self.required:
            good &= np.any(lay == r, axis=1)
        if self.budget is not None:
            good &= self.layout_cost(lay) <= self.budget * (1 + BUDGET_RTOL)
        return np.asarray(good)

    def compatible(self, chosen: list[int] | tuple[int, ...]) -> BoolArray:
        """[S] sites that may join ``chosen`` (allowed, not chosen, no conflict, in budget)."""
        mask = self.allowed.copy()
        if chosen:
            idx = list(chosen)
            mask[idx] = False
            mask &= ~np.any(self.conflict[idx], axis=0)
        if self.budget is not None:
            spent = float(self.cost[list(chosen)].sum()) if chosen else 0.0
            mask &= spent + self.cost <= self.budget * (1 + BUDGET_RTOL)
        return mask

    def enumerate(self, n_ris: int, limit: int) -> IntArray | None:
        """Every feasible layout [N, L] (sorted site indices, lexicographic order), or ``None``
        when more than ``limit`` partial or complete layouts arise (the caller then searches
        heuristically)."""
        req = tuple(sorted(self.required))
        free = n_ris - len(req)
        if free < 0:
            return np.empty((0, n_ris), dtype=int)
        base = self.compatible(req)  # [S]
        spent = float(self.cost[list(req)].sum()) if req else 0.0
        cur = np.empty((1, 0), dtype=int)
        cur_cost = np.array([spent])
        idx = np.arange(self.n_sites)
        for _ in range(free):
            parts, costs = [], []
            n_new = 0
            for b0 in range(0, cur.shape[0], ENUMERATE_BLOCK):
                blk = cur[b0 : b0 + ENUMERATE_BLOCK]
                blk_cost = cur_cost[b0 : b0 + ENUMERATE_BLOCK]
                # [B, S] sites above the last chosen one, compatible with every chosen one
                ok = np.broadcast_to(base, (blk.shape[0], self.n_sites)).copy()
                if blk.shape[1]:
                    ok &= idx[None, :] > blk[:, -1:]
                    for c in range(blk.shape[1]):
                        ok &= ~self.conflict[blk[:, c]]
                if self.budget is not None:
                    ok &= blk_cost[:, None] + self.cost[None, :] <= self.budget * (1 + BUDGET_RTOL)
                rows, cols = np.nonzero(ok)
                n_new += rows.size
                if n_new > limit:
                    return None
                parts.append(np.column_stack([blk[rows], cols]))
                costs.append(blk_cost[rows] + self.cost[cols])
            cur = np.concatenate(parts) if parts else np.empty((0, cur.shape[1] + 1), dtype=int)
            cur_cost = np.concatenate(costs) if costs else np.empty(0)
        if req:
            cur = np.sort(np.column_stack([cur, np.tile(req, (cur.shape[0], 1))]), axis=1)
            cur = cur[np.lexsort(cur.T[::-1])]
        return cur.astype(int, copy=False)

    def count_upper(self, n_ris: int) -> int:
        """An upper bound on the number of feasible layouts (combinations of the free sites)."""
        free = int(self.compatible(self.required).sum())
        k = n_ris - len(self.required)
        return math.comb(free, k) if k >= 0 else 0

    def random_layout(
        self, n_ris: int, rng: np.random.Generator, tries: int = 20
    ) -> tuple[int, ...] | None:
        """A random feasible layout (sites drawn one by one among the compatible ones)."""
        for _ in range(tries):
            cur = list(self.required)
            while len(cur) < n_ris:
                cand = np.flatnonzero(self.compatible(cur))
                if cand.size == 0:
                    break
                cur.append(int(rng.choice(cand)))
            if len(cur) == n_ris:
                return tuple(sorted(cur))
        return None


def unconstrained(n_sites: int) -> Feasibility:
    """Every layout allowed (today's search space)."""
    return Feasibility(
        np.zeros((n_sites, n_sites), dtype=bool),
        np.ones(n_sites, dtype=bool),
        (),
        np.zeros(n_sites),
        None,
    )


def site_costs(sites: list[Site], cost: CostSpec) -> FloatArray:
    """[S] cost of each site as a RIS: its own cost + per_ris + per_element · rows · cols."""
    return np.array(
        [s.cost + cost.per_ris + cost.per_element * s.ris.rows * s.ris.cols for s in sites],
        dtype=float,
    )


def build_feasibility(sites: list[Site], spec: Constraints, cost: CostSpec) -> Feasibility:
    """The document's constraints over the expanded candidate list (indices checked here)."""
    n = len(sites)
    for what, idx in (("require", spec.require), ("exclude", spec.exclude)):
        bad = [i for i in idx if i >= n]
        if bad:
            raise RisPlannerError(
                f"constraints.{what}: candidate index {bad[0]} is out of range (there are {n}"
                f" candidates, indices 0 … {n - 1})"
            )
    pos = np.array([s.ris.position for s in sites], dtype=float).reshape(n, 3)  # [S, 3]
    conflict = np.zeros((n, n), dtype=bool)
    if spec.exclusive_mounts:
        d_xy = np.linalg.norm(pos[:, None, :2] - pos[None, :, :2], axis=-1)  # [S, S]
        conflict |= d_xy <= spec.same_spot_m
    if spec.min_separation_m > 0:
        d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
        conflict |= d < spec.min_separation_m
    np.fill_diagonal(conflict, False)
    req = tuple(spec.require)
    for a, b in itertools.combinations(req, 2):
        if conflict[a, b]:
            raise RisPlannerError(
                f"constraints.require: candidates {a} and {b} exclude each other (one mounting"
                " point or closer than min_separation_m)"
            )
    allowed = np.ones(n, dtype=bool)
    allowed[list(spec.exclude)] = False
    costs = site_costs(sites, cost)
    if spec.budget is not None and req and costs[list(req)].sum() > spec.budget * (1 + BUDGET_RTOL):
        raise RisPlannerError(
            f"constraints.require: the required candidates cost {costs[list(req)].sum():g},"
            f" above the budget {spec.budget:g}"
        )
    return Feasibility(conflict, allowed, req, costs, spec.budget)
