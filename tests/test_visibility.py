"""The visibility engine (Scene.blocked / blocked_to / inside) against the per-leg reference of
tests/visibility_reference.py, on random scenes and on constructed cases (facades, a U notch,
walls), for both engines (numpy and the compiled one), which must agree answer for answer."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from visibility_reference import reference_blocked, reference_inside
from waits import HANG_S

import ris_planner.environment._grid as grid_module
import ris_planner.environment.scene as scene_module
from ris_planner.environment import INSIDE_MARGIN_M, VISIBILITY_TOLERANCE_M, Scene
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment

ENGINES = ("numpy", "numba")

ULPS_INSIDE = 4
"""Facade points are moved this many ulps into their prism (rounding of a RIS centre)."""


def _polygon(rng: np.random.Generator, centre: np.ndarray, radius: float) -> list[list[float]]:
    """A random footprint: convex polygon, concave star, L or U (3–12 vertices)."""
    kind = rng.integers(4)
    if kind <= 1:
        n = int(rng.integers(3, 13))
        ang = (np.arange(n) + rng.uniform(0, 0.8, n)) * 2 * np.pi / n
        rad = radius * (np.ones(n) if kind == 0 else rng.uniform(0.3, 1.0, n))
        pts = np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    elif kind == 2:
        w = rng.uniform(0.3, 0.6)
        pts = radius * (np.array([[0, 0], [1, 0], [1, w], [w, w], [w, 1], [0, 1]]) - 0.5)
    else:
        w = rng.uniform(0.2, 0.4)
        u = [[0, 0], [1, 0], [1, 1], [1 - w, 1], [1 - w, w], [w, w], [w, 1], [0, 1]]
        pts = radius * (np.array(u) - 0.5)
    angle = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return (centre + pts @ rot.T).tolist()


def random_environment(rng: np.random.Generator, prisms: int, walls: int) -> Environment:
    obs: list[dict[str, Any]] = []
    for _ in range(prisms):
        raised = rng.uniform() < 0.3
        obs.append(
            {
                "kind": "prism",
                "footprint": _polygon(rng, rng.uniform(-20, 20, 2), rng.uniform(2, 7)),
                "base_m": float(rng.uniform(0.5, 3)) if raised else 0.0,
                "height_m": float(rng.uniform(1, 10)),
            }
        )
    for _ in range(walls):
        s = rng.uniform(-20, 20, 2)
        obs.append(
            {
                "kind": "wall",
                "start": s.tolist(),
                "end": (s + rng.uniform(-8, 8, 2)).tolist(),
                "base_m": float(rng.choice([0.0, rng.uniform(0, 2)])),
                "height_m": float(rng.uniform(1, 5)),
            }
        )
    return Environment.model_validate({"obstacles": obs})


def random_legs(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Legs of all kinds: random, over the roofs, vertical, horizontal, zero-length."""
    a = np.c_[rng.uniform(-25, 25, (m, 2)), rng.uniform(0, 12, m)]
    b = np.c_[rng.uniform(-25, 25, (m, 2)), rng.uniform(0, 12, m)]
    k = m // 8
    a[:k, 2], b[:k, 2] = rng.uniform(13.5, 20, k), rng.uniform(13.5, 20, k)  # over the roofs
    b[k : 2 * k, :2] = a[k : 2 * k, :2]  # vertical
    b[2 * k : 3 * k, 2] = a[2 * k : 3 * k, 2]  # horizontal
    b[3 * k : 3 * k + 4] = a[3 * k : 3 * k + 4]  # zero length
    return a, b


def check_against_reference(env: Environment, a: np.ndarray, b: np.ndarray) -> int:
    """Both engines equal the reference on every leg it decides; returns how many it decided."""
    got = {e: Scene(env, engine=e).blocked(a, b) for e in ENGINES}
    np.testing.assert_array_equal(got["numpy"], got["numba"])
    decided = 0
    for i in range(a.shape[0]):
        ref = reference_blocked(a[i], b[i], env)
        if ref is not None:
            decided += 1
            assert got["numpy"][i] == ref, (i, a[i].tolist(), b[i].tolist(), ref)
    return decided


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_scenes_equal_the_per_leg_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    env = random_environment(rng, prisms=12, walls=4)
    a, b = random_legs(rng, 160)
    decided = check_against_reference(env, a, b)
    assert decided >= 150  # the unspecified band is thin: almost every leg is decided
    blocked = Scene(env).blocked(a, b)
    assert 0.2 < blocked.mean() < 0.9  # the scenes test both answers


def test_many_legs_both_engines_agree_and_blocked_to_equals_blocked() -> None:
    rng = np.random.default_rng(7)
    env = random_environment(rng, prisms=40, walls=10)
    a, b = random_legs(rng, 20_000)
    np.testing.assert_array_equal(
        Scene(env, engine="numpy").blocked(a, b), Scene(env, engine="numba").blocked(a, b)
    )
    target = np.array([1.0, 2.0, 3.0])
    for engine in ENGINES:
        scene = Scene(env, engine=engine)
        by_target = scene.blocked_to(a, target)
        np.testing.assert_array_equal(by_target, scene.blocked(a, np.tile(target, (len(a), 1))))
        np.testing.assert_array_equal(by_target, scene.blocked(a, target))  # broadcast
        targets = np.array([target, [-4.0, 0.5, 8.0], [10.0, -3.0, 0.0]])
        matrix = scene.blocked_to(a[:500], targets)
        assert matrix.shape == (3, 500)
        for s, t in enumerate(targets):
            np.testing.assert_array_equal(matrix[s], scene.blocked(a[:500], t))  # reversed


def test_walk_in_chunks_keeps_leg_order(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    env = random_environment(rng, prisms=10, walls=3)
    a, b = random_legs(rng, 300)
    whole = Scene(env, engine="numpy").blocked(a, b)
    monkeypatch.setattr(grid_module, "CHUNK_LEGS", 7)
    np.testing.assert_array_equal(Scene(env, engine="numpy").blocked(a, b), whole)


def _convex_prism(rng: np.random.Generator) -> Prism:
    n = int(rng.integers(3, 10))
    ang = (np.arange(n) + rng.uniform(0, 0.6, n)) * 2 * np.pi / n
    r = rng.uniform(3, 30)
    centre = rng.uniform(-500, 500, 2)
    fp = centre + r * np.c_[np.cos(ang), np.sin(ang)]
    return Prism(footprint=fp.tolist(), base_m=float(rng.uniform(0, 3)), height_m=20.0)


def _towards(p: np.ndarray, q: np.ndarray, ulps: int) -> np.ndarray:
    for _ in range(ulps):
        p = np.nextafter(p, q)
    return p


@pytest.mark.parametrize("engine", ENGINES)
def test_legs_from_a_facade_a_few_ulps_inside_are_clear_and_inward_ones_blocked(
    engine: str,
) -> None:
    rng = np.random.default_rng(11)
    starts, outward, inward = [], [], []
    prisms = []
    for _ in range(60):
        prism = _convex_prism(rng)
        v = prism.vertices
        n = v.shape[0]
        e = int(rng.integers(n))
        p0, p1 = v[e], v[(e + 1) % n]
        centre = v.mean(axis=0)
        xy = p0 + rng.uniform(0.05, 0.95) * (p1 - p0)
        tangent = (p1 - p0) / np.linalg.norm(p1 - p0)
        normal = np.array([tangent[1], -tangent[0]])
        if normal @ (xy - centre) < 0:
            normal = -normal
        z = rng.uniform(prism.base_m + 1, prism.top_m - 1)
        start = _towards(np.array([*xy, z]), np.array([*centre, z]), ULPS_INSIDE)
        # outward: into the half-space in front of the facade (never back into a convex prism)
        out_dir = np.array([*(normal + rng.uniform(-2, 2) * tangent), rng.uniform(-0.5, 0.5)])
        starts.append(start)
        outward.append(start + rng.uniform(1, 50) * out_dir)
        inward.append(np.array([*(2 * centre - xy), z]))  # through the building
        prisms.append(prism)
    for prism, s, o, i in zip(prisms, starts, outward, inward, strict=True):
        scene = Scene(Environment(obstacles=[prism]), engine=engine)
        assert not scene.blocked(s, o)[0]
        assert not scene.blocked(o, s)[0]  # either direction
        assert scene.blocked(s, i)[0]
    # a RIS on the roof looking up, and one at a footprint vertex looking out
    prism = prisms[0]
    v = prism.vertices
    roof = _towards(np.array([*v.mean(axis=0), prism.top_m]), np.zeros(3), ULPS_INSIDE)
    corner = np.array([*v[0], 0.5 * (prism.base_m + prism.top_m)])
    away = np.array([*(v[0] + 10 * (v[0] - v.mean(axis=0))), corner[2] + 3])
    scene = Scene(Environment(obstacles=[prism]), engine=engine)
    assert not scene.blocked(roof, roof + np.array([3.0, -2.0, 10.0]))[0]
    assert not scene.blocked(corner, away)[0]


U_NOTCH = Prism(
    name="u",
    footprint=[[0, 0], [10, 0], [10, 10], [7, 10], [7, 3], [3, 3], [3, 10], [0, 10]],
    height_m=6.0,
)
"""A U-shaped footprint: arms 3 m wide, a notch x ∈ (3, 7), y ∈ (3, 10) open to +y."""


@pytest.mark.parametrize("engine", ENGINES)
def test_u_notch(engine: str) -> None:
    scene = Scene(Environment(obstacles=[U_NOTCH]), engine=engine)
    legs = {
        # (a, b): blocked
        ((5, 20, 2), (5, 3.05, 2)): False,  # down the notch to 5 cm from its bottom
        ((3.05, 15, 2), (6.95, 3.05, 1)): False,  # diagonally through the notch
        ((-5, 5, 2), (15, 5, 2)): True,  # through both arms
        ((1.5, 15, 2), (1.5, 5, 2)): True,  # into the left arm
        ((5, 20, 7), (5, 5, 6.5)): False,  # over the roof
        # passing 0.35 mm inside the reflex corner (3, 3): the inside piece's midpoint is
        # almost on the corner, but the piece is 1.5 m deep elsewhere
        ((-1, 7 - 5e-4, 2), (7, -1 - 5e-4, 2)): True,
        # down the notch to 0.7 mm from the same corner: never inside
        ((5, 20, 2), (3 + 5e-4, 3 + 5e-4, 2)): False,
        # along the notch's inner face 0.5 mm inside the arm (no deeper than tol)
        ((3 - 5e-4, 9.5, 2), (3 - 5e-4, 4, 2)): False,
        # along the same face 5 mm inside the arm
        ((3 - 5e-3, 9.5, 2), (3 - 5e-3, 4, 2)): True,
    }
    a = np.array([k[0] for k in legs], dtype=float)
    b = np.array([k[1] for k in legs], dtype=float)
    np.testing.assert_array_equal(scene.blocked(a, b), list(legs.values()))
    env = Environment(obstacles=[U_NOTCH])
    for (p, q), want in legs.items():
        ref = reference_blocked(np.array(p, float), np.array(q, float), env)
        assert ref in (None, want)


@pytest.mark.parametrize("engine", ENGINES)
def test_walls(engine: str) -> None:
    wall = {"kind": "wall", "start": [0, -5], "end": [0, 5], "base_m": 1.0, "height_m": 2.0}
    scene = Scene(Environment.model_validate({"obstacles": [wall]}), engine=engine)
    legs = {
        ((-3, 0, 2), (3, 1, 2)): True,  # through the middle
        ((-3, 0, 2), (-1, 1, 2)): False,  # stays on one side
        ((-3, 0, 3.5), (3, 0, 3.5)): False,  # over it
        ((-3, 0, 0.5), (3, 0, 0.5)): False,  # under it (base 1 m)
        ((-3, 6, 2), (3, 6, 2)): False,  # past its end
        ((0, 0, 2), (3, 0, 2)): False,  # a RIS on the wall looks out
        ((-1e-12, 0, 2), (-3, 2, 2)): False,  # a few ulps off the plane, same side
    }
    a = np.array([k[0] for k in legs], dtype=float)
    b = np.array([k[1] for k in legs], dtype=float)
    np.testing.assert_array_equal(scene.blocked(a, b), list(legs.values()))


@pytest.mark.parametrize("engine", ENGINES)
def test_degenerate_batches(engine: str) -> None:
    scene = Scene(Environment(obstacles=[U_NOTCH]), engine=engine)
    assert scene.blocked(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)
    assert scene.blocked_to(np.zeros((0, 3)), [1, 2, 3]).shape == (0,)
    one = scene.blocked([[-5, 5, 2]], [[15, 5, 2]])
    assert one.shape == (1,) and one[0]
    deep, outside = [1.5, 5.0, 3.0], [5.0, 5.0, 3.0]
    np.testing.assert_array_equal(scene.blocked([deep, outside], [deep, outside]), [True, False])
    assert Scene.from_environment(None).blocked([[0, 0, 0]], [[1, 1, 1]]).tolist() == [False]
    with pytest.raises(ValueError, match="tolerance"):
        scene.blocked([[0, 0, 0]], [[1, 1, 1]], tol=0.5)
    with pytest.raises(ValueError, match="b: coordinates must be finite"):
        scene.blocked([[0, 0, 0]], [[1, np.nan, 1]])
    with pytest.raises(ValueError, match=r"points: points must be \[x, y, z\]"):
        scene.inside([[0, 0]])


def test_grid_with_huge_and_small_obstacles_stays_small_and_exact() -> None:
    """A 10 km prism among 30 m ones: the grid coarsens instead of registering the big box in
    every cell, and the answers stay those of the reference (legs above the big roof)."""
    rng = np.random.default_rng(9)
    big = [[0, 0], [1e4, 0], [1e4, 1e4], [0, 1e4]]
    obs: list[dict[str, Any]] = [{"kind": "prism", "footprint": big, "height_m": 5}]
    corner = np.array([[0, 0], [30, 0], [0, 30]])
    for c in rng.uniform(0, 1e4, (300, 2)):
        fp = (c + corner).tolist()
        obs.append({"kind": "prism", "footprint": fp, "base_m": 6.0, "height_m": 3.0})
    env = Environment.model_validate({"obstacles": obs})
    scene = Scene(env, engine="numpy")
    a = np.c_[rng.uniform(0, 1e4, (60, 2)), rng.uniform(5.5, 10, 60)]
    b = a + np.c_[rng.uniform(-1000, 1000, (60, 2)), rng.uniform(-0.4, 0.4, 60)]
    got = scene.blocked(a, b)
    grid = scene._index.grid
    assert grid.cell_items.size <= grid_module.MAX_REGISTRATIONS_PER_OBSTACLE * len(obs)
    assert got.any() and not got.all()
    for i in range(60):
        ref = reference_blocked(a[i], b[i], env)
        assert ref is None or got[i] == ref


def test_inside_equals_the_reference() -> None:
    rng = np.random.default_rng(5)
    env = random_environment(rng, prisms=25, walls=5)
    pts = np.c_[rng.uniform(-25, 25, (3000, 2)), rng.uniform(0, 12, 3000)]
    got = Scene(env).inside(pts)
    ref = reference_inside(pts, env, INSIDE_MARGIN_M)
    assert None not in ref
    np.testing.assert_array_equal(got, ref)
    assert 0.05 < np.mean(got >= 0) < 0.8
    assert Scene(env).inside(np.zeros((0, 3))).shape == (0,)


def test_inside_margin_and_first_prism() -> None:
    inner = Prism(footprint=[[1, 1], [4, 1], [4, 4], [1, 4]], height_m=3.0)
    outer = Prism(footprint=[[0, 0], [5, 0], [5, 5], [0, 5]], height_m=3.0)
    scene = Scene(Environment(obstacles=[outer, inner]))
    pts = [[2, 2, 1], [0.005, 2, 1], [0.02, 2, 1], [6, 6, 1], [2, 2, 2.995]]
    np.testing.assert_array_equal(scene.inside(pts), [0, -1, 0, -1, -1])
    assert VISIBILITY_TOLERANCE_M < INSIDE_MARGIN_M


@pytest.fixture
def walk_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The leg counts of the compiled walk's calls (the engine ``auto`` picked), as they
    happen."""
    calls: list[int] = []
    compiled = scene_module._Index.walk_compiled

    def spy(self: Any, a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray:
        calls.append(a.shape[0])
        return compiled(self, a, b, tol)

    monkeypatch.setattr(scene_module._Index, "walk_compiled", spy)
    return calls


def test_auto_engine_compiles_only_large_queries(
    monkeypatch: pytest.MonkeyPatch, walk_calls: list[int]
) -> None:
    calls = walk_calls
    monkeypatch.setattr(scene_module, "compiled_code_loaded", lambda: False)  # a fresh process
    scene = Scene(Environment(obstacles=[U_NOTCH]))
    a, b = np.tile([[-5.0, 5, 2]], (20, 1)), np.tile([[15.0, 5, 2]], (20, 1))
    assert scene.blocked(a, b).all() and calls == []
    monkeypatch.setattr(scene_module, "AUTO_COMPILED_MIN_WORK", 20)
    assert scene.blocked(a, b).all() and calls == [20]
    assert Scene(scene.environment, engine="numpy").blocked(a, b).all() and calls == [20]


def test_auto_engine_threshold_drops_once_compiled_code_is_loaded(
    monkeypatch: pytest.MonkeyPatch, walk_calls: list[int]
) -> None:
    calls = walk_calls
    scene = Scene(Environment(obstacles=[U_NOTCH]))
    n = scene_module.AUTO_COMPILED_WARM_MIN_WORK  # one obstacle: legs × obstacles = n
    assert n < scene_module.AUTO_COMPILED_MIN_WORK
    a, b = np.tile([[-5.0, 5, 2]], (n, 1)), np.tile([[15.0, 5, 2]], (n, 1))
    monkeypatch.setattr(scene_module, "compiled_code_loaded", lambda: False)
    assert scene.blocked(a, b).all() and calls == []
    monkeypatch.setattr(scene_module, "compiled_code_loaded", lambda: True)
    assert scene.blocked(a[1:], b[1:]).all() and calls == []  # one leg below the threshold
    assert scene.blocked(a, b).all() and calls == [n]


def test_compiled_code_loaded_turns_true_with_the_first_kernel() -> None:
    code = (
        "import numba\n"
        "from ris_planner.runtime.kernels import compiled_code_loaded\n"
        "assert not compiled_code_loaded()\n"
        "from ris_planner.inversion import _crb_jit\n"
        "assert not compiled_code_loaded()\n"
        "_crb_jit.work_rows(7)\n"
        "assert compiled_code_loaded()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_S
    )
    assert done.returncode == 0, done.stderr


def test_bench_visibility_warm_table_runs() -> None:
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, str(root / "benchmarks" / "bounds" / "bench_visibility.py"), "--warm"],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    rows = [line.split() for line in done.stdout.splitlines()[2:]]
    assert [r[-1] for r in rows] == ["numpy", "numpy", "numba", "numba", "numba"], done.stdout
