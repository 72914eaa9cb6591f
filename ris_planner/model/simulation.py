"""The simulation document: a scenario plus multipath and estimator settings (JSON contract).

``{"scenario": {...}, "multipath": {...}, "estimator": {...}}``; a plain scenario document is
accepted too (no multipath, default estimator). Defaults follow the paper's Simulation
Parameters: N_F = 2^10 delay bins, a 0.02 step for the (ξ, ζ) grid, a 2×2×2 m search box with a
0.2 m step around the TX, equal weights w_ij and w_ℓ, Σ = I.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ris_planner.core.errors import LimitExceededError
from ris_planner.model.scenario import (
    DocumentModel,
    Point3,
    finite_point,
)

MAX_SEARCH_CANDIDATES = 2_000_000
"""More TX candidates than this in the coarse search box is refused (memory ~ 1 KB each)."""

ScatterSide = Literal["tx", "rx"]
"""Which RIS channel hop a scattering point (SP) sits on: ``tx`` makes TX–SP–RIS–RX paths
(the SP near the TX), ``rx`` makes TX–RIS–SP–RX paths (near the RX). Every SP also makes one
uncontrolled TX–SP–RX path (eq. channel_LOS_MP)."""


class Scatterer(DocumentModel):
    """One scattering point with radar cross section c [m²] (Simulation Parameters)."""

    position: Point3
    rcs_m2: float = Field(0.5, gt=0, le=1e4, allow_inf_nan=False, description="RCS c [m²]")
    side: ScatterSide = "tx"

    @field_validator("position")
    @classmethod
    def _check(cls, v: list[float]) -> list[float]:
        return finite_point(v, "scatterer position")


class ScattererCluster(DocumentModel):
    """``count`` SPs drawn uniformly in a horizontal disk (redrawn every realisation)."""

    center: Point3
    radius_m: float = Field(1.0, ge=0, le=1e3, allow_inf_nan=False)
    count: int = Field(5, ge=1, le=1000)
    rcs_m2: float = Field(0.5, gt=0, le=1e4, allow_inf_nan=False, description="RCS c [m²]")
    side: ScatterSide = "tx"

    @field_validator("center")
    @classmethod
    def _check(cls, v: list[float]) -> list[float]:
        return finite_point(v, "cluster center")


MIN_SCATTERER_DISTANCE_M = 0.5
"""Closest a scattering point may come to a UE (TX or RX). The TX–SP–RX and SP–RIS paths of
eq. channel_LOS_MP have gains ∝ 1/(d₁d₂) (radar equation): an SP at a UE makes the gain
diverge and its delay and angles at the UE degenerate (NaN at d = 0), and the point-scatterer
model holds only in the scatterer's far field (≳ its size √c ≈ 0.7 m for the default
c = 0.5 m²). The paper's clusters stay ≥ 1.2 m from its UEs. A document whose scatterer or
cluster disk comes closer to a UE is refused (:func:`scatterer_too_close`)."""


def scatterer_distances(multipath: Multipath, points: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(``scatterers.j`` / ``clusters.j``, the closest distance [P] of each point [P, 3] to
    it): a fixed SP's Euclidean distance; a cluster's to the nearest point of its horizontal
    disk (√(max(ρ − R, 0)² + Δz²), ρ the horizontal distance to the centre), where an SP
    may land."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    out = []
    for j, s in enumerate(multipath.scatterers):
        out.append((f"scatterers.{j}", np.linalg.norm(pts - np.asarray(s.position), axis=-1)))
    for j, c in enumerate(multipath.clusters):
        centre = np.asarray(c.center, dtype=float)
        rho = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
        out.append(
            (f"clusters.{j}", np.hypot(np.maximum(rho - c.radius_m, 0.0), pts[:, 2] - centre[2]))
        )
    return out


def scatterer_too_close(
    multipath: Multipath, points: np.ndarray, min_distance_m: float = MIN_SCATTERER_DISTANCE_M
) -> tuple[str, int, float] | None:
    """The first (``scatterers.j`` / ``clusters.j``, point index, distance) whose SPs may come
    closer than ``min_distance_m`` to one of ``points`` [P, 3], or ``None``."""
    for name, dist in scatterer_distances(multipath, points):
        close = np.flatnonzero(dist < min_distance_m)
        if close.size:
            k = int(close[np.argmin(dist[close])])
            return name, k, float(dist[k])
    return None


def describe_scatterer(multipath: Multipath, name: str) -> str:
    """``the SP at [x, y, z]`` or ``the disk of SPs (centre …, radius … m)`` of an entry."""
    kind, j = name.split(".")
    if kind == "scatterers":
        return f"the SP at {multipath.scatterers[int(j)].position}"
    c = multipath.clusters[int(j)]
    return f"the disk of SPs (centre {c.center}, radius {c.radius_m} m)"


class Multipath(DocumentModel):
    """Fixed scattering points, random clusters and the site's own reflections; empty means
    no multipath.

    ``site_reflections``: add the first-order specular reflections off the scenario's
    ``environment`` faces (image method, per-leg visibility, Fresnel coefficient of each
    obstacle's ``material``; docs/concepts/environment.md "Reflections") for the LOS and
    every TX–RIS and RIS–RX leg. Deterministic (no random draws); the diffuse scatterers and
    clusters remain optional and combine with it.
    """

    scatterers: list[Scatterer] = Field(default_factory=list, max_length=1000)
    clusters: list[ScattererCluster] = Field(default_factory=list, max_length=100)
    site_reflections: bool = Field(
        False,
        description="Add first-order specular reflections off the environment's faces",
    )

    @property
    def empty(self) -> bool:
        return not self.scatterers and not self.clusters and not self.site_reflections


class SearchArea(DocumentModel):
    """The TX candidates of Algorithm 2's coarse search: a box sampled with ``step_m``.

    Either an explicit box (``min_m``, ``max_m``) or ``half_width_m`` around ``center``
    (``"true_tx"``: the paper's simulation convention, a 2×2×2 m box around the true TX).
    """

    center: Literal["true_tx"] | Point3 = "true_tx"
    half_width_m: Annotated[list[float], Field(min_length=3, max_length=3)] = Field(
        default_factory=lambda: [1.0, 1.0, 1.0]
    )
    min_m: Point3 | None = None
    max_m: Point3 | None = None
    step_m: float = Field(0.2, gt=0, le=1e3, allow_inf_nan=False, description="Grid step [m]")

    @field_validator("half_width_m")
    @classmethod
    def _check_half(cls, v: list[float]) -> list[float]:
        arr = np.asarray(v, dtype=float)
        if not np.all(np.isfinite(arr)) or np.any(arr < 0):
            raise ValueError(f"half_width_m must be finite and ≥ 0, got {v} (the box is empty)")
        return [float(x) for x in arr]

    @model_validator(mode="after")
    def _check_box(self) -> SearchArea:
        if (self.min_m is None) != (self.max_m is None):
            raise ValueError("give both min_m and max_m (or neither)")
        if self.min_m is not None and self.max_m is not None:
            lo, hi = np.asarray(self.min_m), np.asarray(self.max_m)
            if np.any(hi < lo):
                axis = int(np.argmax(hi < lo))
                raise ValueError(
                    f"the search area is empty: max_m[{axis}] = {hi[axis]} < min_m[{axis}]"
                    f" = {lo[axis]}"
                )
        return self

    def bounds(self, true_tx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) corners [3] of the box."""
        if self.min_m is not None and self.max_m is not None:
            return np.asarray(self.min_m, float), np.asarray(self.max_m, float)
        c = np.asarray(true_tx if self.center == "true_tx" else self.center, dtype=float)
        h = np.asarray(self.half_width_m, dtype=float)
        return c - h, c + h

    def candidates(self, true_tx: np.ndarray) -> np.ndarray:
        """The grid of TX candidates, [Q, 3] (the box corners included when on the grid)."""
        lo, hi = self.bounds(true_tx)
        counts = np.floor((hi - lo) / self.step_m + 1e-9).astype(int) + 1
        total = int(np.prod(counts.astype(float)))
        if total > MAX_SEARCH_CANDIDATES:
            raise LimitExceededError(
                f"search_area: {total} TX candidates (step_m = {self.step_m}) exceed the limit"
                f" {MAX_SEARCH_CANDIDATES}; use a larger step_m or a smaller box",
                MAX_SEARCH_CANDIDATES,
            )
        axes = [lo[i] + self.step_m * np.arange(counts[i]) for i in range(3)]
        grid = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grid], axis=-1)


class EstimatorSettings(DocumentModel):
    """Settings of Algorithms 1 and 2."""

    delay_fft_size: int = Field(
        1024, ge=8, le=2**22, description="N_F: FFT points of the coarse delay search"
    )
    angle_fft_size: int = Field(
        100,
        ge=4,
        le=4096,
        description="2-D FFT points per axis of the coarse (ξ, ζ) search (step (λ/d)/M)",
    )
    search_area: SearchArea = Field(default_factory=SearchArea)
    pair_weights: list[float] | None = Field(
        None, description="w_ij for the RIS pairs i<j in lexicographic order; default equal"
    )
    path_weights: list[float] | None = Field(
        None, description="w_ℓ of the delay cost per RIS; default 1"
    )
    sigma: Literal["identity", "crb"] = Field(
        "identity", description="Σ of the position MLE: I, or the channel CRB (inverse EFIM)"
    )
    max_channel_iterations: int = Field(50, ge=1, le=1000)

    @field_validator("pair_weights", "path_weights")
    @classmethod
    def _check_weights(cls, v: list[float] | None) -> list[float] | None:
        if v is not None:
            arr = np.asarray(v, dtype=float)
            if not np.all(np.isfinite(arr)) or np.any(arr < 0) or arr.sum() <= 0:
                raise ValueError(f"weights must be finite, ≥ 0 and not all zero, got {v}")
        return v


def paper_clusters(height_m: float = 3.0, rcs_m2: float = 0.5) -> Multipath:
    """The two SP clusters of the paper's multipath figure (section 'The Effect of Multipath').

    Five SPs each, uniform in 1 m disks centred at [0, −3, h] (TX side) and [0, 2, h] (RX side).
    """
    return Multipath(
        clusters=[
            ScattererCluster(center=[0.0, -3.0, height_m], rcs_m2=rcs_m2, side="tx"),
            ScattererCluster(center=[0.0, 2.0, height_m], rcs_m2=rcs_m2, side="rx"),
        ]
    )
