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
sizes on CPython 3.11. A plan's memory is the sum of :func:`plan_memory`'s terms, one table
(:data:`PLAN_MEMORY_TERMS`) that holds each term's bytes with what a refusal says about it; a
refusal names the largest term and the largest value of its quantity that fits, or that none
does and which settings to change (:func:`explain_plan_memory`).
``benchmarks/resources/bench_memory.py`` checks the estimate against the measured peak resident
memory of real runs (docs/validation/resources.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

from ris_planner.bounds.resources import check_bounds_size
from ris_planner.core.errors import DocumentFieldError, LimitExceededError
from ris_planner.model.limits import (
    BASE_BYTES,
    HEATMAP_MAX_PAIRS,
    JOB_MEMORY_ENV,
    MAX_SEARCH_LAYOUTS,
    Knob,
    MemoryTerm,
    RequestLimits,
    Sizes,
    budget_mb,
    cache_layout,
    check_sizes,
    csv_rows,
    explain_memory,
    grouped,
    memory_terms,
    rounded,
)
from ris_planner.model.plan import (
    LayoutBeamsDocument,
    PlanDocument,
    WallSites,
    local_pairs,
    map_points,
    pairs_given,
)
from ris_planner.model.search_methods import (
    AUTO,
    MAX_LAYOUT_RIS,
    MethodChoice,
    SearchMethod,
    count_method,
    method_refusals,
    scoring_of,
    search_method,
    sparse_search,
)
from ris_planner.model.simulation import (
    MIN_SCATTERER_DISTANCE_M,
    Multipath,
    describe_scatterer,
    scatterer_too_close,
)
from ris_planner.planning.inputs.sites import Site, expand_sites, facade_walls
from ris_planner.planning.inputs.ue_maps import PointMap, build_map, build_pairs
from ris_planner.planning.resources.served import document_shares

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


BYTES_PER_HEATMAP_PAIR_OBSTRUCTED = 400
"""Per heatmap pair (planar) where the environment has obstacles: the pair arrays, the LOS path
and the presence masks – a RIS path's information is formed only for the pairs the RIS serves
at both ends and the counting rule leaves open (``compute_bounds``' ``presence``), few of them
on a street (measured peaks: ≈ 550 B per pair and RIS in all, docs/validation/resources.md)."""


BYTES_PER_HEATMAP_PAIR_RIS_OBSTRUCTED = 500
"""Per heatmap pair and RIS of the layout where the environment has obstacles (see
:data:`BYTES_PER_HEATMAP_PAIR_OBSTRUCTED`)."""


BYTES_PER_RELAXATION_SITE_PAIR = 350
"""Per site-pair, while the relaxation bound of a count searched greedily runs (the
Frank–Wolfe iterates and gradients over every site and pair, beside the site cache; measured
+245 MiB at 730 sites × 1000 pairs, +170 MiB at 596 × 1000)."""


BYTES_PER_VALIDATION_CANDIDATE = 1_000
"""Per TX candidate of the validation's coarse position search (``validation.max_candidates``
at most): the candidate grid and each candidate's predicted channel parameters and cost."""


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
(:class:`ris_planner.planning.certify.checks.PendingChecks`): the tasks' pair arrays, scenario
copies
and FIM temporaries (tracemalloc peaks 14 MB at 1000 pairs, 47 MB at 2000,
docs/validation/resources.md)."""


BYTES_PER_CHECK_ELEMENT = 2 * 512 * 16
"""Per RIS element, the same checks' steering block and its product (two [N, 512] complex
arrays of :func:`ris_planner.physics.fim.planar_transmission_gram`'s chunk): 57 MB measured at
64 × 64 elements, 143 MB at 100 × 100."""


CSV_BYTES_PER_ROW_PARSED = 250


def _wall_sites(wall: WallSites) -> int:
    """Sites of one wall, as :func:`ris_planner.planning.inputs.sites.wall_poses` lays them out."""
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


GREEDY_SWAP_ROUNDS = 1.0
"""Rounds' worth of new layouts a greedy start scores in its swap rounds: each round's
neighbours share most layouts with the previous round's and with the other starts' (the memo
scores each once), and on the calibration cases the starts settle within a few rounds – the
new layouts come to about one round's neighbourhood per start (docs/validation/resources.md)."""


def greedy_layouts(n_sites: int, count: int, restarts: int, rounds: int, seeds: int = 0) -> float:
    """Layouts a greedy search scores, roughly: the forward build (count × sites), each
    smaller count's best layout completed (one step of sites each), and per start
    (greedy, seeds, random restarts) :data:`GREEDY_SWAP_ROUNDS` rounds' worth of new
    count × (sites − count) neighbours (the memo scores a layout once)."""
    swaps = count * max(n_sites - count, 0)
    starts = 1 + seeds + restarts
    return count * n_sites + seeds * n_sites + starts * min(rounds, GREEDY_SWAP_ROUNDS) * swaps


def _exhaustive(doc: PlanDocument, sites: int, n_ris: int) -> bool:
    spec = doc.search
    layouts = math.comb(sites, n_ris) if sites >= n_ris else 0
    return count_method(spec.method, layouts, spec.max_exhaustive) == "exhaustive"


def _memo_layouts(doc: PlanDocument, sites: int) -> int:
    """Layouts one run's searches score and memoise, summed over the RIS counts, as a search
    typically runs (:func:`greedy_layouts`; every layout of an exhaustive count)."""
    if sparse_search(doc):
        return 0
    counts = [c for c in doc.max_counts if c <= sites]
    total = 0.0
    for n_ris in counts:
        layouts = math.comb(sites, n_ris)
        if _exhaustive(doc, sites, n_ris):
            total += min(layouts, doc.search.max_exhaustive)
            continue
        seeds = sum(c < n_ris for c in counts)
        spec = doc.search
        total += min(layouts, greedy_layouts(sites, n_ris, spec.restarts, spec.max_rounds, seeds))
    return math.ceil(total)


def _search_layouts(doc: PlanDocument, sites: int) -> int:
    """Layouts the searches may score, summed over the RIS counts (the worst case: every
    start runs ``max_rounds``; the limit's :data:`MAX_SEARCH_LAYOUTS`)."""
    if sparse_search(doc):
        return 0  # no layout is enumerated: the district term counts its work
    total = 0
    spec = doc.search
    for i, n_ris in enumerate(c for c in doc.max_counts if c <= sites):
        if _exhaustive(doc, sites, n_ris):
            total += min(math.comb(sites, n_ris), spec.max_exhaustive)
            continue
        starts = 1 + i + spec.restarts  # greedy, seeds (smaller counts), random restarts
        total += starts * (spec.max_rounds * n_ris * max(0, sites - n_ris) + n_ris * sites)
    return total


def run_layouts(doc: PlanDocument, sites: int) -> int:
    """Layouts a plan's enumerating runs may score: its own searches' and, when the enumerating
    searches answer the sizing question, one run per RIS size over the sizing counts
    (:meth:`~ris_planner.model.plan.PlanDocument.sizing_counts`)."""
    own = _search_layouts(doc, sites)
    runs = sizing_runs(doc)
    if not runs:
        return own
    sizing = doc.model_copy(update={"ris_count": doc.sizing_counts(), "sizing": None})
    return own + _search_layouts(sizing, sites) * runs


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
    """Layouts one plan run's search scores and memoises, as it typically runs
    (:func:`_memo_layouts`; the sizing question's runs are sequential: they multiply the
    search's time, not its memory)."""
    counts: int
    """RIS counts searched (one ``points`` entry each per RX point)."""
    max_count: int
    elements: int
    """Elements per RIS (rows × cols)."""
    ris_side: tuple[int, int]
    transmissions: int
    wavefront: str
    fixed_heatmap_tx: bool
    district: bool = False
    """search.method 'district': sparse information per (pair, serving site), no site cache,
    no heatmap, no codebook checks (:mod:`ris_planner.planning.search.district`)."""
    district_share: float = 0.0
    """A district plan's share of (pair, site) combinations served
    (:func:`~ris_planner.planning.resources.served.pair_served_share`)."""
    district_sizes: int = 1
    """RIS sizes whose district information is held at once (the document's and the other
    sizes of ``sizing.ris_sizes``)."""
    pair_fields: bool = False
    """The per-point fields come from the plan's own pairs (:func:`local_pairs`): no heatmap
    pairs are evaluated, only the per-point results are held."""
    obstructed: bool = False
    """The environment has obstacles: the heatmap forms RIS paths for the served pairs only
    (:data:`BYTES_PER_HEATMAP_PAIR_OBSTRUCTED`)."""
    relaxed_counts: int = 0
    """RIS counts searched greedily with a relaxation bound (``certificate_iterations`` > 0)."""
    sizing_runs: int = 0
    """Runs of the sizing question (one per ``sizing.ris_sizes``), each with its own site cache
    while the plan's own result is held."""
    validation_candidates: int = 0
    """TX candidates of the validation's coarse search (0: no ``validation``)."""

    @property
    def heatmap(self) -> tuple[int, int]:
        """(RX points, TX points) of the heatmap (:meth:`PlanResult.heatmap_tx`)."""
        heat_rx = min(self.rx_points, HEATMAP_MAX_PAIRS)
        if self.fixed_heatmap_tx:
            return heat_rx, 1
        return heat_rx, min(self.tx_points, max(1, HEATMAP_MAX_PAIRS // max(heat_rx, 1)))


RANDOM_CODEBOOK_PAIRS = 2_000
"""Pairs of the random-codebook re-evaluation (``planning.plan.RANDOM_CODEBOOK_MAX_PAIRS``)."""


def _ris_in_layout(shape: PlanShape) -> int:
    return min(shape.max_count, max(shape.sites, 1))


BYTES_PER_DISTRICT_ENTRY = 1200
"""Bytes per estimated (pair, serving site) of the district search (pairs × sites × the served
share): packed information and square-root rows on up to 7 states, the search's strongest
entries, indices, gains and the relaxation – its matrix with the non-cover cuts and the
separated rows, and the solver's interior-point factors (fitted to the peaks of the Helsinki
district plans, docs/validation/resources.md; the sample's share runs low on streets)."""

DISTRICT_SIZE_SHARE = 0.8
"""Each further RIS size of a district sizing holds this share of the first size's entries
more (its information is built while the first's is held)."""

BYTES_PER_DISTRICT_MASK = 3
"""Bytes per (pair, site) of the district search's visibility: the two gathered serve masks
and their conjunction."""


def district_entries(shape: PlanShape) -> float:
    """The estimated (pair, serving site) entries of a district plan: pairs × sites × its served
    share."""
    return shape.district_share * shape.pairs * shape.sites


def _district_bytes(shape: PlanShape) -> int:
    if not shape.district:
        return 0
    held = 1 + DISTRICT_SIZE_SHARE * (shape.district_sizes - 1)
    entries = district_entries(shape) * BYTES_PER_DISTRICT_ENTRY * held
    return int(entries) + shape.pairs * shape.sites * BYTES_PER_DISTRICT_MASK


def _site_cache_bytes(shape: PlanShape) -> int:
    if shape.district:
        return 0
    w, entries = shape.wavefront, shape.sites * shape.pairs
    try:
        return cache_layout(entries, w).bytes(entries, w) + entries * BYTES_PER_CACHE_MASKS
    except LimitExceededError:
        return 0  # refused by its own budget (check_sizes)


def _heatmap_bytes(shape: PlanShape) -> int:
    if shape.district:
        return 0
    heat_rx, heat_tx = shape.heatmap
    per_point = BYTES_PER_HEATMAP_POINT + shape.counts * BYTES_PER_HEATMAP_POINT_COUNT
    if shape.pair_fields:  # the plan's own pairs, already scored: the per-point results only
        return heat_rx * per_point
    if shape.obstructed and shape.wavefront == "planar":
        per_pair = BYTES_PER_HEATMAP_PAIR_OBSTRUCTED
        per_pair += _ris_in_layout(shape) * BYTES_PER_HEATMAP_PAIR_RIS_OBSTRUCTED
    else:
        per_pair = BYTES_PER_HEATMAP_PAIR[shape.wavefront]
        per_pair += _ris_in_layout(shape) * BYTES_PER_HEATMAP_PAIR_RIS
    return heat_rx * heat_tx * per_pair + heat_rx * per_point


def _element_bytes(shape: PlanShape) -> int:
    n_el = shape.elements
    elements = shape.transmissions * n_el * BYTES_PER_PROFILE_ELEMENT
    if shape.wavefront == "spherical":
        heat_rx, heat_tx = shape.heatmap
        positions = shape.tx_points + shape.rx_points
        rc_pairs = min(shape.pairs, RANDOM_CODEBOOK_PAIRS)
        # the largest of: the heatmap's positions, the cache's, the codebook re-evaluation's
        points = max(
            min(positions, heat_rx + heat_tx),
            min(positions, 2 * shape.pairs),
        )
        elements += points * n_el * BYTES_PER_POINT_ELEMENT
        elements += min(rc_pairs * n_el, SPHERICAL_CHUNK_BYTES // 250) * 250
    return elements


def _relaxation_bytes(shape: PlanShape) -> int:
    if shape.district or not shape.relaxed_counts:
        return 0
    return shape.sites * shape.pairs * BYTES_PER_RELAXATION_SITE_PAIR


def _sizing_bytes(shape: PlanShape) -> int:
    """A sizing run's own site cache and cache build, beside the plan's (held until the
    sizing is answered)."""
    if shape.district or not shape.sizing_runs:
        return 0
    return _site_cache_bytes(shape) + shape.pairs * BYTES_PER_CACHE_BUILD_PAIR[shape.wavefront]


def _validation_bytes(shape: PlanShape) -> int:
    if shape.district:
        return 0
    return shape.validation_candidates * BYTES_PER_VALIDATION_CANDIDATE


def _check_bytes(shape: PlanShape) -> int:
    if shape.district:
        return 0
    pairs = min(shape.pairs, RANDOM_CODEBOOK_PAIRS)
    return pairs * BYTES_PER_CHECK_PAIR + shape.elements * BYTES_PER_CHECK_ELEMENT


def _side(shape: PlanShape, side: int) -> PlanShape:
    """The shape with RISs whose longer side is ``side`` elements, the other one in the
    document's proportion."""
    r0, c0 = shape.ris_side
    if r0 >= c0:
        rows, cols = side, max(1, round(side * c0 / r0))
    else:
        rows, cols = max(1, round(side * r0 / c0)), side
    return replace(shape, ris_side=(rows, cols), elements=rows * cols)


# the quantities a plan refusal may lower (advise_memory tries a term's knobs in order)
_PAIRS: Knob[PlanShape] = Knob(
    "the largest pair count that fits is {}",
    lambda s: (1, s.pairs),
    lambda s, v: replace(s, pairs=v),
)
_SITES: Knob[PlanShape] = Knob(
    "the most candidate sites that fit are {}",
    lambda s: (max(1, s.max_count), s.sites),
    lambda s, v: replace(s, sites=v),
)
_RIS_COUNT: Knob[PlanShape] = Knob(
    "the largest RIS count that fits is {}",
    lambda s: (1, _ris_in_layout(s)),
    lambda s, v: replace(s, max_count=v),
)
_FIXED_HEATMAP_TX: Knob[PlanShape] = Knob(
    "it fits with a fixed heatmap_tx (one TX point per RX point of the heatmap)",
    lambda s: (0, 0 if s.fixed_heatmap_tx else 1),
    lambda s, v: s if v else replace(s, fixed_heatmap_tx=True),
)
_HEATMAP_RX: Knob[PlanShape] = Knob(
    "the largest RX map that fits has {} points (with a fixed heatmap_tx)",
    lambda s: (1, s.rx_points),
    lambda s, v: replace(s, fixed_heatmap_tx=True, rx_points=v),
)
_RX_MAP: Knob[PlanShape] = Knob(
    "the largest RX map that fits has {} points",
    lambda s: (1, s.rx_points),
    lambda s, v: replace(s, rx_points=v),
)
_TX_MAP: Knob[PlanShape] = Knob(
    "the largest TX map that fits has {} points",
    lambda s: (1, s.tx_points),
    lambda s, v: replace(s, tx_points=v),
)
_LAYOUTS: Knob[PlanShape] = Knob(
    "at most {} searched layouts fit (search.restarts, search.max_rounds, the sites)",
    lambda s: (1, min(s.layouts, MAX_SEARCH_LAYOUTS)),
    lambda s, v: replace(s, layouts=v),
)
_RIS_SIDE: Knob[PlanShape] = Knob(
    "the largest RIS that fits is {}",
    lambda s: (1, max(s.ris_side)),
    _side,
    lambda s, v: "{} × {}".format(*_side(s, v).ris_side),
)

_VALIDATION_CANDIDATES: Knob[PlanShape] = Knob(
    "the most validation candidates that fit are {} (validation.max_candidates)",
    lambda s: (1, s.validation_candidates),
    lambda s, v: replace(s, validation_candidates=v),
)

_FEWER_PAIRS = "sample fewer pairs (pairs.sample, max_pairs) or use coarser UE maps"
_SMALLER_RIS = "use smaller RISs (ris.rows × ris.cols)"

PLAN_MEMORY_TERMS: dict[str, MemoryTerm[PlanShape]] = {
    "base": MemoryTerm(
        lambda s: BASE_BYTES,
        lambda s: "the base (the interpreter and its imports)",
        f"a plan needs a job memory budget above {BASE_BYTES >> 20} MiB ({JOB_MEMORY_ENV})",
        fixed=True,
    ),
    "maps": MemoryTerm(
        lambda s: (
            (s.tx_points + s.rx_points) * BYTES_PER_MAP_POINT
            + s.csv_rows * CSV_BYTES_PER_ROW_PARSED
        ),
        lambda s: (
            f"the UE maps ({grouped(s.tx_points)} + {grouped(s.rx_points)} points,"
            f" {grouped(s.csv_rows)} CSV rows)"
        ),
        "use coarser tx_map and rx_map (grid steps, road step_m, fewer points or CSV rows)",
        (_RX_MAP, _TX_MAP),
    ),
    "pairs": MemoryTerm(
        lambda s: s.pairs * BYTES_PER_PAIR,
        lambda s: f"the pairs ({grouped(s.pairs)})",
        _FEWER_PAIRS,
        (_PAIRS,),
    ),
    "sites": MemoryTerm(
        lambda s: s.sites * BYTES_PER_SITE,
        lambda s: f"the candidate sites ({grouped(s.sites)})",
        "use fewer candidates, walls or facades (a larger spacing_m, fewer heights_m or tilts_rad)",
        (_SITES,),
    ),
    "site cache": MemoryTerm(
        _site_cache_bytes,
        lambda s: f"the site cache ({grouped(s.sites)} sites × {grouped(s.pairs)} pairs)",
        f"{_FEWER_PAIRS}, or fewer candidate sites",
        (_PAIRS, _SITES),
    ),
    "district": MemoryTerm(
        _district_bytes,
        lambda s: (
            f"the district search's information ({grouped(s.pairs)} pairs × about"
            f" {district_entries(s) / max(s.pairs, 1):.0f} serving sites of"
            f" {grouped(s.sites)} candidates, {s.district_sizes} RIS size(s))"
        ),
        f"{_FEWER_PAIRS}, or fewer candidate sites",
        (_PAIRS, _SITES),
    ),
    "cache build": MemoryTerm(
        lambda s: s.pairs * BYTES_PER_CACHE_BUILD_PAIR[s.wavefront],
        lambda s: (
            f"the cache build (one site's path information for {grouped(s.pairs)} pairs,"
            f" {s.wavefront} wavefront)"
        ),
        _FEWER_PAIRS,
        (_PAIRS,),
    ),
    "relaxation": MemoryTerm(
        _relaxation_bytes,
        lambda s: (
            f"the relaxation bound ({grouped(s.sites)} sites × {grouped(s.pairs)} pairs,"
            f" {s.relaxed_counts} counts searched greedily)"
        ),
        f"{_FEWER_PAIRS}, fewer candidate sites, or search.certificate_iterations 0",
        (_PAIRS, _SITES),
    ),
    "sizing": MemoryTerm(
        _sizing_bytes,
        lambda s: (
            f"the sizing runs' own site cache ({grouped(s.sites)} sites × {grouped(s.pairs)}"
            f" pairs, {s.sizing_runs} runs one after another)"
        ),
        f"{_FEWER_PAIRS}, fewer candidate sites, or ask the sizing question in a plan of its own",
        (_PAIRS, _SITES),
    ),
    "validation": MemoryTerm(
        _validation_bytes,
        lambda s: (
            f"the validation's position search ({grouped(s.validation_candidates)} TX candidates)"
        ),
        "use fewer validation.max_candidates or a larger validation.step_m",
        (_VALIDATION_CANDIDATES,),
    ),
    "search": MemoryTerm(
        lambda s: min(s.layouts, MAX_SEARCH_LAYOUTS) * BYTES_PER_LAYOUT,
        lambda s: f"the search's memoised layouts ({grouped(min(s.layouts, MAX_SEARCH_LAYOUTS))})",
        "use fewer search.restarts or search.max_rounds, fewer candidate sites or smaller"
        " ris_count",
        (_LAYOUTS,),
    ),
    "heatmap": MemoryTerm(
        _heatmap_bytes,
        lambda s: (
            f"the heatmap ({grouped(s.heatmap[0] * s.heatmap[1])} TX–RX pairs"
            f" × {_ris_in_layout(s)} RISs, {grouped(s.heatmap[0])} RX points)"
        ),
        "use a smaller ris_count, a fixed heatmap_tx or a coarser rx_map",
        (_RIS_COUNT, _FIXED_HEATMAP_TX, _HEATMAP_RX),
    ),
    "elements": MemoryTerm(
        _element_bytes,
        lambda s: (
            f"the per-element arrays ({s.ris_side[0]} × {s.ris_side[1]} elements per"
            f" RIS, {s.wavefront} wavefront, {grouped(s.transmissions)} transmissions)"
        ),
        f"{_SMALLER_RIS} or fewer system.transmissions",
        (_RIS_SIDE,),
    ),
    "checks": MemoryTerm(
        _check_bytes,
        lambda s: (
            f"the codebook checks ({s.ris_side[0]} × {s.ris_side[1]} elements per RIS,"
            f" {grouped(min(s.pairs, RANDOM_CODEBOOK_PAIRS))} checked pairs)"
        ),
        _SMALLER_RIS,
        (_RIS_SIDE, _PAIRS),
    ),
}
"""The terms of a plan's memory estimate (:func:`plan_memory`), each with what its refusal
says (:class:`~ris_planner.model.limits.MemoryTerm`): ``base`` (interpreter and imports),
``maps``, ``pairs``, ``sites``, ``site cache`` (its :func:`cache_layout` and masks),
``district`` (the district search's sparse information, :data:`BYTES_PER_DISTRICT_ENTRY`), ``cache
build`` (one site's path information at a time), ``search`` (memoised layouts), ``heatmap``
(the largest count's ``compute_bounds`` on the heatmap pairs, and the per-point results; with
obstacles only the served pairs' RIS paths), ``relaxation`` (the relaxation bound of a count
searched greedily), ``sizing`` (a sizing run's own site cache), ``validation`` (the
estimator's candidate grid),
``elements`` (the per-element arrays: random-codebook profiles, spherical point terms and
chunks), ``checks`` (the codebook checks, which may run beside the heatmap:
:data:`BYTES_PER_CHECK_PAIR`, :data:`BYTES_PER_CHECK_ELEMENT`)."""


def plan_memory(shape: PlanShape) -> dict[str, int]:
    """Peak bytes of a plan run (plan, figures and GIS files in one process, as a service job
    runs it), term by term (:data:`PLAN_MEMORY_TERMS`); the estimate is their sum
    (docs/validation/resources.md)."""
    return memory_terms(PLAN_MEMORY_TERMS, shape)


def _memory(shape: PlanShape) -> int:
    return sum(plan_memory(shape).values())


def sizing_runs(doc: PlanDocument) -> int:
    """Enumerating plan runs the sizing question adds to a document's own (one per RIS size;
    0 without, or when the district search answers it)."""
    if doc.sizing is None or scoring_of(doc.sizing.method) == "sparse":
        return 0
    return len(doc.sizing.ris_sizes)


def plan_runs(doc: PlanDocument) -> int:
    """Plan runs of one document: its own, and one per size of the sizing question
    (:func:`ris_planner.planning.resources.admission.sizing_runs`; the runs are sequential, so they
    multiply the searched layouts, not the memory)."""

    return 1 + sizing_runs(doc)


def explain_plan_memory(shape: PlanShape, budget_bytes: int) -> str:
    """What drives a plan's memory estimate and what fits ``budget_bytes``
    (:func:`~ris_planner.model.limits.advise_memory` on :data:`PLAN_MEMORY_TERMS`) – "dominated
    by the site cache (52 sites × 20 000 pairs): 392 MiB; the largest pair count that fits is
    8 275" for a budget of 700 MiB (docs/validation/resources.md)."""
    return explain_memory(PLAN_MEMORY_TERMS, shape, budget_bytes)


def plan_shape(doc: PlanDocument, shares: tuple[float, float] | None = None) -> PlanShape:
    """The :class:`PlanShape` of a validated plan document (nothing is built but, for a district
    plan without ``shares``, the served-share sample: :func:`document_shares`)."""
    sites = plan_sites(doc)
    n_t, n_r = map_points(doc.tx_map), map_points(doc.rx_map)
    pairs = pairs_given(doc.pairs, n_t, n_r)
    counts = [c for c in doc.max_counts if c <= sites]
    relaxed = sum(not _exhaustive(doc, sites, c) for c in counts)
    district = sparse_search(doc)
    return PlanShape(
        sites=sites,
        tx_points=n_t,
        rx_points=n_r,
        pairs=min(pairs, doc.max_pairs),
        csv_rows=sum(csv_rows(m.csv_text or "") for m in (doc.tx_map, doc.rx_map)),
        layouts=_memo_layouts(doc, sites),
        counts=len(doc.max_counts),
        max_count=max(doc.max_counts),
        elements=doc.ris.rows * doc.ris.cols,
        ris_side=(doc.ris.rows, doc.ris.cols),
        transmissions=doc.system.transmissions,
        wavefront=doc.system.wavefront,
        fixed_heatmap_tx=doc.heatmap_tx is not None,
        district=district,
        pair_fields=local_pairs(doc.pairs),
        district_share=(document_shares(doc) if shares is None else shares)[1] if district else 0.0,
        district_sizes=len(doc.sizing_ris_sizes()) if district else 1,
        obstructed=doc.environment is not None and bool(doc.environment.obstacles),
        relaxed_counts=relaxed if doc.search.certificate_iterations > 0 else 0,
        sizing_runs=sizing_runs(doc),
        validation_candidates=0 if doc.validation is None else doc.validation.max_candidates,
    )


def largest_plan_shape(doc: PlanDocument, shares: tuple[float, float] | None = None) -> PlanShape:
    """The :func:`plan_shape` of the document's run that needs the most memory: its own, or one
    with another RIS size of ``sweep.ris_size`` or ``sizing.ris_sizes`` (those runs are
    sequential: the estimate is the largest one's)."""
    shape = plan_shape(doc, shares)
    sides = [tuple(rc) for rc in (doc.sweep.ris_size or [])] if doc.sweep is not None else []
    sides += [tuple(rc) for rc in doc.sizing.ris_sizes] if doc.sizing is not None else []
    shapes = [shape] + [replace(shape, ris_side=(r, c), elements=r * c) for r, c in sides]
    return max(shapes, key=_memory)


def estimate_plan(doc: PlanDocument, shares: tuple[float, float] | None = None) -> Sizes:
    """Every size of a plan run from its validated document (nothing is built); the memory is
    the sum of :func:`plan_memory` for its largest run (:func:`largest_plan_shape`; ``shares``:
    the document's :func:`document_shares` when the caller has them)."""
    shape = largest_plan_shape(doc, shares)
    n_t, n_r = shape.tx_points, shape.rx_points
    pairs = pairs_given(doc.pairs, n_t, n_r)
    heat_rx, heat_tx = shape.heatmap
    return Sizes(
        sites=shape.sites,
        tx_points=n_t,
        rx_points=n_r,
        pairs=pairs,
        cache_entries=0 if shape.district else shape.sites * pairs,
        heatmap_pairs=heat_rx * heat_tx,
        search_layouts=run_layouts(doc, shape.sites),
        memory_bytes=sum(plan_memory(shape).values()),
    )


@dataclass(frozen=True)
class Admitted:
    """A plan document admitted to run (:func:`admit`): validated and its search chosen
    (:func:`resolve_search`). What the estimates and the plan's inputs read of it is made once,
    when first needed: its UE maps (:attr:`maps`), candidate sites (:attr:`sites`), served
    shares (:attr:`shares`) and sizes (:attr:`sizes`, checked by :func:`admit`)."""

    document: PlanDocument
    """The document with ``search.method`` and ``sizing.method`` as they run (``auto``
    resolved to the district search where that is the choice)."""
    choice: MethodChoice
    sizing_choice: MethodChoice | None = None

    @cached_property
    def maps(self) -> tuple[PointMap, PointMap]:
        """(TX map, RX map) as the document gives them (before points inside obstacles are
        dropped)."""
        doc = self.document
        return build_map(doc.tx_map, "tx_map"), build_map(doc.rx_map, "rx_map")

    @cached_property
    def sites(self) -> list[Site]:
        """The candidate sites, expanded (:func:`~ris_planner.planning.inputs.sites.
        expand_sites`)."""
        return expand_sites(self.document)

    @cached_property
    def shares(self) -> tuple[float, float]:
        """:func:`~ris_planner.planning.resources.served.document_shares` of the document."""
        return document_shares(self.document, self.maps, self.sites)

    @cached_property
    def sizes(self) -> Sizes:
        """:func:`estimate_plan` of the document (its shares sampled only for a district
        plan, whose memory follows them)."""
        doc = self.document
        return estimate_plan(doc, self.shares if sparse_search(doc) else (0.0, 0.0))

    @cached_property
    def shape(self) -> PlanShape:
        """:func:`largest_plan_shape` of the document."""
        doc = self.document
        return largest_plan_shape(doc, self.shares if sparse_search(doc) else (0.0, 0.0))


def admit(document: PlanDocument | dict[str, Any], memory_mb: int | None = None) -> Admitted:
    """The one admission path of a plan document (the command line, the service's routes and
    its jobs, :func:`~ris_planner.planning.pipeline.run_plan`): the model, the candidate count
    against ``ris_count``, the search method (:func:`resolve_search`: what the method cannot
    honour is refused, naming the option), the sizes against their limits and the job memory
    budget (default ``RIS_PLANNER_JOB_MEMORY_MB``) and the validation's scatterers – each
    once."""
    doc = document if isinstance(document, PlanDocument) else PlanDocument.model_validate(document)
    sites = plan_sites(doc)
    if doc.ris_count is not None and max(doc.ris_count) > sites:
        raise DocumentFieldError(
            "ris_count",
            f"ris_count {max(doc.ris_count)} exceeds the {sites} candidate sites",
        )
    admitted = Admitted(*resolve_search(doc))
    check_sizes(
        admitted.sizes,
        max_pairs=admitted.document.max_pairs,
        memory_mb=budget_mb(memory_mb),
        explain=lambda budget: explain_plan_memory(admitted.shape, budget),
    )
    check_validation_scatterers(admitted)
    return admitted


def validate_plan(
    document: PlanDocument | dict[str, Any], memory_mb: int | None = None
) -> PlanDocument:
    """The admitted document (:func:`admit`): what ``run_plan`` accepts, ``auto`` resolved."""
    return admit(document, memory_mb).document


def plan_check(doc: PlanDocument, memory_mb: int | None = None) -> Sizes:
    """The sizes of an admitted plan document (:func:`admit`)."""
    return admit(doc, memory_mb).sizes


def _enumerating_overflow(doc: PlanDocument) -> str | None:
    """Why the enumerating searches cannot take the document (``auto`` then takes the district
    search): more RISs in a layout than they place, more layouts than the search limit over
    the plan and its sizing runs, or a site cache above its budget; ``None`` when they can."""
    largest = max(doc.max_counts)
    if largest > MAX_LAYOUT_RIS:
        return (
            f"{largest} RISs in a layout: the enumerating searches place at most {MAX_LAYOUT_RIS}"
        )
    sites = plan_sites(doc)
    layouts = run_layouts(doc, sites)
    if layouts > MAX_SEARCH_LAYOUTS:
        return (
            f"the enumerating searches would score {grouped(layouts)} layouts,"
            f" above the search limit of {grouped(MAX_SEARCH_LAYOUTS)}"
        )
    try:
        cache_layout(sites * _pairs_built(doc))
    except LimitExceededError as exc:
        return str(exc).split(";")[0]
    return None


def resolve_search(doc: PlanDocument) -> tuple[PlanDocument, MethodChoice, MethodChoice | None]:
    """The searches a document runs – the one place ``auto`` is resolved – and why: (the
    document with ``search.method`` and ``sizing.method`` as they run, the plan's choice, the
    sizing question's choice or ``None`` without ``sizing``).

    A method named in the document runs as named. ``auto`` runs the enumerating searches
    (:func:`~ris_planner.model.search_methods.count_method` per RIS count) unless they cannot
    take the plan (:func:`_enumerating_overflow`, the sizing runs aside) and the district
    search can; the sizing question keeps the plan's search where its runs fit too, else it
    takes the district search, and says why. What the method cannot plan or honour
    (:func:`~ris_planner.model.search_methods.method_refusals`) is refused before any work: a
    :class:`DocumentFieldError` naming the method and the option."""
    base = doc.model_copy(update={"sizing": None}) if doc.sizing is not None else doc
    method, choice = _resolve(doc, _enumerating_overflow(base))
    doc = _as_method(doc, method)
    if doc.sizing is None:
        return doc, choice, None
    asked = doc.sizing.method
    if asked != AUTO:
        _refuse(search_method(asked), _sizing_runs_document(doc, asked))
        sizing = MethodChoice(asked, asked, f"sizing.method {asked!r} in the document")
    elif scoring_of(method) == "sparse":
        sizing = MethodChoice(AUTO, method, f"the plan's own search ({choice.why})")
    else:
        overflow = _enumerating_overflow(doc)
        if overflow is None:
            sizing = MethodChoice(AUTO, AUTO, "the plan's own search: its runs fit at every size")
        else:
            sized, sizing = _resolve(_sizing_runs_document(doc, AUTO), overflow)
            if sized != AUTO:
                sizing = MethodChoice(AUTO, sized, f"{sizing.why}; the plan keeps its own search")
    spec = doc.sizing.model_copy(update={"method": sizing.used})
    return doc.model_copy(update={"sizing": spec}), choice, sizing


def _resolve(doc: PlanDocument, overflow: str | None) -> tuple[str, MethodChoice]:
    """(the method ``doc``'s ``search.method`` resolves to, the choice) given why the
    enumerating searches cannot take it (``overflow``, None when they can)."""
    requested = doc.search.method
    if requested != AUTO:
        _refuse(search_method(requested), doc)
        return requested, MethodChoice(requested, requested, f"search.method {requested!r}")
    if overflow is None:
        _refuse(search_method("exhaustive"), doc)
        why = (
            "auto: each RIS count searched exhaustively when it has at most"
            f" {grouped(doc.search.max_exhaustive)} layouts (search.max_exhaustive), else"
            " greedily"
        )
        return AUTO, MethodChoice(AUTO, AUTO, why)
    district = search_method("district")
    refusals = method_refusals(district, _as_method(doc, district.name))
    # auto's own settings for the enumerating searches do not bind the district search
    unused = [f for f, _ in refusals if f.startswith("search.")]
    refusals = [(f, m) for f, m in refusals if not f.startswith("search.")]
    if refusals:  # neither can: the enumerating searches' limits say why (check_sizes)
        if max(doc.max_counts) > MAX_LAYOUT_RIS:
            field, message = refusals[0]
            raise DocumentFieldError(field, f"{overflow}, and {message}")
        why = f"auto; {overflow} (the district search: {refusals[0][1]})"
        return AUTO, MethodChoice(AUTO, AUTO, why)
    why = f"auto: {overflow}"
    if unused:
        why += f" ({', '.join(unused)}: the enumerating searches' settings, not used)"
    return district.name, MethodChoice(AUTO, district.name, why)


def _sizing_runs_document(doc: PlanDocument, method: str) -> PlanDocument:
    """What the sizing question runs at each size: the document without the options only the
    plan itself takes (beams, validation, roll-out, sweep), with ``search.method`` ``method``."""
    bare = doc.model_copy(
        update={"beams": None, "validation": None, "rollout": "free", "sweep": None}
    )
    return _as_method(bare, method)


def _as_method(doc: PlanDocument, name: str) -> PlanDocument:
    """``doc`` with ``search.method`` set to ``name``, the other search fields as given."""
    search = doc.search.model_copy(update={"method": name})
    return doc.model_copy(update={"search": search})


def _refuse(method: SearchMethod, doc: PlanDocument) -> None:
    refusals = method_refusals(method, doc)
    if refusals:
        field, message = refusals[0]
        raise DocumentFieldError(field, message)


def _pairs_built(doc: PlanDocument) -> int:
    """The pairs a plan run builds (the sample, or every pair up to ``max_pairs``)."""
    n_t, n_r = map_points(doc.tx_map), map_points(doc.rx_map)
    pairs = pairs_given(doc.pairs, n_t, n_r)
    return min(pairs, doc.max_pairs)


def check_validation_scatterers(admitted: Admitted) -> None:
    """``validation.multipath``: no scatterer or cluster disk may come within
    :data:`~ris_planner.model.simulation.MIN_SCATTERER_DISTANCE_M` of a point of the TX or RX
    map (every point may be a sampled UE; docs/validation/estimator.md): a
    :class:`DocumentFieldError` naming the entry, the map and the point. Runs after the size
    checks (it builds the maps)."""
    doc = admitted.document
    spec = doc.validation
    if spec is None or not spec.multipath:
        return
    mp = Multipath.model_validate(spec.multipath)
    if not mp.scatterers and not mp.clusters:
        return
    tx_map, rx_map = admitted.maps
    maps = [("tx_map", tx_map)] + ([] if doc.rx_map == doc.tx_map else [("rx_map", rx_map)])
    for what, point_map in maps:
        points = point_map.points
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
