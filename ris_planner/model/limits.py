"""The limits every run is checked against – the one source of them for the engine, the
command line and the service (docs/reference/settings.md, "Limits") – and the one check.

:class:`Sizes` holds the sizes of a run, computed from its validated document before anything
is built (:func:`ris_planner.planning.resources.admission.estimate_plan`,
:func:`ris_planner.power.resources.estimate_power`); :func:`check_sizes` raises
:class:`LimitExceededError` naming the first quantity above its limit, or the memory estimate
above the job's budget (``RIS_PLANNER_JOB_MEMORY_MB``). The command line and the service call
the same functions, so a document the service accepts is one the job can run.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import Any, Generic, Literal, NamedTuple, TypeVar

from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.environment.kinds.prism import MAX_FOOTPRINT_VERTICES
from ris_planner.environment.model import MAX_OBSTACLES

JOB_MEMORY_MB_DEFAULT = 6144
"""Memory budget of one job [MiB]: the 24 GiB machine runs two job workers beside the server
and the operating system (2 × 6 GiB + headroom)."""

JOB_MEMORY_ENV = "RIS_PLANNER_JOB_MEMORY_MB"
"""Environment variable with the budget (the service's setting; the CLI reads it too)."""

MAX_SITES = 100_000
"""Candidate sites: explicit candidates + Σ over walls of (length/spacing)·heights·tilts."""
MAX_CANDIDATES = 10_000
"""Explicit candidate sites of one document (a plan's ``candidates``, a conversion's)."""
MAX_WALLS = 1000
"""Walls, and facade groups, of one plan document (each expanded to many sites)."""
MAX_FACADE_PRISMS = 10_000
"""Prisms named by one facade group (``facades[].of``)."""
MAX_PAIRS_LIMIT = 500_000
"""The largest ``max_pairs`` and ``pairs.sample`` a document may set (memory: a cached site
holds 28 floats per pair)."""
MAX_MAP_POINTS = 1_000_000
"""Points of one UE map (grid + points + road lattice + CSV rows)."""
CACHE_MEMORY_MB_DEFAULT = 3072
"""Site-cache budget [MiB] (``RIS_PLANNER_CACHE_MEMORY_MB``) for the cache's block storage of 28
entries per site-pair and its square-root rows (:mod:`ris_planner.planning.scoring.site_cache`); the
first layout of :func:`cache_layout` that fits is used: float64 with the rows stored, float64
with the rows recomputed on demand (planar), float32 (half the bytes; the plan then re-scores
its finalists exactly in float64). A cache that does not fit even as float32 is refused before
anything is built. 3 GiB is half the job budget: the hall (156 × 6400 pairs, 392 MB with its
rows) stays as before, a city block grid of 512 candidates × 50 000 pairs (5.7 GB as float64
without rows) runs as float32 (2.9 GB)."""

CACHE_MEMORY_ENV = "RIS_PLANNER_CACHE_MEMORY_MB"
"""Environment variable with the site-cache budget (the service's setting; the CLI reads it)."""

CACHE_ENTRY_BYTES = {"float64": 28 * 8, "float32": 28 * 4}
"""Bytes per site-pair of the cache's block storage in each precision."""

CACHE_ROW_BYTES = {"planar": 3 * 7 * 8, "spherical": 7 * 7 * 8}
"""Bytes per site-pair of the stored square-root rows (float64; spherical ones are always
stored: their expected Gram takes a product over all UE positions)."""


class CacheLayout(NamedTuple):
    """How the site cache is held: the block storage's precision, and whether the square-root
    rows are stored (else recomputed for the few pairs that need them)."""

    storage: Literal["float64", "float32"]
    rows: bool

    def bytes(self, entries: int, wavefront: str = "planar") -> int:
        per = CACHE_ENTRY_BYTES[self.storage] + (CACHE_ROW_BYTES[wavefront] if self.rows else 0)
        return entries * per


HEATMAP_MAX_PAIRS = 200_000
"""TX–RX pairs the plan's heatmap evaluates: at most this many RX points (a seeded sample of a
larger RX map) against a seeded weighted sample of the TX map."""


MAX_SEARCH_LAYOUTS = 2_000_000
"""Layouts a greedy search may score and memoise: (1 + seeds + restarts) starts × max_rounds
rounds × L·(S − L) swaps per round, summed over the RIS counts (the worst case)."""
MAX_DESIGN_POSITIONS = 256
"""Positions (LMIs) of one power SDP; the solve time grows about linearly with them."""
MAX_DESIGN_BEAMS = 4096
"""First-block beams G̃ of a power SDP (its variables)."""
MAX_POWER_TERMS = 65_536
"""Beams × design positions of a power SDP: its per-beam, per-position 7×7 information and
the solver's copy of it (a 4096 × 256 problem needs tens of GB in the solver)."""
MAX_BEAM_ELEMENTS = 50_000_000
"""Σ_ℓ beams × design positions × elements N_ℓ: the complex steering products of the beam
information."""

BASE_BYTES = 420 << 20
"""The interpreter with numpy, scipy, numba, matplotlib and the GIS writers imported, and the
numba compilation of the kernels on a first run (measured: 280 MB warm, 400 MB compiling;
docs/validation/resources.md)."""


@dataclass(frozen=True)
class Sizes:
    """Every size-driving quantity of one run (0 where it does not apply)."""

    sites: int = 0
    tx_points: int = 0
    rx_points: int = 0
    pairs: int = 0
    cache_entries: int = 0
    heatmap_pairs: int = 0
    search_layouts: int = 0
    design_beams: int = 0
    design_positions: int = 0
    power_terms: int = 0
    beam_elements: int = 0
    memory_bytes: int = 0

    def to_json(self) -> dict[str, int]:
        return asdict(self)


LIMITS: dict[str, tuple[int, str, str, str]] = {
    "sites": (
        MAX_SITES,
        "candidate sites",
        "candidate-site",
        "use fewer walls, heights or tilts, or a larger spacing_m",
    ),
    "tx_points": (MAX_MAP_POINTS, "tx_map points", "map-point", "use a coarser tx_map"),
    "rx_points": (MAX_MAP_POINTS, "rx_map points", "map-point", "use a coarser rx_map"),
    "search_layouts": (
        MAX_SEARCH_LAYOUTS,
        "greedy layouts (starts × rounds × swaps)",
        "search",
        "use fewer search.restarts or search.max_rounds, or fewer sites",
    ),
    "design_beams": (MAX_DESIGN_BEAMS, "beams", "design-beam", "use fewer transmissions"),
    "design_positions": (
        MAX_DESIGN_POSITIONS,
        "design positions",
        "design-position",
        "use fewer pairs or prior samples",
    ),
    "power_terms": (
        MAX_POWER_TERMS,
        "beams × design positions",
        "power-SDP",
        "use fewer transmissions, pairs or prior samples",
    ),
    "beam_elements": (
        MAX_BEAM_ELEMENTS,
        "beams × positions × elements",
        "beam-information",
        "use smaller RISs, fewer beams or fewer positions",
    ),
}
"""Quantity → (limit, what is counted, the limit's name, how to get below it); ``pairs`` is
checked against the document's own ``max_pairs``."""


def grouped(value: int) -> str:
    """An integer with thin groups of three digits (``1 000 000``)."""
    return f"{value:,}".replace(",", " ")


def env_mib(name: str, default: int, minimum: int) -> int:
    """A budget [MiB] from the environment variable ``name`` (``default`` when unset or empty);
    :class:`RisPlannerError` naming the variable for a non-integer or one below ``minimum``."""
    text = os.environ.get(name)
    if text is None or text.strip() == "":
        return default
    try:
        value = int(text)
    except ValueError:
        raise RisPlannerError(f"{name} must be an integer (MiB), got {text!r}") from None
    if value < minimum:
        raise RisPlannerError(f"{name} must be ≥ {minimum} MiB, got {value}")
    return value


def cache_memory_mb() -> int:
    """The site-cache budget [MiB] from ``RIS_PLANNER_CACHE_MEMORY_MB`` (default
    :data:`CACHE_MEMORY_MB_DEFAULT`)."""
    return env_mib(CACHE_MEMORY_ENV, CACHE_MEMORY_MB_DEFAULT, 1)


def cache_layout(
    entries: int, wavefront: str = "planar", budget_mb: int | None = None
) -> CacheLayout:
    """The site cache's layout for ``entries`` site-pairs: the first of float64 with rows,
    float64 without rows (planar), float32 (without rows; spherical: with) whose bytes fit the
    budget (default :func:`cache_memory_mb`); raises :class:`LimitExceededError` naming the
    budget when none does."""
    budget_mb = cache_memory_mb() if budget_mb is None else budget_mb
    spherical = wavefront == "spherical"
    tiers = [CacheLayout("float64", True)]
    tiers += [CacheLayout("float32", True)] if spherical else [CacheLayout("float64", False)]
    tiers += [] if spherical else [CacheLayout("float32", False)]
    for tier in tiers:
        if tier.bytes(entries, wavefront) <= budget_mb << 20:
            return tier
    need = math.ceil(tiers[-1].bytes(entries, wavefront) / (1 << 20))
    raise LimitExceededError(
        f"{entries} sites × pairs need {need} MiB of site cache even as float32, above the"
        f" site-cache budget of {budget_mb} MiB ({CACHE_MEMORY_ENV}); sample fewer pairs or use"
        " fewer candidates",
        budget_mb,
    )


def job_memory_mb() -> int:
    """The memory budget [MiB] from ``RIS_PLANNER_JOB_MEMORY_MB`` (default
    :data:`JOB_MEMORY_MB_DEFAULT`)."""
    return env_mib(JOB_MEMORY_ENV, JOB_MEMORY_MB_DEFAULT, 64)


def budget_mb(memory_mb: int | None) -> int:
    """A run's memory budget [MiB]: the one given, else :func:`job_memory_mb`."""
    return job_memory_mb() if memory_mb is None else memory_mb


S = TypeVar("S")
"""The shape of a memory estimate: the quantities its terms grow with (a plan's
:class:`~ris_planner.planning.resources.admission.PlanShape`, a power allocation's
:class:`~ris_planner.power.resources.PowerShape`)."""


def _count_text(shape: object, value: int) -> str:
    return grouped(value)


@dataclass(frozen=True)
class Knob(Generic[S]):
    """A quantity of a shape that lowers a memory term (the estimate grows with it).
    ``span(shape)`` is its smallest value and its value now (nothing to lower when now ≤
    smallest), ``make(shape, v)`` the shape with the value ``v``; ``fits`` says the largest value
    that fits, ``{}`` standing for ``show(shape, v)``."""

    fits: str
    span: Callable[[S], tuple[int, int]]
    make: Callable[[S, int], S]
    show: Callable[[S, int], str] = _count_text


@dataclass(frozen=True)
class MemoryTerm(Generic[S]):
    """One term of a memory estimate, with everything its refusal says about it: its bytes for
    a shape, ``what`` it holds (a phrase that contains the term's name, with the shape's
    quantities), the knobs that lower it (tried in order, :func:`advise_memory`) and
    ``otherwise``: the settings to change when no value of a knob fits. ``fixed``: a term no
    document lowers (the interpreter), named only when it alone is above the budget.

    An estimate is a table of these keyed by term name (a plan's ``PLAN_MEMORY_TERMS``, a power
    allocation's ``POWER_MEMORY_TERMS``) and is their sum, so a term cannot be counted without
    its description."""

    bytes: Callable[[S], int]
    what: Callable[[S], str]
    otherwise: str
    knobs: tuple[Knob[S], ...] = ()
    fixed: bool = False


def memory_terms(terms: Mapping[str, MemoryTerm[S]], shape: S) -> dict[str, int]:
    """Each term's bytes for ``shape``; the estimate is their sum."""
    return {name: term.bytes(shape) for name, term in terms.items()}


def _mib(n_bytes: int) -> str:
    return grouped(math.ceil(n_bytes / (1 << 20)))


def largest_fitting(
    terms: Mapping[str, MemoryTerm[S]], knob: Knob[S], shape: S, budget_bytes: int
) -> int | None:
    """The largest value of ``knob`` (between its smallest and its value now) whose shape's
    estimate fits ``budget_bytes``, by bisection on the estimate (which grows with the value);
    None when the knob cannot be lowered or not even its smallest value fits."""

    def fits(value: int) -> bool:
        return sum(memory_terms(terms, knob.make(shape, value)).values()) <= budget_bytes

    low, now = knob.span(shape)
    if now <= low or not fits(low):
        return None
    if fits(now):
        return now
    lo, hi = low, now  # fits(lo), not fits(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if fits(mid):
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class MemoryAdvice(Generic[S]):
    """What a memory refusal says (:func:`advise_memory`): the term it names, the knob and the
    largest value of it that fits (None: none fits), and the text."""

    term: str
    knob: Knob[S] | None
    value: int | None
    text: str


def advise_memory(
    terms: Mapping[str, MemoryTerm[S]], shape: S, budget_bytes: int
) -> MemoryAdvice[S]:
    """Why ``shape``'s estimate is above ``budget_bytes`` and what fits: the largest term that
    a document can lower (or a ``fixed`` term that alone is at or above the budget) with its
    bytes, then the first of its knobs that has a value that fits – "dominated by the site
    cache (52 sites × 20 000 pairs): 392 MiB; the largest pair count that fits is 10 509" – or,
    when none has, that nothing fits by lowering it alone, the other terms' bytes, the term's
    settings and, when the other terms alone are above the budget, the largest of them with
    its settings (docs/validation/resources.md)."""
    sizes = memory_terms(terms, shape)
    fixed = [name for name, term in terms.items() if term.fixed]
    work = {name: b for name, b in sizes.items() if not terms[name].fixed}
    if fixed and (not work or sum(sizes[n] for n in fixed) >= budget_bytes):
        name = max(fixed, key=sizes.__getitem__)
        term = terms[name]
        return MemoryAdvice(
            name,
            None,
            None,
            f"dominated by {term.what(shape)}: {_mib(sizes[name])} MiB, at or above the budget"
            f" by itself; {term.otherwise}",
        )
    name = max(work, key=work.__getitem__)
    term = terms[name]
    head = f"dominated by {term.what(shape)}: {_mib(sizes[name])} MiB"
    for knob in term.knobs:
        best = largest_fitting(terms, knob, shape, budget_bytes)
        if best is not None:
            return MemoryAdvice(
                name, knob, best, f"{head}; {knob.fits.format(knob.show(shape, best))}"
            )
    rest = sum(sizes.values()) - sizes[name]
    text = (
        f"{head}; nothing fits by lowering it alone (the other terms need {_mib(rest)} MiB):"
        f" {term.otherwise}"
    )
    others = {n: b for n, b in work.items() if n != name}
    if rest >= budget_bytes and others:
        nxt = max(others, key=others.__getitem__)
        text += (
            f"; the next largest is {terms[nxt].what(shape)}: {_mib(sizes[nxt])} MiB"
            f" ({terms[nxt].otherwise})"
        )
    return MemoryAdvice(name, None, None, text)


def explain_memory(terms: Mapping[str, MemoryTerm[S]], shape: S, budget_bytes: int) -> str:
    """The text of :func:`advise_memory` (``check_sizes``'s ``explain``)."""
    return advise_memory(terms, shape, budget_bytes).text


def check_sizes(
    sizes: Sizes,
    *,
    max_pairs: int | None = None,
    memory_mb: int | None,
    explain: Callable[[int], str] | None = None,
) -> None:
    """Raise :class:`LimitExceededError` naming the first quantity above its limit (the limit
    and how to get below it in the message), then the memory estimate against ``memory_mb``
    (None: no budget); ``explain(budget_bytes)`` says what drives the estimate and what fits
    (:func:`explain_memory` on the estimate's table of terms)."""
    values = sizes.to_json()
    if max_pairs is not None and sizes.pairs > max_pairs:
        raise LimitExceededError(
            f"the document gives {sizes.pairs} TX–RX pairs, above max_pairs = {max_pairs}; use"
            ' "pairs": {"sample": N, "seed": S} or coarser maps',
            max_pairs,
        )
    for name, (limit, what, label, hint) in LIMITS.items():
        if values[name] > limit:
            raise LimitExceededError(
                f"{values[name]} {what} exceed the {label} limit of {limit} ({name}); {hint}",
                limit,
            )
    cache_layout(sizes.cache_entries)  # (planar; run_plan checks the spherical rows too)
    if memory_mb is not None and sizes.memory_bytes > memory_mb << 20:
        need = math.ceil(sizes.memory_bytes / (1 << 20))
        why = (
            explain(memory_mb << 20) if explain is not None else "reduce pairs, sites or map sizes"
        )
        raise LimitExceededError(
            f"the run needs an estimated {grouped(need)} MiB, above the job memory budget of"
            f" {grouped(memory_mb)} MiB ({JOB_MEMORY_ENV}); {why}",
            memory_mb,
        )


def count(value: float) -> int:
    """A non-negative count from a float expression (inf/NaN → a count above every limit)."""
    if not math.isfinite(value) or value > 1e18:
        return 10**18
    return max(0, math.floor(value))


def rounded(value: float) -> int:
    """``round(value)`` of a non-negative ratio, overflow-safe (as :func:`count`)."""
    return count(value) if not math.isfinite(value) or value > 1e18 else round(value)


def csv_rows(text: str) -> int:
    """An upper bound on the data rows of CSV text (its lines after the header)."""
    return max(0, text.count("\n") + 1 - 1)


MAX_REQUEST_PAIRS = 10_000
"""Default TX–RX pairs of one bounds or power request (``RIS_PLANNER_MAX_PAIRS``)."""

MAX_ARRAY_ELEMENTS = 20_000_000
"""Default largest engine array of one request [elements]: max over RISs of pairs·N, 3G̃·N,
3G̃·pairs (``RIS_PLANNER_MAX_ARRAY_ELEMENTS``)."""

MAX_WORK = 1_000_000_000
"""Default complex products of one request, Σ_ℓ 3·G̃·N_ℓ·pairs, and its visibility tests
(legs × obstacle edges) (``RIS_PLANNER_MAX_WORK``)."""


@dataclass(frozen=True)
class RequestLimits:
    """The limits of one bounds or power request (the service reads them from its settings;
    :func:`ris_planner.bounds.resources.check_bounds_size` applies them)."""

    max_pairs: int = MAX_REQUEST_PAIRS
    max_array_elements: int = MAX_ARRAY_ELEMENTS
    max_work: int = MAX_WORK


LIST_LIMITS: dict[str, tuple[int, str]] = {
    "obstacles": (MAX_OBSTACLES, "obstacles"),
    "footprint": (MAX_FOOTPRINT_VERTICES, "footprint vertices"),
    "features": (MAX_OBSTACLES, "features"),
    "points": (MAX_MAP_POINTS, "points"),
    "sites": (MAX_SITES, "sites"),
    "candidates": (MAX_CANDIDATES, "candidates"),
    "exclude": (MAX_SITES, "excluded candidates"),
    "walls": (MAX_WALLS, "walls"),
    "facades": (MAX_WALLS, "facade groups"),
    "of": (MAX_FACADE_PRISMS, "prism names"),
    "tx_index": (MAX_PAIRS_LIMIT, "listed pairs"),
    "rx_index": (MAX_PAIRS_LIMIT, "listed pairs"),
    "tx": (MAX_PAIRS_LIMIT, "listed pairs"),
    "rx": (MAX_PAIRS_LIMIT, "listed pairs"),
    "weights": (MAX_MAP_POINTS, "weights"),
}
"""The lists a document may carry in bulk, by field name, with their limits (the models'
``max_length``: every list whose limit is 1000 items or more); :func:`prescan_document` refuses
longer ones before validation, and a model that refuses one reports it as a size limit too
(the service answers 413 with the limit either way)."""

COUNT_LIMITS: dict[str, tuple[int, str]] = {
    "sample": (MAX_PAIRS_LIMIT, "sampled pairs"),
    "max_pairs": (MAX_PAIRS_LIMIT, "pairs"),
}
"""The counts a document states (``pairs.sample``, ``max_pairs``), by field name, with their
limits (the models' ``le``); refused like the lists."""

MAP_FIELDS = ("tx_map", "rx_map", "ue_map")
"""The fields that hold a UE map: its grid, points and CSV rows count against
:data:`MAX_MAP_POINTS` together (a road lattice is counted once the map is validated)."""


def range_points(start: float, stop: float, step: float) -> int:
    """Values of a grid axis [start, stop, step] (stop included); above :data:`MAX_MAP_POINTS`
    however far (no float overflow). The range must be valid (finite, step > 0, stop ≥ start)."""
    ratio = (stop - start) / step
    if not math.isfinite(ratio) or ratio > MAX_MAP_POINTS:
        return MAX_MAP_POINTS + 1
    return math.floor(ratio + 1e-9) + 1


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def grid_points(grid: Any) -> int | None:
    """The points of a grid as a document gives it (``{"x": [start, stop, step], "y": …,
    "z": …}``), or None where it is not a valid grid (validation says why)."""
    if not isinstance(grid, dict):
        return None
    total = 1
    for axis in ("x", "y", "z"):
        r = grid.get(axis)
        if not (isinstance(r, list) and len(r) == 3 and all(_number(v) for v in r)):
            return None
        start, stop, step = (float(v) for v in r)
        if not (math.isfinite(start) and math.isfinite(stop) and step > 0 and stop >= start):
            return None
        total *= range_points(start, stop, step)
    return total


def _check_counts(item: dict[Any, Any], name: str, what: str) -> None:
    """The counts, the grid and the map size of one object of a document (413 above them)."""
    for key, (limit, label) in COUNT_LIMITS.items():
        value = item.get(key)
        if isinstance(value, int | float) and not isinstance(value, bool) and value > limit:
            raise LimitExceededError(
                f"{what}: {key} = {value} {label} exceed the limit of {limit}", limit
            )
    grid = grid_points(item.get("grid"))
    if grid is not None and grid > MAX_MAP_POINTS:
        raise LimitExceededError(
            f"{what}: {name or 'a map'}.grid has {grouped(grid)} points, above the limit of"
            f" {grouped(MAX_MAP_POINTS)}",
            MAX_MAP_POINTS,
        )
    if name in MAP_FIELDS:
        points, csv = item.get("points"), item.get("csv_text")
        total = grid or 0
        total += len(points) if isinstance(points, list) else 0
        total += csv_rows(csv) if isinstance(csv, str) else 0
        if total > MAX_MAP_POINTS:
            raise LimitExceededError(
                f"{what}: {name} has {grouped(total)} points (grid, points and CSV rows), above"
                f" the limit of {grouped(MAX_MAP_POINTS)}",
                MAX_MAP_POINTS,
            )


MAX_LIST_ITEMS = MAX_MAP_POINTS
"""Longest list of any other name (no field of a document takes more)."""

MAX_COORDINATES = 4 * MAX_MAP_POINTS
"""Numbers inside the lists of :data:`LIST_LIMITS` together (vertices, points: 2–3 each)."""


def prescan_document(value: Any, what: str = "request body") -> None:
    """Refuse a parsed JSON document above a size limit – lists longer than their limits
    (:data:`LIST_LIMITS`: obstacles, footprint vertices, features, points, sites, candidates,
    walls, …), any list above :data:`MAX_LIST_ITEMS`, more than :data:`MAX_COORDINATES` numbers
    in them together, a count above its limit (:data:`COUNT_LIMITS`: ``pairs.sample``,
    ``max_pairs``), a grid or a UE map above :data:`MAX_MAP_POINTS` points – with
    :class:`LimitExceededError` (413, with the limit) in one pass over the decoded value,
    before the (much slower) model validation. Iterative: no recursion limit (depth was checked
    when it was parsed)."""
    numbers = 0
    stack: list[tuple[Any, str]] = [(value, "")]
    while stack:
        item, name = stack.pop()
        if isinstance(item, dict):
            _check_counts(item, name, what)
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
