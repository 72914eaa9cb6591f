"""Size limits of one request, checked before any engine work (→ 413 with the limit).

The bounds engine's big arrays per RIS ℓ are the steering vectors [N_ℓ, P], the weighted
profiles [3G̃, N_ℓ] and their product [3G̃, P] (``ris_planner.physics.fim.transmission_vectors``), and
its work is Σ_ℓ 3·G̃·N_ℓ·P complex products (G̃ = G/Γ beams per block, N_ℓ elements, P pairs).
With an environment, deciding the legs (TX–RX and TX/RX–RIS, P·(1 + 2L)) against the obstacles
is at most one segment test per leg and obstacle edge (a wall is one edge); that count is held
to the same work limit.
"""

from __future__ import annotations

from typing import Any

from api.settings import Settings
from ris_planner.core.errors import LimitExceededError
from ris_planner.environment.kinds.prism import MAX_FOOTPRINT_VERTICES
from ris_planner.environment.model import MAX_OBSTACLES, Environment
from ris_planner.model.limits import MAX_MAP_POINTS, MAX_SITES
from ris_planner.model.plan import LayoutBeamsDocument
from ris_planner.model.scenario import Scenario
from ris_planner.physics.codebooks import block_length


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
    before they are expanded, :func:`ris_planner.model.plan.map_points`)."""
    from ris_planner.model.limits import Sizes, check_sizes
    from ris_planner.model.plan import map_points
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
        edges = sum(ob.work_units() for ob in environment.obstacles)
        tests = pairs * (1 + 2 * len(elements)) * edges
        if tests > settings.max_work:
            raise LimitExceededError(
                f"the request needs {tests} visibility tests (legs × obstacle edges; limit"
                f" {settings.max_work}); use fewer pairs, RISs or obstacles",
                settings.max_work,
            )


LIST_LIMITS: dict[str, tuple[int, str]] = {
    "obstacles": (MAX_OBSTACLES, "obstacles"),
    "footprint": (MAX_FOOTPRINT_VERTICES, "footprint vertices"),
    "features": (MAX_OBSTACLES, "features"),
    "points": (MAX_MAP_POINTS, "points"),
    "sites": (MAX_SITES, "sites"),
}
"""The lists a document may carry in bulk, by field name, with their limits (the models'
``max_length``); :func:`prescan_document` refuses longer ones before validation."""

MAX_LIST_ITEMS = MAX_MAP_POINTS
"""Longest list of any other name (no field of a document takes more)."""

MAX_COORDINATES = 4 * MAX_MAP_POINTS
"""Numbers inside the lists of :data:`LIST_LIMITS` together (vertices, points: 2–3 each)."""


def prescan_document(value: Any, what: str = "request body") -> None:
    """Refuse a parsed JSON document whose lists exceed their limits – obstacles, footprint
    vertices, features, points, sites (:data:`LIST_LIMITS`), any list above
    :data:`MAX_LIST_ITEMS`, or more than :data:`MAX_COORDINATES` numbers in them together –
    with :class:`LimitExceededError` (413) in one pass over the decoded value, before the
    (much slower) model validation. Iterative: no recursion limit (depth was checked when it
    was parsed)."""
    numbers = 0
    stack: list[tuple[Any, str]] = [(value, "")]
    while stack:
        item, name = stack.pop()
        if isinstance(item, dict):
            stack.extend((v, str(k)) for k, v in item.items())
            continue
        if not isinstance(item, list):
            numbers += isinstance(item, int | float)
            continue
        limit, label = LIST_LIMITS.get(name, (MAX_LIST_ITEMS, f"items in {name or 'a list'}"))
        if len(item) > limit:
            raise LimitExceededError(
                f"{what}: {len(item)} {label} exceed the limit of {limit}", limit
            )
        if numbers > MAX_COORDINATES:
            raise LimitExceededError(
                f"{what}: more than {MAX_COORDINATES} numbers in one document", MAX_COORDINATES
            )
        stack.extend((v, name) for v in item)  # a list's items keep the list's field name
