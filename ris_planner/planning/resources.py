"""A plan's sizes, memory and admission, computed from its validated document before anything
is built (docs/validation/resources.md).

:func:`estimate_plan` reads only the document (arithmetic on its numbers: no site, map point or
pair is created) and returns :class:`~ris_planner.model.limits.Sizes`; :func:`validate_plan`
is the one admission path of a plan document – the model, the rules that tie its fields
together, then the sizes against their limits (:func:`ris_planner.model.limits.check_sizes`).
The command line, the service's routes and the job functions call it, so a document the
service accepts is one the job can run.

The per-item byte costs below are the arrays each stage holds at its peak (float64, with the
temporaries of building them), rounded up; Python objects (sites, memo entries) are measured
sizes on CPython 3.11. A plan's memory is the sum of :func:`plan_memory`'s terms; a refusal
names the largest term and the largest value of its quantity that fits
(:func:`explain_plan_memory`). ``benchmarks/bench_memory.py`` checks the estimate against the
measured peak resident memory of real runs (docs/validation/resources.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from ris_planner.bounds.resources import check_bounds_size
from ris_planner.core.errors import DocumentFieldError, LimitExceededError
from ris_planner.model.limits import (
    BASE_BYTES,
    MAX_SEARCH_LAYOUTS,
    RequestLimits,
    Sizes,
    budget_mb,
    cache_layout,
    check_sizes,
    csv_rows,
    grouped,
    rounded,
)
from ris_planner.model.plan import LayoutBeamsDocument, PlanDocument, Wall, map_points
from ris_planner.model.simulation import (
    MIN_SCATTERER_DISTANCE_M,
    Multipath,
    describe_scatterer,
    scatterer_too_close,
)
from ris_planner.planning.maps import build_map, build_pairs
from ris_planner.planning.sites import facade_walls

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
directions [U, N, 3] of :func:`ris_planner.physics.spherical.point_terms` with the expected Gram's
[N, 3U] copy (the heatmap's positions and the cache's, each site in turn)."""


SPHERICAL_CHUNK_BYTES = (1 << 21) * 250
"""Spherical wavefront: the largest per-element chunk (:data:`spherical.CHUNK_ELEMENTS`
pair-elements of [·, N, 7] complex vectors and their temporaries) of the random codebooks'
re-evaluation."""


BYTES_PER_PROFILE_ELEMENT = 64
"""Per transmission and element: the random codebooks' first-block profiles (complex) and
their weighted copies (G̃·L ≤ G rows)."""


BYTES_PER_CHECK_PAIR = 24 << 10
"""Per pair of the codebook checks (≤ ``RANDOM_CODEBOOK_MAX_PAIRS``), their working set while
they run on a thread beside the fields and the figures
(:class:`ris_planner.planning.checks.PendingChecks`): the tasks' pair arrays, scenario copies
and FIM temporaries (tracemalloc peaks 14 MB at 1000 pairs, 47 MB at 2000,
docs/validation/resources.md)."""


BYTES_PER_CHECK_ELEMENT = 2 * 512 * 16
"""Per RIS element, the same checks' steering block and its product (two [N, 512] complex
arrays of :func:`ris_planner.physics.fim.planar_transmission_gram`'s chunk): 57 MB measured at
64 × 64 elements, 143 MB at 100 × 100."""


CSV_BYTES_PER_ROW_PARSED = 250


HEATMAP_MAX_PAIRS = 200_000
"""TX–RX pairs the plan's heatmap evaluates: at most this many RX points (a seeded sample of a
larger RX map) against a seeded weighted sample of the TX map."""


def _wall_sites(wall: Wall) -> int:
    """Sites of one wall, as :func:`ris_planner.planning.sites.wall_poses` lays them out."""
    if wall.rectangle is not None:
        x0, y0, x1, y1 = wall.rectangle
        lengths = [x1 - x0, y1 - y0, x1 - x0, y1 - y0]
    else:
        assert wall.start is not None and wall.end is not None
        lengths = [math.hypot(wall.end[0] - wall.start[0], wall.end[1] - wall.start[1])]
    along = sum(max(1, rounded(length / wall.spacing_m)) for length in lengths)
    return along * len(wall.heights_m) * len(wall.tilts_rad)


def plan_sites(doc: PlanDocument) -> int:
    """Candidate sites: explicit candidates, every wall's sites and every facade's (each
    footprint edge of a named prism is a wall)."""

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
    random-codebook profiles, spherical point terms and chunks), ``checks`` (the codebook
    checks, which may run beside the heatmap: :data:`BYTES_PER_CHECK_PAIR`,
    :data:`BYTES_PER_CHECK_ELEMENT`)."""
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
        "checks": min(shape.pairs, RANDOM_CODEBOOK_PAIRS) * BYTES_PER_CHECK_PAIR
        + n_el * BYTES_PER_CHECK_ELEMENT,
    }


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


def sizing_runs(doc: PlanDocument) -> int:
    """Plan runs the sizing question adds to a document's own (one per RIS size; 0 without)."""
    return 0 if doc.sizing is None else len(doc.sizing.ris_sizes)


def plan_runs(doc: PlanDocument) -> int:
    """Plan runs of one document: its own, and one per size of the sizing question
    (:func:`ris_planner.planning.resources.sizing_runs`; the runs are sequential, so they
    multiply the searched layouts, not the memory)."""

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
    mib = grouped(math.ceil(work[name] / (1 << 20)))
    heat_rx, heat_tx = shape.heatmap
    ris_in_layout = min(shape.max_count, max(shape.sites, 1))
    rows, cols = shape.ris_side
    what = {
        "maps": f"the UE maps ({grouped(shape.tx_points)} + {grouped(shape.rx_points)} points)",
        "pairs": f"the pairs ({grouped(shape.pairs)})",
        "sites": f"the candidate sites ({grouped(shape.sites)})",
        "site cache": f"the site cache ({grouped(shape.sites)} sites"
        f" × {grouped(shape.pairs)} pairs)",
        "cache build": f"building the site cache ({grouped(shape.pairs)} pairs)",
        "search": "the search's memoised layouts"
        f" ({grouped(min(shape.layouts, MAX_SEARCH_LAYOUTS))})",
        "heatmap": f"the heatmap ({grouped(heat_rx * heat_tx)} TX–RX pairs × {ris_in_layout} RISs,"
        f" {grouped(heat_rx)} RX points)",
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
            value = (
                "{} × {}".format(*_side(shape, best).ris_side) if knob == "side" else grouped(best)
            )
            return f"{out}; {text[knob].format(value)}"
    rest = grouped(math.ceil((sum(terms.values()) - work[name]) / (1 << 20)))
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
        csv_rows=sum(csv_rows(m.csv_text or "") for m in (doc.tx_map, doc.rx_map)),
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


def validate_plan(
    document: PlanDocument | dict[str, Any], memory_mb: int | None = None
) -> PlanDocument:
    """A plan document that ``run_plan`` accepts: the model, the candidate count against
    ``ris_count``, the sizes against their limits and the job memory budget (default
    ``RIS_PLANNER_JOB_MEMORY_MB``)."""
    doc = document if isinstance(document, PlanDocument) else PlanDocument.model_validate(document)
    plan_check(doc, memory_mb)
    return doc


def plan_check(doc: PlanDocument, memory_mb: int | None = None) -> Sizes:
    """The cross-field and size rules of a validated plan document; its sizes."""
    sites = plan_sites(doc)
    if doc.ris_count is not None and max(doc.ris_count) > sites:
        raise DocumentFieldError(
            "ris_count",
            f"ris_count {max(doc.ris_count)} exceeds the {sites} candidate sites",
        )
    sizes = estimate_plan(doc)
    shape = largest_plan_shape(doc)
    check_sizes(
        sizes,
        max_pairs=doc.max_pairs,
        memory_mb=budget_mb(memory_mb),
        explain=lambda budget: explain_plan_memory(shape, budget),
    )
    check_validation_scatterers(doc)
    return sizes


def check_validation_scatterers(doc: PlanDocument) -> None:
    """``validation.multipath``: no scatterer or cluster disk may come within
    :data:`~ris_planner.model.simulation.MIN_SCATTERER_DISTANCE_M` of a point of the TX or RX
    map (every point may be a sampled UE; docs/validation/estimator.md): a
    :class:`DocumentFieldError` naming the entry, the map and the point. Runs after the size
    checks (it builds the maps)."""
    spec = doc.validation
    if spec is None or not spec.multipath:
        return
    mp = Multipath.model_validate(spec.multipath)
    if not mp.scatterers and not mp.clusters:
        return
    maps = [("tx_map", doc.tx_map)] + ([] if doc.rx_map == doc.tx_map else [("rx_map", doc.rx_map)])
    for what, spec_map in maps:
        points = build_map(spec_map, what).points
        hit = scatterer_too_close(mp, points)
        if hit is not None:
            name, k, dist = hit
            raise DocumentFieldError(
                f"validation.multipath.{name}",
                f"{describe_scatterer(mp, name)} comes within {dist:.3g} m of {what} point {k}"
                f" {[round(float(v), 3) for v in points[k]]}; an SP must stay"
                f" ≥ {MIN_SCATTERER_DISTANCE_M:g} m from every map point (a sampled UE:"
                " its path gain ∝ 1/d diverges, its delay and angles degenerate): move or"
                " raise the cluster, or shrink its radius_m",
            )


def check_layout_beams_size(document: LayoutBeamsDocument, limits: RequestLimits) -> None:
    """The limits of a layout + UE-map power allocation: its pairs are evaluated by the bounds
    engine once per beam design (the maps' point counts are checked against their limit
    before they are expanded, :func:`ris_planner.model.plan.map_points`)."""
    # the maps' sizes before any is built (a road step of 5e-324 would build forever)
    sizes = Sizes(tx_points=map_points(document.tx_map), rx_points=map_points(document.rx_map))
    check_sizes(sizes, memory_mb=None)
    tx_map = build_map(document.tx_map, "tx_map")
    rx_map = build_map(document.rx_map, "rx_map")
    pairs = build_pairs(tx_map, rx_map, document.pairs, document.max_pairs)
    check_bounds_size(
        pairs.size,
        document.system.transmissions,
        [r.elements for r in document.ris],
        limits,
        document.environment,
    )
