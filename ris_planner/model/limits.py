"""Sizes that drive a run's memory and time, computed from the document before anything is
built, and the one check against their limits (README "Limits").

:func:`estimate_plan` / :func:`estimate_power` read only the validated document (arithmetic on
its numbers: no site, map point or pair is created) and return :class:`Sizes`;
:func:`check_sizes` raises :class:`LimitExceededError` naming the first quantity above its
limit, or the memory estimate above the job's budget (``RIS_PLANNER_JOB_MEMORY_MB``). The
command line and the service call the same functions (:mod:`ris_planner.validation`), so a
document the service accepts is one the job can run.

The per-item byte costs below are the arrays each stage holds at its peak (float64, with the
temporaries of building them), rounded up; Python objects (sites, memo entries) are measured
sizes on CPython 3.11. A plan's memory is the sum of :func:`plan_memory`'s terms; a refusal
names the largest term and the largest value of its quantity that fits
(:func:`explain_plan_memory`). ``benchmarks/bench_memory.py`` checks the estimate against the
measured peak resident memory of real runs (docs/validation/resources.md).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Literal, NamedTuple

from ris_planner.errors import LimitExceededError, RisPlannerError

if TYPE_CHECKING:  # the documents import this module's limits
    from ris_planner.planning.document import PlanDocument, Road, UEMap, Wall
    from ris_planner.scenario import Scenario

JOB_MEMORY_MB_DEFAULT = 6144
"""Memory budget of one job [MiB]: the 24 GiB machine runs two job workers beside the server
and the operating system (2 × 6 GiB + headroom)."""

JOB_MEMORY_ENV = "RIS_PLANNER_JOB_MEMORY_MB"
"""Environment variable with the budget (the service's setting; the CLI reads it too)."""

MAX_SITES = 100_000
"""Candidate sites: explicit candidates + Σ over walls of (length/spacing)·heights·tilts."""
MAX_MAP_POINTS = 1_000_000
"""Points of one UE map (grid + points + road lattice + CSV rows)."""
CACHE_MEMORY_MB_DEFAULT = 3072
"""Site-cache budget [MiB] (``RIS_PLANNER_CACHE_MEMORY_MB``) for the cache's block storage of 28
entries per site-pair and its square-root rows (:mod:`ris_planner.planning.site_cache`); the
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

# peak bytes per item (see the module docstring and docs/validation/resources.md)
BYTES_PER_MAP_POINT = 160
BYTES_PER_PAIR = 200
BYTES_PER_SITE = 4_000
BYTES_PER_CACHE_MASKS = 3
"""Per site-pair, beside the block storage: the degenerate, far-field and presence masks."""
BYTES_PER_LAYOUT = 250
BYTES_PER_CACHE_BUILD_PAIR = {"planar": 2_000, "spherical": 7_000}
"""Per pair, while the site cache is built: one site's path information (its 7×7 / 9×9
blocks, Jacobian and square-root rows) and its packed rows, reused site after site."""
BYTES_PER_HEATMAP_PAIR = {"planar": 1_600, "spherical": 5_500}
"""Per heatmap pair (TX × RX), independent of the RIS count: the pair arrays and the LOS path
of ``compute_bounds`` with its temporaries (spherical: the complex 9×9 products of one RIS
path), the reasons and weights of :meth:`PlanResult.rx_field`."""
BYTES_PER_HEATMAP_PAIR_RIS = 1_100
"""Per heatmap pair and RIS of the layout: each path's information and Jacobian, kept until
the state FIM is formed."""
BYTES_PER_HEATMAP_POINT = 1_200
BYTES_PER_HEATMAP_POINT_COUNT = 600
"""Per RX point of the heatmap, and per point and RIS count: the ``points`` entries of
plan.json (Python dicts and lists) and their JSON text."""
BYTES_PER_POINT_ELEMENT = 64
"""Spherical wavefront: per distinct UE position and RIS element, φ [U, N] and the centred
directions [U, N, 3] of :func:`ris_planner.spherical.point_terms` with the expected Gram's
[N, 3U] copy (the heatmap's positions and the cache's, each site in turn)."""
SPHERICAL_CHUNK_BYTES = (1 << 21) * 250
"""Spherical wavefront: the largest per-element chunk (:data:`spherical.CHUNK_ELEMENTS`
pair-elements of [·, N, 7] complex vectors and their temporaries) of the random codebooks'
re-evaluation."""
BYTES_PER_PROFILE_ELEMENT = 64
"""Per transmission and element: the random codebooks' first-block profiles (complex) and
their weighted copies (G̃·L ≤ G rows)."""
BYTES_PER_POWER_TERM = 8 * 49 * 24
"""Power: per beam and position, the 7×7 information and the conic solver's copies."""
BYTES_PER_BEAM_ELEMENT = 48
CSV_BYTES_PER_ROW_PARSED = 250
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
    (:func:`explain_plan_memory`)."""
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
            f"the run needs an estimated {_n(need)} MiB, above the job memory budget of"
            f" {_n(memory_mb)} MiB ({JOB_MEMORY_ENV}); {why}",
            memory_mb,
        )


def count(value: float) -> int:
    """A non-negative count from a float expression (inf/NaN → a count above every limit)."""
    if not math.isfinite(value) or value > 1e18:
        return 10**18
    return max(0, math.floor(value))


HEATMAP_MAX_PAIRS = 200_000
"""TX–RX pairs the plan's heatmap evaluates: at most this many RX points (a seeded sample of a
larger RX map) against a seeded weighted sample of the TX map."""


def _rounded(value: float) -> int:
    """``round(value)`` of a non-negative ratio, overflow-safe (as :func:`count`)."""
    return count(value) if not math.isfinite(value) or value > 1e18 else round(value)


def _wall_sites(wall: Wall) -> int:
    """Sites of one wall, as :func:`ris_planner.planning.sites.wall_poses` lays them out."""
    if wall.rectangle is not None:
        x0, y0, x1, y1 = wall.rectangle
        lengths = [x1 - x0, y1 - y0, x1 - x0, y1 - y0]
    else:
        assert wall.start is not None and wall.end is not None
        lengths = [math.hypot(wall.end[0] - wall.start[0], wall.end[1] - wall.start[1])]
    along = sum(max(1, _rounded(length / wall.spacing_m)) for length in lengths)
    return along * len(wall.heights_m) * len(wall.tilts_rad)


def _road_points(road: Road) -> int:
    """Lattice points of one road, as :func:`ris_planner.planning.maps.road_points` samples."""
    lateral = 2 * count(road.width_m / 2 / road.step_m + 1e-9) + 1
    total, any_segment = 0, False
    for a, b in zip(road.points, road.points[1:], strict=False):
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        if length == 0:
            continue
        any_segment = True
        total += count(math.ceil(length / road.step_m - 1e-9)) * lateral
    return total + (lateral if any_segment else 1)


def _csv_rows(text: str) -> int:
    """An upper bound on the data rows of CSV text (its lines after the header)."""
    return max(0, text.count("\n") + 1 - 1)


def map_points(spec: UEMap) -> int:
    """Points of a UE map before any is built (zero-weight points included)."""
    from ris_planner.planning.document import range_count

    n = 0
    if spec.grid is not None:
        g = spec.grid
        n += range_count(g.x, "x") * range_count(g.y, "y") * range_count(g.z, "z")
    n += len(spec.points or [])
    n += sum(_road_points(r) for r in spec.roads or [])
    if spec.csv_text is not None:
        n += _csv_rows(spec.csv_text)
    return n


def plan_sites(doc: PlanDocument) -> int:
    """Candidate sites: explicit candidates, every wall's sites and every facade's (each
    footprint edge of a named prism is a wall)."""
    from ris_planner.planning.sites import facade_walls

    facades = sum(
        _wall_sites(w)
        for fac, prisms in zip(doc.facades, doc.facade_prisms(), strict=True)
        for _, prism in prisms
        for w in facade_walls(fac, prism)
    )
    return len(doc.candidates) + sum(_wall_sites(w) for w in doc.walls) + facades


def _search_layouts(doc: PlanDocument, sites: int) -> int:
    """Layouts the searches may score, summed over the RIS counts (the worst case)."""
    total = 0
    for i, n_ris in enumerate(c for c in doc.max_counts if c <= sites):
        spec = doc.search
        layouts = math.comb(sites, n_ris) if sites >= n_ris else 0
        if spec.method == "exhaustive" or (
            spec.method == "auto" and layouts <= spec.max_exhaustive
        ):
            total += min(layouts, spec.max_exhaustive)
            continue
        starts = 1 + i + spec.restarts  # greedy, seeds (smaller counts), random restarts
        total += starts * (spec.max_rounds * n_ris * max(0, sites - n_ris) + n_ris * sites)
    return total


@dataclass(frozen=True)
class PlanShape:
    """The quantities a plan's memory grows with, read from its document
    (:func:`plan_shape`); :func:`plan_memory` turns them into bytes."""

    sites: int
    tx_points: int
    rx_points: int
    pairs: int
    """Pairs the run builds (the sample, or every pair up to ``max_pairs``)."""
    csv_rows: int
    layouts: int
    """Layouts one plan run may score (the sizing question's runs are sequential: they
    multiply the search, not the memory)."""
    counts: int
    """RIS counts searched (one ``points`` entry each per RX point)."""
    max_count: int
    elements: int
    """Elements per RIS (rows × cols)."""
    ris_side: tuple[int, int]
    transmissions: int
    wavefront: str
    fixed_heatmap_tx: bool

    @property
    def heatmap(self) -> tuple[int, int]:
        """(RX points, TX points) of the heatmap (:meth:`PlanResult.heatmap_tx`)."""
        heat_rx = min(self.rx_points, HEATMAP_MAX_PAIRS)
        if self.fixed_heatmap_tx:
            return heat_rx, 1
        return heat_rx, min(self.tx_points, max(1, HEATMAP_MAX_PAIRS // max(heat_rx, 1)))


def plan_memory(shape: PlanShape) -> dict[str, int]:
    """Peak bytes of a plan run (plan, figures and GIS files in one process, as a service job
    runs it), term by term; the estimate is their sum (docs/validation/resources.md).

    Terms: ``base`` (interpreter and imports), ``maps``, ``pairs``, ``sites``, ``site cache``
    (its :func:`cache_layout` and masks), ``cache build`` (one site's path information at a
    time), ``search`` (memoised layouts), ``heatmap`` (the largest count's ``compute_bounds``
    on the heatmap pairs, and the per-point results), ``elements`` (the per-element arrays:
    random-codebook profiles, spherical point terms and chunks)."""
    w = shape.wavefront
    spherical = w == "spherical"
    n_el = shape.elements
    heat_rx, heat_tx = shape.heatmap
    heat_pairs = heat_rx * heat_tx
    ris_in_layout = min(shape.max_count, max(shape.sites, 1))
    entries = shape.sites * shape.pairs
    try:
        cache = cache_layout(entries, w).bytes(entries, w) + entries * BYTES_PER_CACHE_MASKS
    except LimitExceededError:
        cache = 0  # refused by its own budget (check_sizes)
    elements = shape.transmissions * n_el * BYTES_PER_PROFILE_ELEMENT
    if spherical:
        positions = shape.tx_points + shape.rx_points
        rc_pairs = min(shape.pairs, RANDOM_CODEBOOK_PAIRS)
        # the largest of: the heatmap's positions, the cache's, the codebook re-evaluation's
        points = max(
            min(positions, heat_rx + heat_tx),
            min(positions, 2 * shape.pairs),
        )
        elements += points * n_el * BYTES_PER_POINT_ELEMENT
        elements += min(rc_pairs * n_el, SPHERICAL_CHUNK_BYTES // 250) * 250
    return {
        "base": BASE_BYTES,
        "maps": (shape.tx_points + shape.rx_points) * BYTES_PER_MAP_POINT
        + shape.csv_rows * CSV_BYTES_PER_ROW_PARSED,
        "pairs": shape.pairs * BYTES_PER_PAIR,
        "sites": shape.sites * BYTES_PER_SITE,
        "site cache": cache,
        "cache build": shape.pairs * BYTES_PER_CACHE_BUILD_PAIR[w],
        "search": min(shape.layouts, MAX_SEARCH_LAYOUTS) * BYTES_PER_LAYOUT,
        "heatmap": heat_pairs
        * (BYTES_PER_HEATMAP_PAIR[w] + ris_in_layout * BYTES_PER_HEATMAP_PAIR_RIS)
        + heat_rx * (BYTES_PER_HEATMAP_POINT + shape.counts * BYTES_PER_HEATMAP_POINT_COUNT),
        "elements": elements,
    }


def _n(value: int) -> str:
    """An integer with thin groups of three digits (``1 000 000``)."""
    return f"{value:,}".replace(",", " ")


def _memory(shape: PlanShape) -> int:
    return sum(plan_memory(shape).values())


def _largest(make: Callable[[int], PlanShape], low: int, now: int, budget: int) -> int:
    """The largest value ``low`` ≤ v ≤ ``now`` whose shape ``make(v)`` fits ``budget`` bytes
    (the memory grows with v); 0 when not even ``low`` fits."""
    if _memory(make(low)) > budget:
        return 0
    lo, hi = low, now  # fits(lo); hi: the current value, which does not fit
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _memory(make(mid)) <= budget:
            lo = mid
        else:
            hi = mid
    return lo


def plan_runs(doc: PlanDocument) -> int:
    """Plan runs of one document: its own, and one per size of the sizing question
    (:func:`ris_planner.planning.sizing.sizing_runs`; the runs are sequential, so they
    multiply the searched layouts, not the memory)."""
    from ris_planner.planning.sizing import sizing_runs

    return 1 + sizing_runs(doc)


def _side(shape: PlanShape, rows: int) -> PlanShape:
    r0, c0 = shape.ris_side
    cols = max(1, round(rows * c0 / r0))
    return replace(shape, ris_side=(rows, cols), elements=rows * cols)


def explain_plan_memory(shape: PlanShape, budget_bytes: int) -> str:
    """What drives a plan's memory estimate (its largest term of :func:`plan_memory` but the
    base) and the largest value of that quantity that fits ``budget_bytes`` – "dominated by
    the site cache (52 sites × 1 000 000 pairs); the largest pair count that fits is 860 000"
    (docs/validation/resources.md)."""
    terms = plan_memory(shape)
    work = {k: v for k, v in terms.items() if k != "base"}
    name = max(work, key=lambda k: work[k])
    mib = _n(math.ceil(work[name] / (1 << 20)))
    heat_rx, heat_tx = shape.heatmap
    ris_in_layout = min(shape.max_count, max(shape.sites, 1))
    rows, cols = shape.ris_side
    what = {
        "maps": f"the UE maps ({_n(shape.tx_points)} + {_n(shape.rx_points)} points)",
        "pairs": f"the pairs ({_n(shape.pairs)})",
        "sites": f"the candidate sites ({_n(shape.sites)})",
        "site cache": f"the site cache ({_n(shape.sites)} sites × {_n(shape.pairs)} pairs)",
        "cache build": f"building the site cache ({_n(shape.pairs)} pairs)",
        "search": f"the search's memoised layouts ({_n(min(shape.layouts, MAX_SEARCH_LAYOUTS))})",
        "heatmap": f"the heatmap ({_n(heat_rx * heat_tx)} TX–RX pairs × {ris_in_layout} RISs,"
        f" {_n(heat_rx)} RX points)",
        "elements": f"the per-element arrays ({rows} × {cols} elements per RIS,"
        f" {shape.wavefront} wavefront)",
    }[name]
    fixed = replace(shape, fixed_heatmap_tx=True)
    pairs = ("pairs", lambda v: replace(shape, pairs=v), 1, shape.pairs)
    sites = ("sites", lambda v: replace(shape, sites=v), max(1, shape.max_count), shape.sites)
    knobs: dict[str, list[tuple[str, Callable[[int], PlanShape], int, int]]] = {
        "pairs": [pairs],
        "site cache": [pairs, sites],
        "cache build": [pairs],
        "sites": [sites],
        "heatmap": [
            ("count", lambda v: replace(shape, max_count=v), 1, ris_in_layout),
            ("fixed", lambda v: fixed if v else shape, 0, 1),
            ("rx", lambda v: replace(fixed, rx_points=v), 1, shape.rx_points),
        ],
        "elements": [("side", lambda v: _side(shape, v), 1, rows)],
        "maps": [("rx", lambda v: replace(shape, rx_points=v), 1, shape.rx_points)],
    }
    text = {
        "pairs": "the largest pair count that fits is {}",
        "sites": "the most candidate sites that fit are {}",
        "count": "the largest RIS count that fits is {}",
        "fixed": "it fits with a fixed heatmap_tx (one TX point per RX point of the heatmap)",
        "rx": "the largest RX map that fits has {} points (with a fixed heatmap_tx)",
        "side": "the largest RIS that fits is {}",
    }
    out = f"dominated by {what}: {mib} MiB"
    for knob, make, low, now in knobs.get(name, []):
        if now <= low and knob != "fixed":
            continue
        if knob == "fixed" and shape.fixed_heatmap_tx:
            continue
        best = _largest(make, low, now, budget_bytes) if knob != "fixed" else 0
        if knob == "fixed" and _memory(fixed) <= budget_bytes:
            return f"{out}; {text[knob]}"
        if best >= 1:
            value = "{} × {}".format(*_side(shape, best).ris_side) if knob == "side" else _n(best)
            return f"{out}; {text[knob].format(value)}"
    rest = _n(math.ceil((sum(terms.values()) - work[name]) / (1 << 20)))
    return f"{out}; the rest of the run alone needs {rest} MiB"


RANDOM_CODEBOOK_PAIRS = 2_000
"""Pairs of the random-codebook re-evaluation (``planning.plan.RANDOM_CODEBOOK_MAX_PAIRS``)."""


def plan_shape(doc: PlanDocument) -> PlanShape:
    """The :class:`PlanShape` of a validated plan document (nothing is built)."""
    sites = plan_sites(doc)
    n_t, n_r = map_points(doc.tx_map), map_points(doc.rx_map)
    pairs_spec = doc.pairs
    if isinstance(pairs_spec, str):
        pairs = n_t * (n_t - 1) // 2 if pairs_spec == "unordered" else n_t * n_r
    else:
        pairs = pairs_spec.sample
    return PlanShape(
        sites=sites,
        tx_points=n_t,
        rx_points=n_r,
        pairs=min(pairs, doc.max_pairs),
        csv_rows=sum(_csv_rows(m.csv_text or "") for m in (doc.tx_map, doc.rx_map)),
        layouts=_search_layouts(doc, sites),
        counts=len(doc.max_counts),
        max_count=max(doc.max_counts),
        elements=doc.ris.rows * doc.ris.cols,
        ris_side=(doc.ris.rows, doc.ris.cols),
        transmissions=doc.system.transmissions,
        wavefront=doc.system.wavefront,
        fixed_heatmap_tx=doc.heatmap_tx is not None,
    )


def largest_plan_shape(doc: PlanDocument) -> PlanShape:
    """The :func:`plan_shape` of the document's run that needs the most memory: its own, or one
    with another RIS size of ``sweep.ris_size`` or ``sizing.ris_sizes`` (those runs are
    sequential: the estimate is the largest one's)."""
    shape = plan_shape(doc)
    sides = [tuple(rc) for rc in (doc.sweep.ris_size or [])] if doc.sweep is not None else []
    sides += [tuple(rc) for rc in doc.sizing.ris_sizes] if doc.sizing is not None else []
    shapes = [shape] + [replace(shape, ris_side=(r, c), elements=r * c) for r, c in sides]
    return max(shapes, key=_memory)


def estimate_plan(doc: PlanDocument) -> Sizes:
    """Every size of a plan run from its validated document (nothing is built); the memory is
    the sum of :func:`plan_memory` for its largest run (:func:`largest_plan_shape`)."""
    shape = largest_plan_shape(doc)
    n_t, n_r = shape.tx_points, shape.rx_points
    pairs_spec = doc.pairs
    if isinstance(pairs_spec, str):
        pairs = n_t * (n_t - 1) // 2 if pairs_spec == "unordered" else n_t * n_r
    else:
        pairs = pairs_spec.sample
    heat_rx, heat_tx = shape.heatmap
    return Sizes(
        sites=shape.sites,
        tx_points=n_t,
        rx_points=n_r,
        pairs=pairs,
        cache_entries=shape.sites * pairs,
        heatmap_pairs=heat_rx * heat_tx,
        search_layouts=shape.layouts * plan_runs(doc),
        memory_bytes=sum(plan_memory(shape).values()),
    )


def estimate_power(scenario: Scenario) -> Sizes:
    """The sizes of a power allocation (``ris-planner power``) from its validated scenario:
    G̃ beams, the design positions (prior samples of a DIR/DIR+DER codebook, else the pairs)
    and the elements of each RIS."""
    from ris_planner.codebooks import block_length

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
