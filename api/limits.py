"""Size limits of one request, checked before any engine work (→ 413 with the limit).

The bounds engine's big arrays per RIS ℓ are the steering vectors [N_ℓ, P], the weighted
profiles [3G̃, N_ℓ] and their product [3G̃, P] (``ris_planner.fim.transmission_vectors``), and
its work is Σ_ℓ 3·G̃·N_ℓ·P complex products (G̃ = G/Γ beams per block, N_ℓ elements, P pairs).
With an environment, deciding the legs (TX–RX and TX/RX–RIS, P·(1 + 2L)) against the obstacles
is at most one segment test per leg and obstacle edge (a wall is one edge); that count is held
to the same work limit.
"""

from __future__ import annotations

from api.settings import Settings
from ris_planner.codebooks import block_length
from ris_planner.errors import LimitExceededError
from ris_planner.scenario import Scenario


def check_scenario_size(scenario: Scenario, settings: Settings) -> None:
    """Raise :class:`LimitExceededError` if the scenario exceeds a configured limit."""
    pairs = int(scenario.tx_array.shape[0])
    if pairs > settings.max_pairs:
        raise LimitExceededError(
            f"{pairs} TX–RX pairs exceed the limit of {settings.max_pairs} pairs per request;"
            " split the batch",
            settings.max_pairs,
        )
    g3 = 3 * block_length(scenario.system.transmissions, len(scenario.ris))
    largest = max(max(pairs * r.elements, g3 * r.elements, g3 * pairs) for r in scenario.ris)
    if largest > settings.max_array_elements:
        raise LimitExceededError(
            f"the request needs an engine array of {largest} elements (limit"
            f" {settings.max_array_elements}); use fewer pairs, elements or transmissions",
            settings.max_array_elements,
        )
    work = sum(g3 * r.elements * pairs for r in scenario.ris)
    if work > settings.max_work:
        raise LimitExceededError(
            f"the request needs {work} complex products Σ 3·G̃·N·pairs (limit"
            f" {settings.max_work}); use fewer pairs, elements or transmissions",
            settings.max_work,
        )

    if scenario.environment is not None:
        edges = sum(
            len(ob.footprint) if ob.kind == "prism" else 1 for ob in scenario.environment.obstacles
        )
        tests = pairs * (1 + 2 * len(scenario.ris)) * edges
        if tests > settings.max_work:
            raise LimitExceededError(
                f"the request needs {tests} visibility tests (legs × obstacle edges; limit"
                f" {settings.max_work}); use fewer pairs, RISs or obstacles",
                settings.max_work,
            )
