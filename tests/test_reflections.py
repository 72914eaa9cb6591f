"""First-order specular reflections (docs/concepts/environment.md, "Reflections") against a
brute-force reference: explicit mirror points computed face by face in plain Python, explicit
segment-versus-obstacle tests (the exact maximum depth of a segment in a convex prism, the
crossing of a wall), on seeded random scenes."""

from __future__ import annotations

import cmath
import math
import random

import numpy as np
import pytest
from tolerance import assert_close

from ris_planner.environment.materials import (
    ITU_P2040,
    fresnel_te,
    relative_permittivity,
)
from ris_planner.environment.reflections import face_table, specular_paths
from ris_planner.environment.scene import Scene
from ris_planner.obstacles import Environment

TOL = 1e-3  # the engine's visibility tolerance (environment.VISIBILITY_TOLERANCE_M)
BAND = 1e-7  # (leg, face) combinations this close to a threshold are skipped (unspecified)
CARRIER_HZ = 28e9
EPS0 = 8.8541878128e-12
MATERIALS = sorted(ITU_P2040)


def _random_scene(rng: random.Random) -> dict:
    obstacles = []
    for _ in range(rng.randint(1, 4)):
        n = rng.randint(3, 6)
        angles = sorted(rng.uniform(0, 2 * math.pi) for _ in range(n))
        gaps = [(angles[(i + 1) % n] - angles[i]) % (2 * math.pi) for i in range(n)]
        if min(gaps) < 0.3:
            continue
        cx, cy, r = rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(1, 4)
        pts = [[cx + r * math.cos(a), cy + r * math.sin(a)] for a in angles]
        if rng.random() < 0.5:
            pts.reverse()  # clockwise footprints too
        base = rng.choice([0.0, rng.uniform(0, 2)])
        obstacles.append(
            {
                "kind": "prism",
                "footprint": pts,
                "base_m": base,
                "height_m": rng.uniform(2, 10),
                "material": rng.choice(MATERIALS),
            }
        )
    for _ in range(rng.randint(1, 3)):
        x0, y0 = rng.uniform(-10, 10), rng.uniform(-10, 10)
        a, length = rng.uniform(0, 2 * math.pi), rng.uniform(2, 10)
        obstacles.append(
            {
                "kind": "wall",
                "start": [x0, y0],
                "end": [x0 + length * math.cos(a), y0 + length * math.sin(a)],
                "base_m": rng.choice([0.0, rng.uniform(0, 2)]),
                "height_m": rng.uniform(2, 8),
                "material": rng.choice(MATERIALS),
            }
        )
    return {"obstacles": obstacles}


# ---- plain-Python geometry of the reference -------------------------------------------------


def _sub(a, b):
    return [a[i] - b[i] for i in range(min(len(a), len(b)))]


def _dot2(a, b):
    return a[0] * b[0] + a[1] * b[1]


def _prism_planes(ob: dict) -> list[tuple[list[float], float]]:
    """Inward half-planes (unit normal n, offset c: n·x − c ≥ 0 inside) of a convex footprint,
    the inside found from the centroid (not from the winding)."""
    pts = ob["footprint"]
    n = len(pts)
    cx = sum(p[0] for p in pts) / n
    cy = sum(p[1] for p in pts) / n
    planes = []
    for i in range(n):
        s, e = pts[i], pts[(i + 1) % n]
        ex, ey = e[0] - s[0], e[1] - s[1]
        length = math.hypot(ex, ey)
        nx, ny = -ey / length, ex / length
        if nx * (cx - s[0]) + ny * (cy - s[1]) < 0:
            nx, ny = -nx, -ny
        planes.append(([nx, ny], nx * s[0] + ny * s[1]))
    return planes


def _max_depth(a, b, ob: dict) -> float:
    """The exact maximum over the segment a–b of min(distance to each face plane) (the depth in
    a convex prism, negative outside): a concave piecewise-linear function of t, maximal at
    t = 0, 1 or where two of its affine pieces cross."""
    d = _sub(b, a)
    base, top = ob["base_m"], ob["base_m"] + ob["height_m"]
    pieces = [
        (n[0] * a[0] + n[1] * a[1] - c, n[0] * d[0] + n[1] * d[1]) for n, c in _prism_planes(ob)
    ]
    pieces += [(a[2] - base, d[2]), (top - a[2], -d[2])]
    ts = [0.0, 1.0]
    for i in range(len(pieces)):
        for j in range(i + 1, len(pieces)):
            (p0, p1), (q0, q1) = pieces[i], pieces[j]
            if p1 != q1:
                t = (q0 - p0) / (p1 - q1)
                if 0.0 < t < 1.0:
                    ts.append(t)
    return max(min(c0 + c1 * t for c0, c1 in pieces) for t in ts)


def _wall_blocks(a, b, ob: dict) -> bool | None:
    s, e = ob["start"], ob["end"]
    length = math.hypot(e[0] - s[0], e[1] - s[1])
    u = [(e[0] - s[0]) / length, (e[1] - s[1]) / length]
    n = [-u[1], u[0]]
    sa, sb = _dot2(_sub(a, s), n), _dot2(_sub(b, s), n)
    if min(abs(abs(sa) - TOL), abs(abs(sb) - TOL)) < BAND:
        return None
    if not (sa * sb < 0 and abs(sa) > TOL and abs(sb) > TOL):
        return False
    t = sa / (sa - sb)
    x = [a[i] + t * (b[i] - a[i]) for i in range(3)]
    along = _dot2(_sub(x, s), u)
    margin = min(along, length - along, x[2] - ob["base_m"], ob["base_m"] + ob["height_m"] - x[2])
    if abs(margin - TOL) < BAND:
        return None
    return margin > TOL


def _blocked(a, b, env: dict) -> bool | None:
    """True/False, or None when a threshold is within BAND (the combination is skipped)."""
    unsure = False
    for ob in env["obstacles"]:
        if ob["kind"] == "prism":
            depth = _max_depth(a, b, ob)
            if abs(depth - TOL) < BAND:
                unsure = True
            elif depth > TOL:
                return True
        else:
            r = _wall_blocks(a, b, ob)
            if r is True:
                return True
            unsure |= r is None
    return None if unsure else False


def _faces(env: dict) -> list[tuple[int, int, list, list, list[float], bool, dict]]:
    """(obstacle, face, start, end, front normal, two-sided, obstacle) for every face."""
    out = []
    for k, ob in enumerate(env["obstacles"]):
        if ob["kind"] == "wall":
            s, e = ob["start"], ob["end"]
            length = math.hypot(e[0] - s[0], e[1] - s[1])
            out.append((k, 0, s, e, [-(e[1] - s[1]) / length, (e[0] - s[0]) / length], True, ob))
        else:
            pts = ob["footprint"]
            planes = _prism_planes(ob)
            for i in range(len(pts)):
                inward = planes[i][0]
                out.append(
                    (k, i, pts[i], pts[(i + 1) % len(pts)], [-inward[0], -inward[1]], False, ob)
                )
    return out


def _reference(src, snk, env: dict, carrier_hz: float, visibility: bool = True):
    """Per face: None (skip), or (valid, point, length, coefficient); ``visibility`` False
    ignores blockage."""
    rows = []
    for _, _, s, e, n, two_sided, ob in _faces(env):
        ds, dt = _dot2(_sub(src, s), n), _dot2(_sub(snk, s), n)
        if two_sided and ds < 0:
            n, ds, dt = [-n[0], -n[1]], -ds, -dt
        if min(abs(ds - TOL), abs(dt - TOL)) < BAND:
            rows.append(None)
            continue
        if not (ds > TOL and dt > TOL):
            rows.append((False, None, None, None))
            continue
        image = [src[0] - 2 * ds * n[0], src[1] - 2 * ds * n[1], src[2]]
        # the reflection point: where image → sink crosses the plane (signed distance 0)
        t = ds / (ds + dt)
        point = [image[i] + t * (snk[i] - image[i]) for i in range(3)]
        length = math.hypot(e[0] - s[0], e[1] - s[1])
        along = ((point[0] - s[0]) * (e[0] - s[0]) + (point[1] - s[1]) * (e[1] - s[1])) / length
        base, top = ob["base_m"], ob["base_m"] + ob["height_m"]
        margins = [along, length - along, point[2] - base, top - point[2]]
        if min(abs(m) for m in margins) < 1e-9:
            rows.append(None)
            continue
        if min(margins) < 0:
            rows.append((False, None, None, None))
            continue
        b1, b2 = (_blocked(src, point, env), _blocked(point, snk, env)) if visibility else (0, 0)
        if (b1 is None or b2 is None) and not (b1 or b2):
            rows.append(None)  # unspecified and not blocked by the other segment
            continue
        if b1 or b2:
            rows.append((False, None, None, None))
            continue
        total = math.dist(src, point) + math.dist(point, snk)
        inc = _sub(point, src)
        cos_t = abs(inc[0] * n[0] + inc[1] * n[1]) / math.dist(src, point)
        a_, b_, c_, d_, _, _ = ITU_P2040[ob["material"]]
        f_ghz = carrier_hz / 1e9
        eta = complex(a_ * f_ghz**b_, -(c_ * f_ghz**d_) / (2 * math.pi * carrier_hz * EPS0))
        root = cmath.sqrt(eta - (1 - cos_t**2))
        rows.append((True, point, total, (cos_t - root) / (cos_t + root)))
    return rows


def _outside(p, env: dict) -> bool:
    """More than 2 cm outside every prism (sampled points inside are not legs' ends)."""
    for ob in env["obstacles"]:
        if ob["kind"] == "prism":
            d = min(_dot2(n, p) - c for n, c in _prism_planes(ob))
            dz = min(p[2] - ob["base_m"], ob["base_m"] + ob["height_m"] - p[2])
            if min(d, dz) > -0.02:
                return False
    return True


def _points(rng: random.Random, env: dict, count: int) -> list[list[float]]:
    out: list[list[float]] = []
    while len(out) < count:
        p = [rng.uniform(-14, 14), rng.uniform(-14, 14), rng.uniform(0.5, 8)]
        if _outside(p, env):
            out.append(p)
    return out


@pytest.mark.parametrize("seed", range(50))
def test_specular_paths_match_the_brute_force_reference(seed: int) -> None:
    rng = random.Random(seed)
    doc = _random_scene(rng)
    env = Environment.model_validate(doc)
    src, snk = _points(rng, doc, 12), _points(rng, doc, 12)
    got = specular_paths(Scene(env, engine="numpy"), np.array(src), np.array(snk), CARRIER_HZ)
    faces = _faces(doc)
    assert got.valid.shape == (12, len(faces))
    assert got.obstacle[0].tolist() == [f[0] for f in faces]
    assert got.face[0].tolist() == [f[1] for f in faces]
    checked = valid = 0
    for p in range(12):
        for k, row in enumerate(_reference(src[p], snk[p], doc, CARRIER_HZ)):
            if row is None:
                continue
            checked += 1
            ok, point, length, coef = row
            assert bool(got.valid[p, k]) == ok, (seed, p, k, faces[k][:2])
            if not ok:
                assert np.isnan(got.length[p, k]) and got.coefficient[p, k] == 0
                continue
            valid += 1
            # coordinates ≤ 30 m, ~10 roundings apart: 30 · 10 · ε ≈ 7e-14 m absolute
            assert_close(got.point[p, k], np.array(point), atol=1e-12)
            assert_close(got.length[p, k], length, atol=1e-12)
            assert_close(complex(got.coefficient[p, k]).real, coef.real, ulps=1e3, atol=1e-13)
            assert_close(complex(got.coefficient[p, k]).imag, coef.imag, ulps=1e3, atol=1e-13)
    assert checked >= 12 * len(faces) - 2  # skipped combinations are rare


def test_random_scenes_exercise_every_case() -> None:
    """Across the 50 scenes the reference finds valid reflections, ones blocked on either
    segment and ones off the face's extent (so the comparison above cannot pass vacuously)."""
    counts = {"valid": 0, "blocked": 0, "off_face": 0}
    for seed in range(50):
        rng = random.Random(seed)
        doc = _random_scene(rng)
        src, snk = _points(rng, doc, 12), _points(rng, doc, 12)
        env = Environment.model_validate(doc)
        free = specular_paths(Environment(), np.array(src), np.array(snk), CARRIER_HZ)
        assert free.valid.shape == (12, 0)
        got = specular_paths(env, np.array(src), np.array(snk), CARRIER_HZ)
        unblocked = _geometric_only(doc, src, snk)
        counts["valid"] += int(got.valid.sum())
        counts["blocked"] += int((unblocked & ~got.valid).sum())
        counts["off_face"] += int((~unblocked).sum())
    assert counts["valid"] > 100 and counts["blocked"] > 30 and counts["off_face"] > 1000, counts


def _geometric_only(doc: dict, src, snk) -> np.ndarray:
    """[P, K] the reference's reflections ignoring blockage (both segments)."""
    rows = [
        _reference(a, b, doc, CARRIER_HZ, visibility=False) for a, b in zip(src, snk, strict=True)
    ]
    return np.array([[r is not None and r[0] for r in row] for row in rows], dtype=bool)


def test_material_constants_match_published_values_at_9_ghz() -> None:
    """ITU-R P.2040 Table 3 at 9 GHz as MATLAB's buildingMaterialPermittivity (an independent
    implementation of the same recommendation) documents them: (η', σ [S/m])."""
    published = {
        "concrete": (5.31, 0.19305),
        "brick": (3.75, 0.038),
        "plasterboard": (2.94, 0.054914),
        "wood": (1.99, 0.049528),
        "glass": (6.27, 0.059075),
    }
    for material, (eps, sigma) in published.items():
        eta = relative_permittivity(material, 9e9)
        assert_close(eta.real, eps)
        # η'' = σ/(ω ε₀); the published σ has 5 significant digits
        assert_close(-eta.imag * 2 * math.pi * 9e9 * EPS0, sigma, accuracy=1e-4)
    with pytest.raises(ValueError, match="known materials: brick, concrete"):
        relative_permittivity("adamantium", 9e9)


def test_fresnel_limits() -> None:
    """Normal incidence (1 − √η)/(1 + √η); grazing incidence −1; metal ≈ −1 at any angle."""
    eta = relative_permittivity("concrete", 28e9)
    normal = complex(fresnel_te(eta, 1.0))
    want = (1 - cmath.sqrt(eta)) / (1 + cmath.sqrt(eta))
    assert_close([normal.real, normal.imag], [want.real, want.imag])
    grazing = complex(fresnel_te(eta, 0.0))
    assert_close([grazing.real, grazing.imag], [-1.0, 0.0], atol=1e-15)
    metal = fresnel_te(relative_permittivity("metal", 28e9), np.array([1.0, 0.5, 0.1]))
    assert np.all(np.abs(metal + 1) < 1e-3)


def test_single_wall_by_hand() -> None:
    """A wall along x = 0: source (2, −1, 1.5), sink (3, 1, 1.5) reflect at (0, −0.2, 1.5)
    with path length √29 (image (−2, −1, 1.5)); a second wall between them blocks the second
    segment; a prism's back face does not reflect."""
    wall = {"kind": "wall", "start": [0, -5], "end": [0, 5], "height_m": 3, "material": "glass"}
    got = specular_paths(
        Environment.model_validate({"obstacles": [wall]}), [2, -1, 1.5], [3, 1, 1.5], 28e9
    )
    assert got.valid.tolist() == [[True]]
    assert_close(got.point[0, 0], np.array([0.0, -0.2, 1.5]), atol=1e-15)
    assert_close(got.length[0, 0], math.sqrt(29))
    assert_close(got.image[0, 0], np.array([-2.0, -1.0, 1.5]))
    # the same from the other side of the wall (two-sided)
    back = specular_paths(
        Environment.model_validate({"obstacles": [wall]}), [-2, -1, 1.5], [-3, 1, 1.5], 28e9
    )
    assert back.valid.tolist() == [[True]] and back.point[0, 0, 0] == 0.0
    # legs on opposite sides, or the point above the wall: no reflection
    cross = specular_paths(
        Environment.model_validate({"obstacles": [wall]}),
        [[2, -1, 1.5], [2, -1, 5.0]],
        [[-3, 1, 1.5], [3, 1, 5.0]],
        28e9,
    )
    assert cross.valid.tolist() == [[False], [False]]
    screen = {"kind": "wall", "start": [0.5, 0.2], "end": [2.0, 0.2], "height_m": 3}
    blocked = specular_paths(
        Environment.model_validate({"obstacles": [wall, screen]}), [2, -1, 1.5], [3, 1, 1.5], 28e9
    )
    assert not blocked.valid[0, 0]
    box = {"kind": "prism", "footprint": [[0, -5], [-1, -5], [-1, 5], [0, 5]], "height_m": 3}
    prism = specular_paths(
        Environment.model_validate({"obstacles": [box]}), [2, -1, 1.5], [3, 1, 1.5], 28e9
    )
    k = int(np.nonzero(prism.valid[0])[0][0])  # only the face at x = 0 reflects
    assert prism.valid[0].sum() == 1 and prism.face[0, k] == 3
    assert_close(prism.length[0, k], math.sqrt(29))
    faces = face_table(Environment.model_validate({"obstacles": [box]}))
    assert_close(faces.normal[3], np.array([1.0, 0.0]), atol=1e-16)
