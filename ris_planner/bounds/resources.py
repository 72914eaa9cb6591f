"""The sizes of one bounds request against its limits, checked before any engine work
(:class:`~ris_planner.model.limits.RequestLimits`; the service answers 413 with the limit).

The bounds engine's big arrays per RIS ℓ are the steering vectors [N_ℓ, P], the weighted
profiles [3G̃, N_ℓ] and their product [3G̃, P] (:func:`ris_planner.physics.fim.transmission_vectors`),
and its work is Σ_ℓ 3·G̃·N_ℓ·P complex products (G̃ = G/Γ beams per block, N_ℓ elements, P
pairs). With an environment, deciding the legs (TX–RX and TX/RX–RIS, P·(1 + 2L)) against the
obstacles is at most one segment test per leg and obstacle edge (a wall is one edge); that count
is held to the same work limit.
"""

from __future__ import annotations

from ris_planner.core.errors import LimitExceededError
from ris_planner.environment.model import Environment
from ris_planner.model.limits import RequestLimits
from ris_planner.model.profiles import block_length
from ris_planner.model.scenario import Scenario


def check_scenario_size(scenario: Scenario, limits: RequestLimits) -> None:
    """Raise :class:`LimitExceededError` if the scenario exceeds a configured limit."""
    check_bounds_size(
        int(scenario.tx_array.shape[0]),
        scenario.system.transmissions,
        [r.elements for r in scenario.ris],
        limits,
        scenario.environment,
    )


def check_bounds_size(
    pairs: int,
    transmissions: int,
    elements: list[int],
    limits: RequestLimits,
    environment: Environment | None = None,
) -> None:
    """The pair, array, work and visibility limits for ``pairs`` TX–RX pairs, RISs of
    ``elements`` and the obstacles of ``environment``."""
    if pairs > limits.max_pairs:
        raise LimitExceededError(
            f"{pairs} TX–RX pairs exceed the limit of {limits.max_pairs} pairs per request;"
            " split the batch",
            limits.max_pairs,
        )
    g3 = 3 * block_length(transmissions, len(elements))
    largest = max(max(pairs * n, g3 * n, g3 * pairs) for n in elements)
    if largest > limits.max_array_elements:
        raise LimitExceededError(
            f"the request needs an engine array of {largest} elements (limit"
            f" {limits.max_array_elements}); use fewer pairs, elements or transmissions",
            limits.max_array_elements,
        )
    work = sum(g3 * n * pairs for n in elements)
    if work > limits.max_work:
        raise LimitExceededError(
            f"the request needs {work} complex products Σ 3·G̃·N·pairs (limit"
            f" {limits.max_work}); use fewer pairs, elements or transmissions",
            limits.max_work,
        )
    if environment is not None:
        edges = sum(ob.work_units() for ob in environment.obstacles)
        tests = pairs * (1 + 2 * len(elements)) * edges
        if tests > limits.max_work:
            raise LimitExceededError(
                f"the request needs {tests} visibility tests (legs × obstacle edges; limit"
                f" {limits.max_work}); use fewer pairs, RISs or obstacles",
                limits.max_work,
            )
