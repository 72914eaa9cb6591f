"""A power allocation's sizes and admission, computed from its validated scenario before
anything is built (docs/guides/power.md): the one admission path of ``ris-planner power`` and
``POST /v1/power-allocations``."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ris_planner.core.errors import DocumentFieldError
from ris_planner.model.limits import (
    BASE_BYTES,
    JOB_MEMORY_ENV,
    Knob,
    MemoryTerm,
    Sizes,
    budget_mb,
    check_sizes,
    explain_memory,
    grouped,
    memory_terms,
)
from ris_planner.model.power import OBJECTIVES
from ris_planner.model.profiles import block_length
from ris_planner.model.scenario import ExpectedRandomCodebook, Scenario, load_scenario

BYTES_PER_POWER_TERM = 8 * 49 * 24
"""Power: per beam and position, the 7×7 information and the conic solver's copies."""


BYTES_PER_BEAM_ELEMENT = 48


@dataclass(frozen=True)
class PowerShape:
    """The quantities a power allocation's memory grows with (:func:`power_shape`)."""

    beams: int
    """First-block beams G̃."""
    positions: int
    """Design positions: the prior samples of a DIR/DIR+DER codebook, else the pairs."""
    elements: int
    """Elements of all RISs together."""


_POSITIONS: Knob[PowerShape] = Knob(
    "the most design positions that fit are {} (fewer pairs, or fewer prior.samples)",
    lambda s: (1, s.positions),
    lambda s, v: replace(s, positions=v),
)

POWER_MEMORY_TERMS: dict[str, MemoryTerm[PowerShape]] = {
    "base": MemoryTerm(
        lambda s: BASE_BYTES,
        lambda s: "the base (the interpreter and its imports)",
        f"a power allocation needs a job memory budget above {BASE_BYTES >> 20} MiB"
        f" ({JOB_MEMORY_ENV})",
        fixed=True,
    ),
    "power terms": MemoryTerm(
        lambda s: s.beams * s.positions * BYTES_PER_POWER_TERM,
        lambda s: (
            f"the power terms ({grouped(s.beams)} beams × {grouped(s.positions)} design"
            " positions: the 7×7 information and the solver's copies)"
        ),
        "use fewer system.transmissions, pairs or prior.samples",
        (_POSITIONS,),
    ),
    "beam information": MemoryTerm(
        lambda s: s.beams * s.positions * s.elements * BYTES_PER_BEAM_ELEMENT,
        lambda s: (
            f"the beam information ({grouped(s.beams)} beams × {grouped(s.positions)}"
            f" positions × {grouped(s.elements)} elements)"
        ),
        "use smaller RISs, fewer system.transmissions, pairs or prior.samples",
        (_POSITIONS,),
    ),
}
"""The terms of a power allocation's memory estimate, each with what its refusal says
(:class:`~ris_planner.model.limits.MemoryTerm`): ``base``, ``power terms``
(:data:`BYTES_PER_POWER_TERM` per beam and position), ``beam information``
(:data:`BYTES_PER_BEAM_ELEMENT` per beam, position and element)."""


def power_shape(scenario: Scenario) -> PowerShape:
    """The :class:`PowerShape` of a validated scenario: G̃ beams, the design positions (prior
    samples of a DIR/DIR+DER codebook, else the pairs) and the elements of the RISs."""
    g_tilde = block_length(scenario.system.transmissions, len(scenario.ris))
    prior = getattr(scenario.codebook, "prior", None)
    if prior is not None:
        per_sample = int(getattr(scenario.codebook, "beams_per_sample", 1))
        positions = prior.samples if prior.samples is not None else max(1, g_tilde // per_sample)
    else:
        positions = int(scenario.tx_array.shape[0])
    return PowerShape(g_tilde, positions, sum(r.elements for r in scenario.ris))


def estimate_power(scenario: Scenario) -> Sizes:
    """The sizes of a power allocation (``ris-planner power``) from its validated scenario
    (:func:`power_shape`); the memory is the sum of :data:`POWER_MEMORY_TERMS`."""
    shape = power_shape(scenario)
    terms = shape.beams * shape.positions
    return Sizes(
        pairs=int(scenario.tx_array.shape[0]),
        design_beams=shape.beams,
        design_positions=shape.positions,
        power_terms=terms,
        beam_elements=terms * shape.elements,
        memory_bytes=sum(memory_terms(POWER_MEMORY_TERMS, shape).values()),
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
    shape = power_shape(sc)
    check_sizes(
        sizes,
        memory_mb=budget_mb(memory_mb),
        explain=lambda budget: explain_memory(POWER_MEMORY_TERMS, shape, budget),
    )
    return sizes
