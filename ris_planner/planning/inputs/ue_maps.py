"""UE probability maps (grids, weighted points, roads, CSV) and the weighted TX–RX pairs."""

from __future__ import annotations

import csv
import io
import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.limits import MAX_MAP_POINTS
from ris_planner.model.plan import (
    GridMap,
    PairList,
    PairSample,
    PairsSpec,
    Road,
    UEMap,
    range_count,
)
from ris_planner.model.scenario import MIN_UE_RIS_DISTANCE_M
from ris_planner.planning.inputs.separation import draw_near, near_combinations

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]


STREET_COLUMNS = 6
"""Columns of :attr:`PointMap.street`: the centre-line segment's ends (ax, ay, bx, by), the
distance along it from (ax, ay) and the signed lateral offset [m]."""


@dataclass(frozen=True)
class PointMap:
    """Positions [M, 3] and relative weights [M] (all ≥ 0, not all zero); ``street`` [M, 6]
    places each point on its road (:data:`STREET_COLUMNS`; a row of NaN for a point that is
    not on a road), ``None`` when no point is."""

    points: FloatArray
    weights: FloatArray
    street: FloatArray | None = None

    def subset(self, keep: NDArray[np.bool_]) -> PointMap:
        """The points where ``keep`` is true."""
        street = None if self.street is None else self.street[keep]
        return PointMap(self.points[keep], self.weights[keep], street)


def range_values(r: list[float], what: str) -> FloatArray:
    """The values of a [start, stop, step] range, stop included."""
    n = range_count(r, what)
    return np.asarray(r[0] + r[2] * np.arange(n), dtype=float)


def grid_points(grid: GridMap) -> PointMap:
    """Grid positions in x-major order (x outer, then y, then z), as ``paper.fig10_grid``."""
    xs, ys, zs = (range_values(getattr(grid, a), f"grid.{a}") for a in "xyz")
    mesh = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)
    w = np.ones(len(mesh)) if grid.weights is None else np.asarray(grid.weights, dtype=float)
    return PointMap(mesh, w)


def road_points(road: Road) -> PointMap:
    """Lattice samples of a road: every ``step_m`` along each segment of the centre line
    (segment starts included, the last vertex too) at lateral offsets k·step within
    ±width/2 (symmetric about the centre line), all at ``height_m``."""
    verts = np.asarray(road.points, dtype=float)
    half = road.width_m / 2 / road.step_m  # lateral samples each side (inf for a 5e-324 step)
    if not half <= MAX_MAP_POINTS:
        raise LimitExceededError(
            f"road width_m / step_m gives more than {MAX_MAP_POINTS} lateral samples; raise step_m",
            MAX_MAP_POINTS,
        )
    n_lat = int(np.floor(half + 1e-9))
    lateral = road.step_m * np.arange(-n_lat, n_lat + 1)
    rows: list[FloatArray] = []  # [n, 2 + STREET_COLUMNS]: x, y and the street columns
    last = None  # the last segment with a length: the end vertex's lateral direction
    for a, b in itertools.pairwise(verts):
        seg = b - a
        length = float(np.hypot(*seg))
        if length == 0:
            continue
        n_along = int(np.ceil(length / road.step_m - 1e-9))
        if n_along * len(lateral) > MAX_MAP_POINTS:
            raise LimitExceededError(
                f"road samples exceed the limit of {MAX_MAP_POINTS} map points; raise step_m",
                MAX_MAP_POINTS,
            )
        last = (a, b, length)
        along = np.arange(n_along) * float(road.step_m)
        rows.append(_lattice(a, b, length, along, a + (along / length)[:, None] * seg, lateral))
    if last is None:
        tail = np.column_stack([verts[-1:], np.full((1, STREET_COLUMNS), np.nan)])
    else:
        a, b, length = last
        tail = _lattice(a, b, length, np.array([length]), verts[-1:], lateral)
    table = np.concatenate([*rows, tail])
    xyz = np.column_stack([table[:, :2], np.full(len(table), road.height_m)])
    return PointMap(xyz, np.full(len(xyz), road.weight), table[:, 2:])


def _lattice(
    a: FloatArray,
    b: FloatArray,
    length: float,
    along: NDArray[np.floating],
    centre: NDArray[np.floating],
    lateral: NDArray[np.floating],
) -> FloatArray:
    """[len(along) · len(lateral), 2 + STREET_COLUMNS]: the points at the ``centre`` points
    (``along`` the segment a–b from ``a``) and ``lateral`` offsets to their left (x-major),
    each with its street columns."""
    direction = (b - a) / length
    normal = np.array([-direction[1], direction[0]])
    # [n_along, n_lat, 2]
    xy = centre[:, None, :] + lateral[None, :, None] * normal
    s, o = (g.ravel() for g in np.meshgrid(along, lateral, indexing="ij"))
    ends = np.broadcast_to(np.concatenate([a, b]), (len(s), 4))
    return np.column_stack([xy.reshape(-1, 2), ends, s, o])


def csv_points(text: str) -> PointMap:
    """Rows ``x, y, z[, weight]`` with a header row naming the columns."""
    reader = csv.DictReader(io.StringIO(text))
    fields = [f.strip().lower() for f in (reader.fieldnames or [])]
    if not {"x", "y", "z"} <= set(fields):
        raise RisPlannerError(f"CSV map needs a header with x, y, z (and weight), got {fields}")
    rows = []
    for n, row in enumerate(reader, start=2):
        vals = {k.strip().lower(): v for k, v in row.items() if k is not None}
        try:
            rows.append(
                [
                    float(vals["x"]),
                    float(vals["y"]),
                    float(vals["z"]),
                    float(vals.get("weight") or 1),
                ]
            )
        except (TypeError, ValueError):
            raise RisPlannerError(f"CSV map line {n}: x, y, z, weight must be numbers") from None
        if len(rows) > MAX_MAP_POINTS:
            raise LimitExceededError(f"CSV map has more than {MAX_MAP_POINTS} rows", MAX_MAP_POINTS)
    if not rows:
        raise RisPlannerError("CSV map has no rows")
    arr = np.asarray(rows, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr[:, 3] < 0):
        raise RisPlannerError("CSV map: coordinates must be finite and weights ≥ 0")
    return PointMap(arr[:, :3], arr[:, 3])


def build_map(spec: UEMap, what: str) -> PointMap:
    """All sources of a map concatenated (grid, points, roads, CSV); zero-weight points are
    dropped. Raises when nothing with a positive weight remains."""
    parts: list[PointMap] = []
    if spec.grid is not None:
        parts.append(grid_points(spec.grid))
    if spec.points is not None:
        w = np.ones(len(spec.points)) if spec.weights is None else np.asarray(spec.weights)
        parts.append(PointMap(np.asarray(spec.points, dtype=float), w.astype(float)))
    for road in spec.roads or []:
        parts.append(road_points(road))
    if spec.csv_text is not None:
        parts.append(csv_points(spec.csv_text))
    pts = np.concatenate([p.points for p in parts])
    w = np.concatenate([p.weights for p in parts])
    if len(pts) > MAX_MAP_POINTS:
        raise LimitExceededError(
            f"{what} has {len(pts)} points, above the limit {MAX_MAP_POINTS}", MAX_MAP_POINTS
        )
    street = None
    if any(p.street is not None for p in parts):
        street = np.concatenate(
            [
                np.full((len(p.points), STREET_COLUMNS), np.nan) if p.street is None else p.street
                for p in parts
            ]
        )
    keep = w > 0
    if not np.any(keep):
        raise RisPlannerError(f"{what} is empty: no point has a positive weight")
    return PointMap(pts, w, street).subset(keep)


@dataclass(frozen=True)
class PairSet:
    """The evaluated TX–RX pairs: positions [P, 3], normalised weights [P] (sum 1) and the
    map indices of each pair's TX and RX."""

    tx: FloatArray
    rx: FloatArray
    weights: FloatArray
    tx_index: IntArray
    rx_index: IntArray

    @property
    def size(self) -> int:
        return int(self.weights.shape[0])


def unit_scaled(weights: FloatArray) -> FloatArray:
    """Relative weights divided by their largest: in [0, 1], the largest exactly 1."""
    return weights / weights.max()


def unordered_directions(spec: PairsSpec, metric: str, known: tuple[str, ...]) -> str:
    """How unordered pairs count both directions (half the weight each):

    * ``"single"``: not ``"unordered"``, or metric ``max`` (max(PEB_T, PEB_R) is symmetric);
    * ``"mirror"``: the scorer takes the reverse direction's bound from the same inversion
      (PEB_R of j→i is PEB_T of i→j; see :mod:`ris_planner.planning.scoring.scorer`);
    * ``"explicit"``: a known TX breaks that symmetry, so the pair set holds both directions.
    """
    if spec != "unordered" or metric == "max":
        return "single"
    return "explicit" if "tx" in known else "mirror"


def build_pairs(
    tx_map: PointMap,
    rx_map: PointMap,
    spec: PairsSpec,
    max_pairs: int,
    both_directions: bool = False,
    scene: Scene | None = None,
) -> PairSet:
    """Pairs per the document's ``pairs`` (see :class:`PlanDocument`: every combination, the
    unordered ones, a sample or the listed pairs, :func:`listed_pairs`); raises
    :class:`LimitExceededError` naming ``max_pairs`` when there are too many.
    ``both_directions`` (``unordered`` only): every pair i < j also as j → i, weights halved.
    ``scene``: the environment a ``line_of_sight`` sample checks its TX–RX legs against
    (absent: free space)."""
    n_t, n_r = len(tx_map.points), len(rx_map.points)
    if isinstance(spec, PairSample):
        if spec.sample > max_pairs:
            raise LimitExceededError(
                f"pairs.sample = {spec.sample} exceeds max_pairs = {max_pairs}", max_pairs
            )
        if spec.max_separation_m is None and not spec.line_of_sight:
            return _sample_pairs(tx_map, rx_map, spec)
        return _sample_near(tx_map, rx_map, spec, scene or Scene.from_environment(None))
    if isinstance(spec, PairList):
        if spec.size > max_pairs:
            raise LimitExceededError(
                f"pairs lists {spec.size} TX–RX pairs, above max_pairs = {max_pairs}", max_pairs
            )
        return listed_pairs(tx_map, rx_map, spec)
    count = n_t * (n_t - 1) // 2 if spec == "unordered" else n_t * n_r
    if spec == "unordered" and both_directions:
        count *= 2
    if count > max_pairs:
        raise LimitExceededError(
            f"pairs {spec!r} gives {count} TX–RX pairs, above max_pairs = {max_pairs}; use"
            ' "pairs": {"sample": N, "seed": S} or coarser maps',
            max_pairs,
        )
    if spec == "unordered":
        it, ir = canonical_unordered(tx_map, *np.triu_indices(n_t, k=1), both_directions)
    else:
        it, ir = (a.ravel() for a in np.meshgrid(np.arange(n_t), np.arange(n_r), indexing="ij"))
    tx, rx = tx_map.points[it], rx_map.points[ir]
    keep = np.linalg.norm(tx - rx, axis=-1) >= MIN_UE_RIS_DISTANCE_M
    if not np.any(keep):
        raise RisPlannerError("no TX–RX pair with distinct positions")
    # relative weights scaled by their largest (into (0, 1]) before any product or sum, so
    # neither overflows however large (1e308) or small (1e-320) the document's numbers are
    w = unit_scaled(tx_map.weights)[it[keep]] * unit_scaled(rx_map.weights)[ir[keep]]
    w = w / w.max() if w.max() > 0 else w
    total = w.sum()
    if not (np.isfinite(total) and total > 0):
        raise RisPlannerError(
            "pair weights underflow: the TX and RX map weights span too many orders of"
            " magnitude (their products are 0); use weights within 1e-150 of each other"
        )
    return PairSet(tx[keep], rx[keep], w / total, it[keep], ir[keep])


PAIR_POSITION_TOLERANCE_M = 1e-3
"""An explicit pair's position matches a map point this close (:func:`listed_pairs`)."""


def listed_pairs(tx_map: PointMap, rx_map: PointMap, spec: PairList) -> PairSet:
    """The explicit pairs of ``spec`` over the maps (:class:`~ris_planner.model.plan.PairList`),
    in the listed order, weights normalised to sum 1: map indices as given, positions matched
    to their map's nearest point (within :data:`PAIR_POSITION_TOLERANCE_M`). Raises naming the
    first pair whose index is beyond its map, whose position is no point of it (a point inside
    an obstacle is no longer one), or whose TX and RX coincide."""
    ends = []
    for side, pm in (("tx", tx_map), ("rx", rx_map)):
        if spec.by_index:
            idx = np.asarray(getattr(spec, f"{side}_index"), dtype=np.int64)
            bad = np.flatnonzero(idx >= len(pm.points))
            if bad.size:
                k = int(bad[0])
                raise RisPlannerError(
                    f"pairs.{side}_index[{k}] = {int(idx[k])} is beyond the {side}_map's"
                    f" {len(pm.points)} points (as planned: zero-weight points and points inside"
                    " obstacles left out)"
                )
        else:
            from scipy.spatial import cKDTree

            pos = np.asarray(getattr(spec, side), dtype=float)
            dist, idx = cKDTree(pm.points).query(pos)
            bad = np.flatnonzero(dist > PAIR_POSITION_TOLERANCE_M)
            if bad.size:
                k = int(bad[0])
                raise RisPlannerError(
                    f"pairs.{side}[{k}] = {pos[k].tolist()} is no point of the {side}_map (the"
                    f" nearest is {dist[k]:.3g} m away; a point inside an obstacle is left out)"
                )
        ends.append(idx.astype(np.int_))
    it, ir = ends
    tx, rx = tx_map.points[it], rx_map.points[ir]
    same = np.flatnonzero(np.linalg.norm(tx - rx, axis=-1) < MIN_UE_RIS_DISTANCE_M)
    if same.size:
        raise RisPlannerError(f"pairs: pair {int(same[0])} has the same TX and RX position")
    w = np.ones(len(it)) if spec.weights is None else np.asarray(spec.weights, dtype=float)
    w = unit_scaled(w)
    return PairSet(tx, rx, w / w.sum(), it, ir)


def canonical_unordered(
    pm: PointMap, i: IntArray, j: IntArray, both_directions: bool
) -> tuple[IntArray, IntArray]:
    """(TX, RX) map indices of the unordered pairs {i, j} in an order that does not depend on
    the map's order: each pair's TX is the point that sorts first by (x, y, z, weight) (both
    orientations with ``both_directions``), and the pairs are sorted by (TX, RX) in that key.
    A map listed in another order thus gives bit-identical pairs, weights and scores."""
    p, w = pm.points, pm.weights
    rank = np.empty(len(p), dtype=int)
    rank[np.lexsort((w, p[:, 2], p[:, 1], p[:, 0]))] = np.arange(len(p))
    swap = rank[j] < rank[i]
    a, b = np.where(swap, j, i), np.where(swap, i, j)
    if both_directions:
        a, b = np.concatenate([a, b]), np.concatenate([b, a])
    order = np.lexsort((rank[b], rank[a]))
    return a[order], b[order]


def _sample_pairs(tx_map: PointMap, rx_map: PointMap, spec: PairSample) -> PairSet:
    rng = np.random.default_rng(spec.seed)
    pt, pr = unit_scaled(tx_map.weights), unit_scaled(rx_map.weights)
    pt, pr = pt / pt.sum(), pr / pr.sum()
    it = np.empty(0, dtype=int)
    ir = np.empty(0, dtype=int)
    for _ in range(100):  # redraw pairs whose positions coincide
        need = spec.sample - len(it)
        if need == 0:
            break
        a = rng.choice(len(pt), size=need, p=pt)
        b = rng.choice(len(pr), size=need, p=pr)
        ok = np.linalg.norm(tx_map.points[a] - rx_map.points[b], axis=-1) >= MIN_UE_RIS_DISTANCE_M
        it, ir = np.concatenate([it, a[ok]]), np.concatenate([ir, b[ok]])
    if len(it) < spec.sample:
        raise RisPlannerError("cannot sample pairs with distinct TX and RX positions")
    n = len(it)
    return PairSet(tx_map.points[it], rx_map.points[ir], np.full(n, 1.0 / n), it, ir)


def _sample_near(tx_map: PointMap, rx_map: PointMap, spec: PairSample, scene: Scene) -> PairSet:
    """Sidelink pairs (:mod:`ris_planner.planning.inputs.separation`): drawn ∝ w_i · w_j among the
    combinations within the separation (and with a clear TX–RX leg with ``line_of_sight``)."""
    it, ir = near_combinations(tx_map.points, rx_map.points, tx_map.street, rx_map.street, spec)
    w = unit_scaled(tx_map.weights)[it] * unit_scaled(rx_map.weights)[ir]
    pick = draw_near(tx_map.points, rx_map.points, it, ir, w, spec, scene)
    a, b = it[pick], ir[pick]
    n = len(pick)
    return PairSet(tx_map.points[a], rx_map.points[b], np.full(n, 1.0 / n), a, b)
