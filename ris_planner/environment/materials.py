"""Reflection coefficients of facade materials (docs/concepts/environment.md, "Reflections").

Material constants are those of Recommendation ITU-R P.2040-1, "Effects of building materials
and structures on radiowave propagation above about 100 MHz" (2015), Table 3: the real
relative permittivity η' = a·f^b and the conductivity σ = c·f^d [S/m], f in GHz. The complex
relative permittivity is η = η' − j σ/(2π f ε₀) = η' − j 17.98 σ/f_GHz (P.2040 eq. 9b, time
convention e^{jωt}).

The reflection coefficient is the Fresnel coefficient of a half-space (a thick facade: no
slab resonance) for the electric field perpendicular to the plane of incidence (TE):

    R⊥(θ) = (cos θ − √(η − sin² θ)) / (cos θ + √(η − sin² θ)),

θ the angle of incidence from the face normal. Polarisation assumption: TX, RIS and RX are
vertically polarised and faces are vertical, so for horizontal propagation the field is
perpendicular to the (horizontal) plane of incidence; the TE coefficient is used for every
incidence (an approximation when the legs are steep). Depolarisation is ignored.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

Material = Literal["concrete", "brick", "glass", "wood", "plasterboard", "metal"]
"""Facade materials of ITU-R P.2040-1 Table 3 an obstacle may declare (``material``)."""

DEFAULT_MATERIAL: Material = "concrete"
"""The material of an obstacle that declares none."""

ITU_P2040: dict[str, tuple[float, float, float, float, float, float]] = {
    # material: (a, b, c, d, f_min_GHz, f_max_GHz) of ITU-R P.2040-1 Table 3
    "concrete": (5.31, 0.0, 0.0326, 0.8095, 1.0, 100.0),
    "brick": (3.75, 0.0, 0.038, 0.0, 1.0, 10.0),
    "glass": (6.27, 0.0, 0.0043, 1.1925, 0.1, 100.0),
    "wood": (1.99, 0.0, 0.0047, 1.0718, 0.001, 100.0),
    "plasterboard": (2.94, 0.0, 0.0116, 0.7076, 1.0, 100.0),
    "metal": (1.0, 0.0, 1e7, 0.0, 1.0, 100.0),
}
"""ITU-R P.2040-1 Table 3 constants; outside [f_min, f_max] the fit is extrapolated."""

VACUUM_PERMITTIVITY = 8.8541878128e-12
"""ε₀ [F/m]."""

ComplexArray = NDArray[np.complex128]


def relative_permittivity(material: str, carrier_hz: float) -> complex:
    """Complex relative permittivity η = η' − j σ/(ω ε₀) of a material at the carrier."""
    if material not in ITU_P2040:
        raise ValueError(
            f"unknown material {material!r}; known materials: {', '.join(sorted(ITU_P2040))}"
        )
    a, b, c, d, _, _ = ITU_P2040[material]
    f_ghz = carrier_hz / 1e9
    eps = a * f_ghz**b
    sigma = c * f_ghz**d
    return complex(eps, -sigma / (2 * math.pi * carrier_hz * VACUUM_PERMITTIVITY))


def fresnel_te(eta: ArrayLike, cos_incidence: ArrayLike) -> ComplexArray:
    """R⊥ = (cos θ − √(η − sin²θ)) / (cos θ + √(η − sin²θ)), elementwise (principal root)."""
    c = np.asarray(cos_incidence, dtype=float)
    root = np.sqrt(np.asarray(eta, dtype=complex) - (1.0 - c * c))
    return np.asarray((c - root) / (c + root))
