"""The element pattern and field of view a plan assumes for its candidate RISs, and the
``physics`` block of plan.json that states them (docs/concepts/planning-physics.md).

A RIS path's amplitude gain is |ρ_ℓ| = λ²/(16π² d_T d_R) · (cos θ_T cos θ_R)^q (the paper's
Simulation Parameters with the element pattern of :func:`ris_planner.bounds.compute.ris_path_gain`),
and a UE is served only when its angle θ to the RIS normal is strictly below
``max_angle_deg``. Scenario documents keep the paper's isotropic model (q = 0, 90°); a plan
document's shared ``ris`` defaults to the physical pattern below, because a placement search
with an isotropic element favours facade sites that see the UEs at grazing angles
(73–82° off boresight) at full gain.

Source: W. Tang et al., "Wireless Communications With Reconfigurable Intelligent Surface:
Path Loss Modeling and Experimental Measurement", IEEE Trans. Wireless Commun. 20(1), 2021
(arXiv:1911.05326). Its received power is
P_r ∝ |Σ √(F(θ_t) F(θ_r)) Γ / (r_t r_r)|², with the unit cell's normalised *power* pattern
F(θ) = cos³ θ on the front half-space (θ ∈ [0, π/2]), the pattern its simulations use
for the unit cells of its path loss model. Our ρ_ℓ is an *amplitude*: √(F(θ_T) F(θ_R)) =
(cos θ_T cos θ_R)^{3/2}, so q = 3/2 (a power exponent p maps to q = p/2). Only the pattern's
shape is taken: the boresight gain stays the paper's λ²/(16π² d_T d_R), so a UE on the normal
sees exactly the paper's path.

Field of view: the cut where one leg's power pattern cos³ θ falls 30 dB below boresight –
the floor (front-to-back ratio and side-lobe limit A_max = SLA_V = 30 dB) of the antenna
element model of 3GPP TR 38.901, Table 7.3-1 – i.e. cos θ > 0.1, θ < 84.26°. Beyond it a leg
is weaker than that model lets any element radiate, so the RIS is not credited with serving
the UE at all (its path would add a negligible information anyway: the two-leg factor is
below 10⁻³ · cos³ θ_other).
"""

from __future__ import annotations

import math

UNIT_CELL_POWER_EXPONENT = 3.0
"""Exponent of the unit cell's normalised power pattern F(θ) = cos^p θ (Tang et al. 2021)."""

PLAN_PATTERN_EXPONENT = UNIT_CELL_POWER_EXPONENT / 2
"""Default ``pattern_exponent`` q of a plan's RISs: the amplitude exponent of the power
pattern cos³ θ, q = p/2 = 1.5 (module docstring)."""

PATTERN_FLOOR_DB = 30.0
"""The element pattern floor of 3GPP TR 38.901 Table 7.3-1 (A_max = SLA_V = 30 dB)."""

PLAN_MAX_ANGLE_DEG = math.degrees(
    math.acos(10 ** (-PATTERN_FLOOR_DB / (10 * UNIT_CELL_POWER_EXPONENT)))
)
"""Default ``max_angle_deg`` of a plan's RISs: where cos³ θ is 30 dB below boresight,
cos θ = 0.1, θ = 84.26° (module docstring)."""

PHYSICS_FIELDS = ("pattern_exponent", "max_angle_deg")
"""The fields of a plan's shared ``ris`` whose plan default differs from the scenario's."""

PLAN_PHYSICS_SOURCE = (
    "unit-cell power pattern cos^3(theta) of Tang et al., IEEE TWC 20(1) 2021"
    " (arXiv:1911.05326), as an amplitude exponent q = 3/2; field of view cos(theta) > 0.1"
    " (84.26 deg: one leg 30 dB below boresight, the element floor of 3GPP TR 38.901"
    " Table 7.3-1)"
)
"""What plan.json ``physics.source`` says when the defaults are in force."""

ISOTROPIC_SOURCE = "the paper's isotropic element (q = 0, field of view 90 deg)"
"""What plan.json ``physics.source`` says for q = 0 and 90° set in the document."""
