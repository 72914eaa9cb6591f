"""Benchmark: visibility of 10⁶ legs in a random city of 400 buildings and 40 walls.

A 20 × 20 grid of city blocks (50 m pitch, 10 m streets); each block holds one prism with a
4–12 vertex footprint (quadrilaterals, convex polygons, L and U shapes, concave stars), height
5–40 m, a fifth of them raised (base 0.5–4 m: arcades); 40 walls (fences, 2–3 m) along the
streets. The legs are the planner's pattern: UE points at 1.5 m on the streets to RIS sites
on the facades at 4–12 m (20 sites × 50 000 points). Reported: the time of
:meth:`Scene.blocked` for all legs (the first call, which builds the index and loads the
compiled code, separately), of :meth:`Scene.blocked_to` site by site and for all sites at
once, legs/s, the numpy engine and the brute-force per-leg reference of the tests
(tests/visibility_reference.py) measured in the same run on subsamples, extrapolated, with
the ratios. The answers on the subsample must agree wherever the reference decides.
Target on the 2-core machine: ≤ 0.5 s for 10⁶ legs.

    python benchmarks/bounds/bench_visibility.py [--points 50000] [--sites 20]
        [--reference-legs 200] [--quick]
    python benchmarks/bounds/bench_visibility.py --warm

``--quick``: 5000 points × 5 sites, 50 reference legs.

``--warm`` measures ``engine="auto"``'s threshold once the process has loaded compiled code
(another kernel first, as a plan's search does): for growing queries, the walk's first call
(its load from the cache), its later calls and the numpy engine, with the engine ``auto``
picks (:data:`ris_planner.environment.scene.AUTO_COMPILED_WARM_MIN_WORK`).
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from visibility_reference import reference_blocked

from ris_planner.environment import Scene
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment

PITCH_M = 50.0
STREET_M = 10.0
BLOCKS = 20


def footprint(rng: np.random.Generator, x0: float, y0: float) -> list[list[float]]:
    """A random footprint inside the block [x0, x0 + 40] × [y0, y0 + 40]."""
    kind = rng.integers(5)
    if kind == 0:  # quadrilateral
        pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) + rng.uniform(-0.1, 0.1, (4, 2))
    elif kind == 1:  # convex polygon
        n = int(rng.integers(5, 9))
        ang = (np.arange(n) + rng.uniform(0, 0.5, n)) * 2 * np.pi / n
        pts = 0.5 + 0.5 * np.c_[np.cos(ang), np.sin(ang)]
    elif kind == 2:  # L
        w = rng.uniform(0.3, 0.6)
        pts = np.array([[0, 0], [1, 0], [1, w], [w, w], [w, 1], [0, 1]])
    elif kind == 3:  # U (a courtyard open to one side)
        w = rng.uniform(0.25, 0.4)
        pts = np.array([[0, 0], [1, 0], [1, 1], [1 - w, 1], [1 - w, w], [w, w], [w, 1], [0, 1]])
    else:  # concave star
        n = int(rng.integers(8, 13))
        ang = (np.arange(n) + rng.uniform(0, 0.5, n)) * 2 * np.pi / n
        rad = np.where(np.arange(n) % 2 == 0, 0.5, rng.uniform(0.2, 0.4, n))
        pts = 0.5 + rad[:, None] * np.c_[np.cos(ang), np.sin(ang)]
    pts = np.clip(pts, 0.0, 1.0)
    size = rng.uniform(25.0, 40.0)
    return (np.array([x0, y0]) + (40.0 - size) / 2 + size * pts).round(3).tolist()


def city(rng: np.random.Generator) -> Environment:
    obstacles: list[dict[str, Any]] = []
    for i in range(BLOCKS):
        for j in range(BLOCKS):
            x0, y0 = i * PITCH_M + STREET_M / 2, j * PITCH_M + STREET_M / 2
            raised = rng.uniform() < 0.2
            obstacles.append(
                {
                    "kind": "prism",
                    "name": f"b{i}-{j}",
                    "footprint": footprint(rng, x0, y0),
                    "base_m": float(rng.uniform(0.5, 4.0)) if raised else 0.0,
                    "height_m": float(rng.uniform(5.0, 40.0)),
                }
            )
    for k in range(40):  # fences in the middle of streets, 2–3 m high
        along = rng.uniform(0, BLOCKS * PITCH_M - 20)
        street = int(rng.integers(1, BLOCKS)) * PITCH_M
        s, e = [along, street], [along + rng.uniform(5, 20), street]
        if k % 2:
            s, e = s[::-1], e[::-1]
        obstacles.append(
            {"kind": "wall", "start": s, "end": e, "base_m": 0.0, "height_m": rng.uniform(2, 3)}
        )
    return Environment.model_validate({"obstacles": obstacles})


def street_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """[n, 3] UE points at 1.5 m on the streets (1 m off the street centre lines' fences)."""
    along = rng.uniform(0, BLOCKS * PITCH_M, n)
    street = rng.integers(0, BLOCKS + 1, n) * PITCH_M + rng.choice([-1, 1], n) * rng.uniform(
        1.0, 4.0, n
    )
    swap = rng.uniform(size=n) < 0.5
    x, y = np.where(swap, street, along), np.where(swap, along, street)
    return np.c_[x, y, np.full(n, 1.5)]


def facade_sites(rng: np.random.Generator, env: Environment, n: int) -> np.ndarray:
    """[n, 3] RIS centres on facades (points of footprint edges, 4–12 m up)."""
    prisms = [o for o in env.obstacles if isinstance(o, Prism)]
    out = []
    for k in rng.choice(len(prisms), n, replace=False):
        p = prisms[k]
        v = p.vertices
        e = int(rng.integers(v.shape[0]))
        xy = v[e] + rng.uniform(0.2, 0.8) * (v[(e + 1) % v.shape[0]] - v[e])
        z = min(rng.uniform(4.0, 12.0), p.top_m - 0.5)
        out.append([*xy, max(z, p.base_m + 0.5)])
    return np.array(out)


def timed(fn):  # type: ignore[no-untyped-def]
    """(result, wall seconds, CPU seconds of this process)."""
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def warm_crossover(env: Environment, rng: np.random.Generator) -> None:
    """The ``--warm`` table (module docstring)."""
    from ris_planner.environment import scene as scene_module
    from ris_planner.inversion import _crb_jit
    from ris_planner.runtime.kernels import compiled_code_loaded

    _crb_jit.work_rows(7)  # compiled code loaded, not the walk: a plan after its search
    assert compiled_code_loaded()
    n_ob = len(env.obstacles)
    print(
        f"{n_ob} obstacles; compiled code loaded; warm threshold "
        f"{scene_module.AUTO_COMPILED_WARM_MIN_WORK:,} legs × obstacles"
    )
    print(f"{'legs':>8} {'legs×obst':>11} {'first numba':>16} {'numba':>9} {'numpy':>9}  auto")
    first = True
    for n in (10, 100, 1_000, 10_000, 100_000):
        a, b = street_points(rng, n), street_points(rng, n)
        fast_scene, slow_scene = Scene(env, engine="numba"), Scene(env, engine="numpy")
        w = time.perf_counter()
        fast = fast_scene.blocked(a, b)  # the index, and the first time the walk's load
        t_first = time.perf_counter() - w
        _, t_nb, _ = timed(partial(fast_scene.blocked, a, b))
        slow, t_np, _ = timed(partial(slow_scene.blocked, a, b))
        assert np.array_equal(fast, slow), "the numpy and numba engines disagree"
        pick = "numba" if Scene(env)._compiled(n) else "numpy"
        label = f"{t_first * 1e3:.1f} ms" + (" (load)" if first else "")
        first = False
        print(
            f"{n:8d} {n * n_ob:11,d} {label:>16} {t_nb * 1e3:6.1f} ms {t_np * 1e3:6.1f} ms  {pick}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=50_000)
    ap.add_argument("--sites", type=int, default=20)
    ap.add_argument("--numpy-legs", type=int, default=100_000)
    ap.add_argument("--reference-legs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--warm", action="store_true", help="the warm threshold's table only")
    ap.add_argument("--quick", action="store_true", help="5000 points × 5 sites")
    args = ap.parse_args()
    if args.quick:
        args.points, args.sites, args.numpy_legs, args.reference_legs = 5000, 5, 10_000, 50
    rng = np.random.default_rng(args.seed)
    env = city(rng)
    if args.warm:
        warm_crossover(env, rng)
        return
    pts = street_points(rng, args.points)
    sites = facade_sites(rng, env, args.sites)
    a = np.repeat(sites, pts.shape[0], axis=0)  # [M, 3] legs site → point
    b = np.tile(pts, (sites.shape[0], 1))
    m = a.shape[0]

    scene = Scene(env, engine="numba")
    _, t_build, _ = timed(lambda: scene.blocked(a[:1], b[:1]))  # index and compiled code
    blocked, t_all, c_all = timed(lambda: scene.blocked(a, b))
    per_site, t_sites, _ = timed(lambda: np.concatenate([scene.blocked_to(pts, s) for s in sites]))
    matrix, t_matrix, _ = timed(lambda: scene.blocked_to(pts, sites))
    assert np.array_equal(per_site, blocked)
    assert np.array_equal(matrix.ravel(), blocked)
    n_np = min(m, args.numpy_legs)
    sub_np = rng.choice(m, n_np, replace=False)
    slow, t_np, _ = timed(lambda: Scene(env, engine="numpy").blocked(a[sub_np], b[sub_np]))
    assert np.array_equal(slow, blocked[sub_np]), "the numpy and numba engines disagree"
    t_np *= m / n_np

    sub = rng.choice(m, args.reference_legs, replace=False)
    ref, t_ref, _ = timed(lambda: [reference_blocked(a[i], b[i], env) for i in sub])
    t_ref *= m / sub.size
    decided = [(k, r) for k, r in enumerate(ref) if r is not None]
    wrong = sum(blocked[sub[k]] != r for k, r in decided)

    n_ob = len(env.obstacles)
    print(
        f"{m} legs, {n_ob} obstacles ({n_ob - 40} prisms, 40 walls), {blocked.mean():.1%} blocked"
    )
    print(f"first call: index, numba import, compile or cached load {t_build:7.2f} s")
    print(
        f"Scene.blocked, numba (all legs)     {t_all:7.3f} s wall {c_all:7.3f} s CPU"
        f"   {m / t_all:10.3g} legs/s"
    )
    print(f"Scene.blocked_to, numba (site by site)  {t_sites:7.3f} s   {m / t_sites:10.3g} legs/s")
    print(
        f"Scene.blocked_to, numba (all sites)     {t_matrix:7.3f} s   {m / t_matrix:10.3g} legs/s"
    )
    print(f"Scene.blocked, numpy (extrap. from {n_np})  {t_np:7.2f} s   ratio {t_np / t_all:6.1f}×")
    print(
        f"per-leg reference (extrap. from {sub.size})  {t_ref:9.0f} s   ratio {t_ref / t_all:8.0f}×"
    )
    print(f"reference decided {len(decided)}/{sub.size} subsampled legs, disagreements: {wrong}")
    if wrong:
        raise SystemExit("the engine disagrees with the per-leg reference")


if __name__ == "__main__":
    main()
