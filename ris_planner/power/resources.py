"""A power allocation's sizes and admission, computed from its validated scenario before
anything is built (docs/guides/power.md): the one admission path of ``ris-planner power`` and
``POST /v1/power-allocations``."""

from __future__ import annotations

from typing import Any

from ris_planner.core.errors import DocumentFieldError
from ris_planner.model.limits import BASE_BYTES, Sizes, budget_mb, check_sizes
from ris_planner.model.power import OBJECTIVES
from ris_planner.model.profiles import block_length
from ris_planner.model.scenario import ExpectedRandomCodebook, Scenario, load_scenario

BYTES_PER_POWER_TERM = 8 * 49 * 24
"""Power: per beam and position, the 7×7 information and the conic solver's copies."""


BYTES_PER_BEAM_ELEMENT = 48


def estimate_power(scenario: Scenario) -> Sizes:
    """The sizes of a power allocation (``ris-planner power``) from its validated scenario:
    G̃ beams, the design positions (prior samples of a DIR/DIR+DER codebook, else the pairs)
    and the elements of each RIS."""
    g_tilde = block_length(scenario.system.transmissions, len(scenario.ris))
    prior = getattr(scenario.codebook, "prior", None)
    if prior is not None:
        per_sample = int(getattr(scenario.codebook, "beams_per_sample", 1))
        positions = prior.samples if prior.samples is not None else max(1, g_tilde // per_sample)
    else:
        positions = int(scenario.tx_array.shape[0])
    elements = sum(r.elements for r in scenario.ris)
    terms = g_tilde * positions
    products = terms * elements
    memory = BASE_BYTES + terms * BYTES_PER_POWER_TERM + products * BYTES_PER_BEAM_ELEMENT
    return Sizes(
        pairs=int(scenario.tx_array.shape[0]),
        design_beams=g_tilde,
        design_positions=positions,
        power_terms=terms,
        beam_elements=products,
        memory_bytes=memory,
    )


def validate_power(
    scenario: Scenario | dict[str, Any], objective: str, memory_mb: int | None = None
) -> Scenario:
    """A scenario and objective that ``run_power`` accepts: concrete beams (not
    ``expected_random``), an objective whose bound is not known, the SDP's sizes within their
    limits and the job memory budget."""
    sc = load_scenario(scenario)
    power_check(sc, objective, memory_mb)
    return sc


def power_check(sc: Scenario, objective: str, memory_mb: int | None = None) -> Sizes:
    """The power rules of a validated scenario; its sizes."""
    if objective not in OBJECTIVES:
        raise DocumentFieldError(
            "objective",
            f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}",
        )
    if isinstance(sc.codebook, ExpectedRandomCodebook):
        raise DocumentFieldError(
            "codebook.kind",
            "power allocation needs concrete beams; codebook 'expected_random' has none"
            " (use 'random', 'explicit', 'directional' or 'directional_derivative')",
        )
    if "tx" in sc.known and objective in ("tx", "sum"):
        raise DocumentFieldError("known", f"objective {objective!r} needs PEB_T, but 'tx' is known")
    sizes = estimate_power(sc)
    check_sizes(sizes, memory_mb=budget_mb(memory_mb))
    return sizes
