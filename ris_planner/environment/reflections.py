"""First-order specular reflections off the vertical faces of an environment (image method;
docs/concepts/environment.md, "Reflections").

Every obstacle contributes vertical rectangular faces (its kind's ``faces``): a wall one
two-sided face, a prism one outward-facing face per footprint edge. For a leg source → sink
and a face, the reflected path exists when

* both ends lie in front of the face (on its outer side; either side of a wall, both on the
  same side), each more than :data:`~ris_planner.environment.scene.VISIBILITY_TOLERANCE_M`
  (1 mm) from its plane;
* the reflection point – where the segment from the source's mirror image to the sink meets
  the face's plane – lies on the face, inside its extent (closed: along the edge and between
  ``base_m`` and the top);
* both segments source → reflection point and reflection point → sink are clear under the
  environment's visibility rules (:meth:`~ris_planner.environment.scene.Scene.blocked`: the
  reflection point lies on a surface, which does not block).

The path length is |sink − source image| and the reflection coefficient the Fresnel TE
coefficient of the face's material at the angle of incidence (:mod:`~ris_planner.environment.
materials`: ITU-R P.2040-1 constants, vertical polarisation). Ground and roof reflections,
diffraction and higher orders are not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ris_planner.environment.materials import fresnel_te, relative_permittivity
from ris_planner.environment.scene import VISIBILITY_TOLERANCE_M, Scene
from ris_planner.obstacles import Environment

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class FaceTable:
    """The vertical faces of an environment, [K] arrays in obstacle order, then face order.

    A face runs from ``start`` to ``end`` ([K, 2]) between z = ``base`` and ``top``; its front
    is the side of ``normal`` ([K, 2], unit, horizontal); ``two_sided`` faces (walls) reflect
    on both sides. ``obstacle`` is the index in ``environment.obstacles``, ``face`` the face's
    index within its obstacle (a prism's footprint edge k runs from vertex k to k + 1),
    ``material`` the obstacle's material.
    """

    start: FloatArray
    end: FloatArray
    base: FloatArray
    top: FloatArray
    normal: FloatArray
    two_sided: BoolArray
    obstacle: IntArray
    face: IntArray
    material: tuple[str, ...]

    @property
    def size(self) -> int:
        return int(self.obstacle.size)


def face_table(environment: Environment) -> FaceTable:
    """Every obstacle's faces (its kind's ``faces()``) stacked in document order."""
    starts, ends, bases, tops, normals, two, obs, idx, mats = [], [], [], [], [], [], [], [], []
    for k, ob in enumerate(environment.obstacles):
        f = ob.faces()
        n = f.start.shape[0]
        starts.append(f.start)
        ends.append(f.end)
        normals.append(f.normal)
        bases.append(np.full(n, ob.base_m))
        tops.append(np.full(n, ob.top_m))
        two.append(np.full(n, f.two_sided))
        obs.append(np.full(n, k))
        idx.append(np.arange(n))
        mats.extend([ob.material] * n)
    if not starts:
        z2, z1 = np.zeros((0, 2)), np.zeros(0)
        return FaceTable(
            z2, z2, z1, z1, z2, np.zeros(0, bool), np.zeros(0, int), np.zeros(0, int), ()
        )
    return FaceTable(
        np.concatenate(starts),
        np.concatenate(ends),
        np.concatenate(bases),
        np.concatenate(tops),
        np.concatenate(normals),
        np.concatenate(two),
        np.concatenate(obs).astype(int),
        np.concatenate(idx).astype(int),
        tuple(mats),
    )


@cache
def _permittivity(material: str, carrier_hz: float) -> complex:
    return relative_permittivity(material, carrier_hz)


@dataclass(frozen=True)
class SpecularPaths:
    """First-order reflections of P legs off K faces ([P, K] arrays; K = every face of the
    environment, :class:`FaceTable` order).

    ``point`` [P, K, 3] reflection points (NaN where not ``valid``); ``valid`` [P, K] whether
    the reflected path exists (geometry and both segments clear); ``length`` [P, K] total
    path length source → point → sink = |sink − source image| [m] (NaN where not valid);
    ``coefficient`` [P, K] complex Fresnel TE reflection coefficient (0 where not valid);
    ``cos_incidence`` [P, K] cosine of the angle of incidence (0 where not valid);
    ``obstacle`` [P, K] index of the reflecting obstacle in ``environment.obstacles`` and
    ``face`` [P, K] the face's index within it; ``image`` [P, K, 3] the source's mirror image
    in the face's plane (NaN where not valid): the sink sees the reflected wave arrive from
    it, at distance ``length``.
    """

    point: FloatArray
    valid: BoolArray
    length: FloatArray
    coefficient: ComplexArray
    cos_incidence: FloatArray
    obstacle: IntArray
    face: IntArray
    image: FloatArray


def _as_scene(scene_or_environment: Scene | Environment | None) -> Scene:
    if isinstance(scene_or_environment, Scene):
        return scene_or_environment
    return Scene.from_environment(scene_or_environment)


def specular_paths(
    scene_or_environment: Scene | Environment | None,
    sources: ArrayLike,
    sinks: ArrayLike,
    carrier_hz: float,
) -> SpecularPaths:
    """First-order specular reflections of the legs sources[p] → sinks[p] off every face of
    the environment (image method; rules in the module docstring).

    scene_or_environment : a :class:`~ris_planner.environment.scene.Scene`, an
    ``Environment`` or ``None`` (no faces: K = 0); sources, sinks : [P, 3] (or one [3],
    broadcast); carrier_hz : the carrier frequency for the materials' permittivity.
    Returns a :class:`SpecularPaths` of [P, K] arrays. Pure and batched: the geometry of all
    P × K (leg, face) combinations is vectorised, the visibility of both segments is one
    :meth:`Scene.blocked` query over the geometrically valid ones.
    """
    scene = _as_scene(scene_or_environment)
    src = np.asarray(sources, dtype=float)
    snk = np.asarray(sinks, dtype=float)
    if src.shape[-1:] != (3,) or snk.shape[-1:] != (3,) or src.ndim > 2 or snk.ndim > 2:
        raise ValueError(f"sources and sinks must be [P, 3] or [3], got {src.shape}, {snk.shape}")
    src, snk = np.broadcast_arrays(np.atleast_2d(src), np.atleast_2d(snk))
    if not (np.all(np.isfinite(src)) and np.all(np.isfinite(snk))):
        raise ValueError("sources and sinks must be finite")
    if not (np.isfinite(carrier_hz) and carrier_hz > 0):
        raise ValueError(f"carrier_hz must be finite and > 0, got {carrier_hz}")
    faces = face_table(scene.environment)
    p, k = src.shape[0], faces.size
    tol = VISIBILITY_TOLERANCE_M
    n = faces.normal  # [K, 2]
    # [P, K] signed distances of source and sink from each face's plane (front side > 0)
    ds = (src[:, None, 0] - faces.start[:, 0]) * n[:, 0] + (
        src[:, None, 1] - faces.start[:, 1]
    ) * n[:, 1]
    dt = (snk[:, None, 0] - faces.start[:, 0]) * n[:, 0] + (
        snk[:, None, 1] - faces.start[:, 1]
    ) * n[:, 1]
    flip = faces.two_sided[None, :] & (ds < 0)
    ds = np.where(flip, -ds, ds)
    dt = np.where(flip, -dt, dt)
    front = (ds > tol) & (dt > tol)
    ds_safe = np.where(front, ds, 1.0)
    dt_safe = np.where(front, dt, 1.0)
    sign = np.where(flip, -1.0, 1.0)  # the side the legs are on
    # [P, K, 3] image of the source: mirrored through the plane (z unchanged)
    image = np.broadcast_to(src[:, None, :], (p, k, 3)).copy()
    image[..., 0] -= 2 * ds * sign * n[None, :, 0]
    image[..., 1] -= 2 * ds * sign * n[None, :, 1]
    u = ds_safe / (ds_safe + dt_safe)
    point = image + u[..., None] * (snk[:, None, :] - image)
    e = faces.end - faces.start
    elen = np.hypot(e[:, 0], e[:, 1])
    along = (
        (point[..., 0] - faces.start[:, 0]) * e[:, 0]
        + (point[..., 1] - faces.start[:, 1]) * e[:, 1]
    ) / elen
    z = point[..., 2]
    valid = front & (along >= 0) & (along <= elen) & (z >= faces.base) & (z <= faces.top)
    rows, cols = np.nonzero(valid)
    if rows.size and not scene.empty:
        pts = point[rows, cols]
        legs_a = np.concatenate([src[rows], pts])
        legs_b = np.concatenate([pts, snk[rows]])
        blocked = scene.blocked(legs_a, legs_b).reshape(2, rows.size).any(axis=0)
        valid[rows[blocked], cols[blocked]] = False
    length = np.linalg.norm(snk[:, None, :] - image, axis=-1)
    cos_inc = np.where(valid, (ds_safe + dt_safe) / np.where(valid, length, 1.0), 0.0)
    eta = np.array([_permittivity(m, float(carrier_hz)) for m in faces.material], dtype=complex)
    coefficient = np.where(valid, fresnel_te(np.broadcast_to(eta, (p, k)), cos_inc), 0.0)
    nan3 = np.where(valid[..., None], 1.0, np.nan)
    return SpecularPaths(
        point=point * nan3,
        valid=valid,
        length=np.where(valid, length, np.nan),
        coefficient=np.asarray(coefficient, dtype=complex),
        cos_incidence=cos_inc,
        obstacle=np.broadcast_to(faces.obstacle, (p, k)).copy(),
        face=np.broadcast_to(faces.face, (p, k)).copy(),
        image=image * nan3,
    )
