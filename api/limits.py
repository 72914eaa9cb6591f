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
from ris_planner.obstacles import Environment
from ris_planner.planning.document import LayoutBeamsDocument
from ris_planner.scenario import Scenario


def check_scenario_size(scenario: Scenario, settings: Settings) -> None:
    """Raise :class:`LimitExceededError` if the scenario exceeds a configured limit."""
    check_size(
        int(scenario.tx_array.shape[0]),
        scenario.system.transmissions,
        [r.elements for r in scenario.ris],
        settings,
        scenario.environment,
    )


def check_layout_beams_size(document: LayoutBeamsDocument, settings: Settings) -> None:
    """The limits of a layout + UE-map power allocation: its pairs are evaluated by the bounds
    engine once per beam design (the maps' point counts are checked against their limit
    before they are expanded, :func:`ris_planner.limits.map_points`)."""
    from ris_planner.limits import Sizes, check_sizes, map_points
    from ris_planner.planning.maps import build_map, build_pairs

    # the maps' sizes before any is built (a road step of 5e-324 would build forever)
    sizes = Sizes(tx_points=map_points(document.tx_map), rx_points=map_points(document.rx_map))
    check_sizes(sizes, memory_mb=None)
    tx_map = build_map(document.tx_map, "tx_map")
    rx_map = build_map(document.rx_map, "rx_map")
    pairs = build_pairs(tx_map, rx_map, document.pairs, document.max_pairs)
    check_size(
        pairs.size,
        document.system.transmissions,
        [r.elements for r in document.ris],
        settings,
        document.environment,
    )


def check_size(
    pairs: int,
    transmissions: int,
    elements: list[int],
    settings: Settings,
    environment: Environment | None = None,
) -> None:
    """The pair, array, work and visibility limits for ``pairs`` TX–RX pairs, RISs of
    ``elements`` and the obstacles of ``environment``."""
    if pairs > settings.max_pairs:
        raise LimitExceededError(
            f"{pairs} TX–RX pairs exceed the limit of {settings.max_pairs} pairs per request;"
            " split the batch",
            settings.max_pairs,
        )
    g3 = 3 * block_length(transmissions, len(elements))
    largest = max(max(pairs * n, g3 * n, g3 * pairs) for n in elements)
    if largest > settings.max_array_elements:
        raise LimitExceededError(
            f"the request needs an engine array of {largest} elements (limit"
            f" {settings.max_array_elements}); use fewer pairs, elements or transmissions",
            settings.max_array_elements,
        )
    work = sum(g3 * n * pairs for n in elements)
    if work > settings.max_work:
        raise LimitExceededError(
            f"the request needs {work} complex products Σ 3·G̃·N·pairs (limit"
            f" {settings.max_work}); use fewer pairs, elements or transmissions",
            settings.max_work,
        )
    if environment is not None:
        edges = sum(len(ob.footprint) if ob.kind == "prism" else 1 for ob in environment.obstacles)
        tests = pairs * (1 + 2 * len(elements)) * edges
        if tests > settings.max_work:
            raise LimitExceededError(
                f"the request needs {tests} visibility tests (legs × obstacle edges; limit"
                f" {settings.max_work}); use fewer pairs, RISs or obstacles",
                settings.max_work,
            )
