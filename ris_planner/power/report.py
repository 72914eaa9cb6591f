"""``run_power``: uniform power, the best γ_P and the SDP allocation for one scenario, every
objective re-evaluated by the bounds code (``compute_bounds``) from the returned powers.

Design positions (eq. opt_formulation_2): the sampled prior pairs of a ``directional`` /
``directional_derivative`` codebook, otherwise the document's TX–RX pairs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import ComplexArray, compute_bounds, first_block_profiles
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.core.io_json import finite_or_none
from ris_planner.model.limits import MAX_DESIGN_BEAMS, MAX_DESIGN_POSITIONS
from ris_planner.model.power import Objective
from ris_planner.model.scenario import (
    DirectionalCodebook,
    DirectionalDerivativeCodebook,
    Scenario,
)
from ris_planner.physics.beams import codebook_block
from ris_planner.power.gamma import GammaSearch, search_gamma_p
from ris_planner.power.information import beam_information
from ris_planner.power.sdp import (
    SdpResult,
    mean_trace_bound,
    objective_index,
    solve_power_sdp,
)
from ris_planner.runtime.progress import ProgressCallback, no_progress
from ris_planner.runtime.provenance import provenance

FloatArray = NDArray[np.float64]


def design_objective(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    profiles: list[ComplexArray],
    objective: Objective,
) -> Callable[[FloatArray], float]:
    """Mean PEB² [m²] over the design positions as a function of the first-block powers,
    computed by ``compute_bounds`` (``inf`` when a position is a blind spot)."""

    def evaluate(powers: FloatArray) -> float:
        res = compute_bounds(scenario, tx, rx, profiles=profiles, beam_powers=powers)
        parts: dict[str, list[FloatArray | None]] = {
            "rx": [res.peb_rx],
            "tx": [res.peb_tx],
            "sum": [res.peb_tx, res.peb_rx],
        }
        total = np.zeros(tx.shape[0])
        for arr in parts[objective]:
            if arr is None:
                raise RisPlannerError(f"objective {objective!r} needs PEB_T but 'tx' is known")
            total = total + arr**2
        return float(np.mean(total))

    return evaluate


def _entry(objective: float | None) -> dict[str, Any]:
    out: dict[str, Any] = {"objective": finite_or_none(objective)}
    out["rms_peb_m"] = None if out["objective"] is None else math.sqrt(out["objective"])
    if objective is not None and not math.isfinite(objective):
        out["reason"] = "a design position is a blind spot (singular Fisher information)"
    return out


@dataclass(frozen=True)
class PowerResult:
    """Uniform, γ_P and SDP power allocations with objectives re-evaluated by the bounds code.

    Objectives are the mean over the design positions of PEB_R² (``rx``), PEB_T² (``tx``) or
    their sum (``sum``) [m²]; powers are per first-block beam (sum G̃, repeated over Γ blocks).
    """

    objective_kind: Objective
    tx: FloatArray
    rx: FloatArray
    uniform_objective: float
    gamma_p: GammaSearch | None
    sdp: SdpResult
    sdp_objective: float | None
    beams: int
    provenance: dict[str, str] | None = None

    def to_json(self) -> dict[str, Any]:
        """What ``ris-planner power FILE.json`` prints."""
        gamma: dict[str, Any]
        if self.gamma_p is None:
            gamma = {
                "value": None,
                "objective": None,
                "rms_peb_m": None,
                "reason": "γ_P applies to the directional_derivative codebook only",
            }
        else:
            gamma = {"value": self.gamma_p.value, **_entry(self.gamma_p.objective)}
        sdp = {
            **_entry(self.sdp_objective),
            "status": self.sdp.status,
            "solve_time_s": self.sdp.solve_time_s,
            "solver_time_s": self.sdp.solver_time_s,
            "solver": self.sdp.solver,
            "solver_objective": finite_or_none(self.sdp.objective),
            "powers": None if self.sdp.powers is None else [float(x) for x in self.sdp.powers],
            "message": self.sdp.message,
        }
        return {
            "objective": self.objective_kind,
            "unit": "m^2 (mean squared PEB over the design positions)",
            "positions": int(self.tx.shape[0]),
            "beams": self.beams,
            "uniform": _entry(self.uniform_objective),
            "gamma_p": gamma,
            "sdp": sdp,
            **({"provenance": self.provenance} if self.provenance is not None else {}),
        }


def run_power(
    scenario: Scenario | dict[str, Any],
    progress: ProgressCallback = no_progress,
    objective: Objective = "rx",
    *,
    solver: str = "CLARABEL",
) -> PowerResult:
    """Uniform power, the best γ_P (DIR+DER only) and the SDP allocation for a scenario."""
    from ris_planner.power.resources import validate_power

    sc = validate_power(scenario, objective)  # the CLI's and the service's checks, sizes first
    progress(0.0, "beams")
    beam_types = None
    if isinstance(sc.codebook, DirectionalCodebook | DirectionalDerivativeCodebook):
        block = codebook_block(sc)
        profiles, tx, rx = block.profiles, block.tx, block.rx
        if isinstance(sc.codebook, DirectionalDerivativeCodebook):
            beam_types = block.beam_types
    else:
        prof = first_block_profiles(sc)
        assert prof is not None
        profiles, tx, rx = prof, sc.tx_array, sc.rx_array
    g_tilde = profiles[0].shape[0]
    if tx.shape[0] > MAX_DESIGN_POSITIONS:
        raise LimitExceededError(
            f"{tx.shape[0]} design positions exceed the limit of {MAX_DESIGN_POSITIONS}",
            MAX_DESIGN_POSITIONS,
        )
    if g_tilde > MAX_DESIGN_BEAMS:
        raise LimitExceededError(
            f"{g_tilde} beams exceed the limit of {MAX_DESIGN_BEAMS}", MAX_DESIGN_BEAMS
        )
    evaluate = design_objective(sc, tx, rx, profiles, objective)
    uniform = evaluate(np.ones(g_tilde))
    info = beam_information(sc, tx, rx, profiles)
    gamma = None
    if beam_types is not None:
        # search on the per-path beam blocks (one [J]×[J, P·m²] product per path, then the
        # bounds' own inversion route: equal to compute_bounds to the bounds' accuracy,
        # tests/test_power.py), then re-evaluate
        index = objective_index(info, objective)
        gamma = search_gamma_p(
            lambda p: mean_trace_bound(info, p, index),
            beam_types,
            lambda f, m: progress(0.05 + 0.45 * f, m),
        )
        gamma = replace(gamma, objective=evaluate(gamma.powers))
    progress(0.5, "SDP")
    sdp = solve_power_sdp(info, objective, solver=solver)
    sdp_obj = None if sdp.powers is None else evaluate(sdp.powers)
    progress(1.0, f"SDP {sdp.status}")
    return PowerResult(objective, tx, rx, uniform, gamma, sdp, sdp_obj, g_tilde, provenance(sc))
