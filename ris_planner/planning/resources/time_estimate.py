"""Estimated seconds of a plan's stages: the plan's time estimate and the weights of honest
progress (:class:`ris_planner.runtime.progress.Stages`; docs/concepts/planning-physics.md,
"Progress").

:func:`stage_seconds` models each stage of the pipeline (the names of plan.json's
``timing_s``) from the sizes that drive it – sites, pairs, layouts searched, RIS elements and
first-block beams of the codebook checks, heatmap pairs, and for the spherical model the
per-element terms; :func:`plan_work` and :func:`report_work` group them into the progress
stages. Each stage's share of the bar is its estimate over the sum, so the bar moves at a
roughly even pace and reaches 100 % only when plan.json's figures and exports are written.

The model reads the plan's document (:class:`WorkSizes`: its sizes, nothing computed on
them) and a seeded sample of its visibility (:func:`served_share`), so the estimate exists
before any work: ``ris-planner plan`` prints it, a service plan job holds it from its
submission and plan.json keeps it beside what the run measured (:func:`plan_estimate`,
:func:`resources_json`). The constants are calibrated with ``python
benchmarks/resources/bench_memory.py --stages`` (one process per case, ``SerialExecutor``) so
that the estimate is within [0.8, 1.9] of the measured CPU time on its cases, and checked on
held-out real sites (``benchmarks/resources/bench_estimates.py``,
docs/validation/resources.md).
"""

from __future__ import annotations

import itertools
import math
import sys
import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from ris_planner.model.limits import HEATMAP_MAX_PAIRS, budget_mb, grouped
from ris_planner.model.plan import PlanDocument, local_pairs
from ris_planner.model.search_methods import count_method, sparse_search
from ris_planner.physics.codebooks import block_length
from ris_planner.planning.resources.admission import (
    Admitted,
    greedy_layouts,
    plan_shape,
)
from ris_planner.planning.resources.served import (
    document_shares,
    pair_served_share,
    served_share,
)

if TYPE_CHECKING:
    from typing import TypeAlias

    from ris_planner.planning.inputs.plan_inputs import PlanInputs

    Sized: TypeAlias = "PlanInputs | Admitted | PlanDocument | WorkSizes"
    """What the time model reads sizes from (:meth:`WorkSizes.of`)."""

CHECKS_HIDDEN_BY = ("sizing", "validation", "fields", "figures")
"""The stages that checks running beside them (:func:`checks_beside`) overlap: the checks'
thread starts after the search and is waited for after the figures."""

CHECKS_BESIDE_SHARE = 0.25
"""Of checks that run on their thread beside the fields and the figures (:func:`checks_beside`),
the share of the overlapped time that still lengthens the plan (the GIL and the core they
share): ``checks`` is estimated as the part the later stages do not hide plus this share of
the rest (docs/validation/resources.md)."""

MARGIN = 1.3
"""Every stage's model times this: the estimate stays above the measured time on a machine
somewhat busier than the calibration's (docs/validation/resources.md)."""

TIME_COEFFICIENTS: dict[str, dict[str, float]] = {
    "inputs": {"const": 0.025, "per_site": 9.27e-05},
    "visibility": {
        "const": 0.00195,
        "per_site_point": 2.22e-09,
        "per_site_point_obstructed": 8.49e-07,
    },
    "cache": {
        "const": 0.00909,
        "per_site_pair": 4.49e-07,
        "per_served_site_pair": 3.42e-07,
        "per_site_pair_element_spherical": 2.08e-08,
    },
    "search": {
        "per_count": 0.173,
        "per_layout_pair": 2.41e-08,
        "per_exhaustive_layout_pair": 1.53e-08,
        "per_served_layout_pair": 1.9e-07,
        "per_served_exhaustive_layout_pair": 8.16e-08,
        "per_rescored_site_pair": 4.78e-06,
    },
    "checks": {
        "per_codebook_mac": 5.8e-11,
        "per_served_codebook_mac": 9.41e-11,
        "per_checked_ris_pair": 0,
        "per_served_checked_ris_pair": 7.15e-06,
        "per_checked_ris_pair_element_spherical": 2.99e-07,
        "per_rescored_site_pair": 1.54e-06,
        "per_relaxation_site_pair": 3.06e-08,
    },
    "rollout": {"const": 0.00282, "per_layout_pair": 6.36e-08},
    "fields": {
        "per_ris_pair": 4.17e-07,
        "per_served_ris_pair": 8.56e-07,
        "per_ris_pair_element_spherical": 4.28e-09,
        "per_rx_point": 0.000381,
    },
    "report": {"const": 0.095, "per_pair": 0, "per_rx_point": 0, "per_rescored_site_pair": 3e-06},
    "figures": {"const": 0.759, "per_rx_point": 0.000208, "per_extra_figure": 0.243},
    "exports": {"const": 0.08, "per_rx_point": 3.95e-05},
    "sizing": {"per_run": 0, "per_modelled_s": 0.608},
    "validation": {"const": 0, "per_estimate": 0.000709, "per_served_estimate": 0.0265},
}
"""Seconds per unit of each size that drives a stage (:func:`stage_terms` names the sizes),
fitted to the per-stage CPU seconds of ``python benchmarks/resources/bench_memory.py --stages
--json F`` (the bench's ring cases, and ``--document`` runs of synthetic city grids and of the
shipped junction and hall, plain, with sizing, nested and validated) by ``python
benchmarks/resources/fit_time_model.py F … --cpu --low 0.8 --high 1.9``
(docs/validation/resources.md, "The time estimate per stage"); none of the real OpenStreetMap
sites, which are the held-out check (``benchmarks/resources/bench_estimates.py``). ``const``
once, ``per_count`` per RIS count, the rest per unit of the size of the same name.
``per_served_…`` terms are the same size times the served share (:func:`served_share`: the
work that follows the pairs a RIS serves – an open ring serves every pair, a city street a few
percent); ``…_element_spherical`` terms are the
spherical model's (its expected Gram and Jacobians sum over the N elements per pair),
``per_rescored_site_pair`` the float32 cache's float64 re-score of the reported layouts
(their sites × pairs, per count), ``per_relaxation_site_pair`` the Frank–Wolfe bound of each
count searched greedily (iterations × sites × pairs). ``sizing`` is per run of the sizing
question and per modelled second of those runs (:func:`sizing_runs_sizes`: each a search-only
plan at one RIS size, modelled with these coefficients), ``validation`` per estimator run
(pairs × draws × layouts), most of it per served one (a pair no RIS serves stops early).
The visibility walks each leg through the obstacles' grid: per site and UE point with any
obstacle (the walk's cells, whatever the obstacle count: 0.75–0.96 µs per site-point on the
five cities with 9–40 buildings), the hall's rate without (≤ 0.02 s on every case: below the
fit's floor)."""

BEAMS_PER_LAYOUT_S = 2.0
"""Beam design and power allocation per layout (the SDPs dominate)."""

_SERVED: dict[int, tuple[weakref.ref[PlanInputs], tuple[float, float]]] = {}
""":func:`_inputs_served` of prepared inputs, once per inputs object (the progress weights ask
for it several times per plan)."""


def _inputs_served(inputs: PlanInputs) -> tuple[float, float]:
    """(:func:`served_share`, :func:`pair_served_share` over the drawn pairs – the latter
    only for a district plan, else the former) of prepared inputs, once per inputs object."""
    key = id(inputs)
    hit = _SERVED.get(key)
    if hit is not None and hit[0]() is inputs:
        return hit[1]
    share = served_share(inputs.sites, inputs.tx_map, inputs.rx_map, inputs.scene)
    pairs = inputs.pairs
    by_pair = (
        pair_served_share(inputs.sites, pairs.tx, pairs.rx, pairs.weights, inputs.scene)
        if sparse_search(inputs.document)
        else share
    )
    for k in [k for k, (ref, _) in _SERVED.items() if ref() is None]:
        del _SERVED[k]
    _SERVED[key] = (weakref.ref(inputs), (share, by_pair))
    return share, by_pair


@dataclass(frozen=True)
class WorkSizes:
    """The sizes a plan's time is modelled from (:func:`stage_terms`): read from its validated
    document (:meth:`from_document`: the estimate printed before a plan starts and kept with a
    service job from its submission; the maps and candidate sites are expanded for the
    served-share sample, nothing is computed on them) or from its prepared inputs (:meth:`of`:
    the progress weights, the same model on the exact counts)."""

    document: PlanDocument
    sites: int
    pairs: int
    tx_points: int
    rx_points: int
    counts: tuple[int, ...]
    """The RIS counts searched (``ris_count``, or 1 … ``max_ris`` in target mode)."""
    elements: int
    """Elements per RIS (rows × cols)."""
    served: float = 1.0
    """The share of (pair, site) combinations with a RIS path (:func:`served_share`)."""
    pair_served: float = 1.0
    """The same share over the plan's own pairs (:func:`pair_served_share`; a district plan's,
    else :attr:`served`)."""

    @classmethod
    def of(cls, plan: Sized) -> WorkSizes:
        """The sizes of prepared inputs, of an admitted or a validated document, or
        themselves."""
        if isinstance(plan, WorkSizes):
            return plan
        if isinstance(plan, Admitted):
            return cls.from_document(plan.document, plan)
        if isinstance(plan, PlanDocument):
            return cls.from_document(plan)
        doc = plan.document
        return cls(
            doc,
            len(plan.sites),
            plan.pairs.size,
            len(plan.tx_map.points),
            len(plan.rx_map.points),
            tuple(plan.counts),
            doc.ris.rows * doc.ris.cols,
            *_inputs_served(plan),
        )

    @classmethod
    def from_document(cls, doc: PlanDocument, admitted: Admitted | None = None) -> WorkSizes:
        """The sizes of a validated document (the memory estimate's
        :func:`~ris_planner.planning.resources.admission.plan_shape`) and its served share (its
        sites and maps expanded, :func:`served_share`; an admitted document's own, made
        once)."""
        share, by_pair = document_shares(doc) if admitted is None else admitted.shares
        shape = plan_shape(doc, (share, by_pair))
        counts = doc.max_counts
        if doc.ris_count is None:  # target mode: at most every candidate (prepare_plan's rule)
            counts = [c for c in counts if c <= shape.sites]
        return cls(
            doc,
            shape.sites,
            shape.pairs,
            shape.tx_points,
            shape.rx_points,
            tuple(counts),
            shape.elements,
            share,
            by_pair,
        )


def searched_exhaustively(plan: Sized, count: int) -> bool:
    """Whether the search for ``count`` RISs is exhaustive (``auto`` within
    ``max_exhaustive`` layouts)."""
    w = WorkSizes.of(plan)
    s = w.document.search
    return count_method(s.method, math.comb(w.sites, count), s.max_exhaustive) == "exhaustive"


def search_layouts(plan: Sized, count: int) -> float:
    """Layouts the search for ``count`` RISs evaluates (all of them when exhaustive)."""
    w = WorkSizes.of(plan)
    s = w.document.search
    total = math.comb(w.sites, count)
    if searched_exhaustively(w, count):
        return total
    seeds = sum(c < count for c in w.counts)  # the smaller counts' best layouts
    return min(total, greedy_layouts(w.sites, count, s.restarts, s.max_rounds, seeds))


def heatmap_pairs(plan: Sized) -> int:
    """TX × RX pairs of the per-point bounds
    (:func:`~ris_planner.planning.outputs.rx_fields.rx_fields`); none where the fields come
    from the plan's own pairs (:func:`~ris_planner.model.plan.local_pairs`)."""
    w = WorkSizes.of(plan)
    if local_pairs(w.document.pairs):
        return 0
    n_rx = min(w.rx_points, HEATMAP_MAX_PAIRS)
    n_tx = 1 if w.document.heatmap_tx is not None else w.tx_points
    return min(n_tx * n_rx, max(HEATMAP_MAX_PAIRS, n_rx))


def codebook_macs(plan: Sized, count: int) -> float:
    """Complex multiply-adds of one ``random``-codebook evaluation of a ``count``-RIS layout:
    per RIS the first block's 3·G̃ derivative-weighted profiles times the N-element steering
    vectors of every checked pair (:func:`ris_planner.physics.fim.planar_transmission_gram`)."""
    from ris_planner.planning.certify.checks import RANDOM_CODEBOOK_MAX_PAIRS

    w = WorkSizes.of(plan)
    pairs = min(w.pairs, RANDOM_CODEBOOK_MAX_PAIRS)
    try:
        g_tilde = block_length(w.document.system.transmissions, count)
    except ValueError:  # G < L+1: the document's check refuses it before any work
        g_tilde = 1
    return float(count * 3 * g_tilde * w.elements * pairs)


def validation_estimates(plan: Sized) -> float:
    """Estimator runs of the document's ``validation``: its pairs × draws on each count's best
    layout (:func:`ris_planner.planning.outputs.estimator_check.run_estimator_check`); 0 without."""
    w = WorkSizes.of(plan)
    spec = w.document.validation
    if spec is None:
        return 0.0
    return float(spec.pairs * spec.draws * max(len(w.counts), 1))


def sizing_runs_sizes(plan: Sized) -> list[WorkSizes]:
    """The sizes of each run of the sizing question (one per RIS size of ``sizing.ris_sizes``,
    sequential, each a search-only plan over the same candidates and pairs: its counts are
    ``sizing.counts``, else ``ris_count``, else 1 … ``max_ris``); none without ``sizing``.
    Every size is counted: a size that cannot beat the answer found is skipped at run time,
    which the estimate cannot know."""
    w = WorkSizes.of(plan)
    sizing = w.document.sizing
    if sizing is None:
        return []
    counts = sizing.counts if sizing.counts is not None else w.document.ris_count
    if counts is None:
        counts = [c for c in range(1, w.document.max_ris + 1) if c <= w.sites]
    return [replace(w, counts=tuple(counts), elements=r * c) for r, c in sizing.ris_sizes]


SEARCH_STAGES = ("inputs", "visibility", "cache", "search", "checks", "rollout")
"""The stages of one search-only plan run (:func:`~ris_planner.planning.pipeline.plan_once`):
a sizing run's (:func:`sizing_runs_sizes`)."""


def _modelled(terms: dict[str, dict[str, float]], stages: tuple[str, ...]) -> float:
    return sum(TIME_COEFFICIENTS[st][t] * v for st in stages for t, v in terms[st].items())


def stage_terms(plan: Sized) -> dict[str, dict[str, float]]:
    """The sizes that drive each stage's time, by the names of :data:`TIME_COEFFICIENTS`."""
    w = WorkSizes.of(plan)
    terms = _run_terms(w)
    runs = [_run_terms(s) for s in sizing_runs_sizes(w)]
    terms["sizing"] = {
        "per_run": float(len(runs)),
        "per_modelled_s": sum(_modelled(t, SEARCH_STAGES) for t in runs),
    }
    n_est = validation_estimates(w)
    terms["validation"] = {
        "const": float(n_est > 0),
        "per_estimate": n_est,
        "per_served_estimate": w.served * n_est,
    }
    return terms


def _run_terms(w: WorkSizes) -> dict[str, dict[str, float]]:
    """:func:`stage_terms` of one plan run, without the sizing and validation stages."""
    from ris_planner.model.limits import cache_layout
    from ris_planner.planning.certify.checks import RANDOM_CODEBOOK_MAX_PAIRS, RANDOM_CODEBOOK_SEEDS
    from ris_planner.planning.search.rollout import chain_is_cheap

    doc = w.document
    n_sites, n_pairs = w.sites, w.pairs
    counts = list(w.counts)
    n_el = w.elements
    wave = doc.system.wavefront
    sph = float(n_el if wave == "spherical" else 0)
    planar = float(wave != "spherical")
    f = w.served
    n_points = w.tx_points + w.rx_points
    n_heat = heatmap_pairs(w)
    n_rx = min(w.rx_points, n_heat or HEATMAP_MAX_PAIRS)
    obstacles = 0 if doc.environment is None else len(doc.environment.obstacles)
    checked = (1 + RANDOM_CODEBOOK_SEEDS) * sum(counts) * min(n_pairs, RANDOM_CODEBOOK_MAX_PAIRS)
    try:
        float32 = cache_layout(n_sites * n_pairs, wave).storage == "float32"
    except ValueError:  # above every tier: the guard refuses the plan before any work
        float32 = False
    # a float32 cache re-scores the reported layouts in float64: their sites × the pairs
    rescored = (
        float(sum(min(n_sites, doc.search.top_k * c) for c in counts) * n_pairs) if float32 else 0.0
    )
    ris_hm = float(sum(counts) * n_heat)
    exhaustive = {c: searched_exhaustively(w, c) for c in counts}
    greedy_lp = float(sum(search_layouts(w, c) for c in counts if not exhaustive[c]) * n_pairs)
    exhaustive_lp = float(sum(search_layouts(w, c) for c in counts if exhaustive[c]) * n_pairs)
    # the nested chain: searched with rollout "nested", and in free mode when it is cheap
    chain = sum(
        min(math.comb(n_sites - a, b - a), doc.search.max_exhaustive)
        for a, b in itertools.pairwise(counts)
    )
    if doc.rollout != "nested" and not chain_is_cheap(
        n_sites, counts, doc.search.max_exhaustive, n_pairs, greedy_lp + exhaustive_lp
    ):
        chain = 0
    # the relaxation bound of each count searched greedily (Frank–Wolfe over sites × pairs)
    relaxed = sum(not exhaustive[c] for c in counts)
    macs = RANDOM_CODEBOOK_SEEDS * sum(codebook_macs(w, c) for c in counts)
    return {
        "inputs": {"const": 1.0, "per_site": n_sites},
        "visibility": {
            "const": 1.0,
            "per_site_point": n_sites * n_points,
            "per_site_point_obstructed": n_sites * n_points * float(obstacles > 0),
        },
        "cache": {
            "const": 1.0,
            "per_site_pair": planar * n_sites * n_pairs,
            "per_served_site_pair": planar * f * n_sites * n_pairs,
            "per_site_pair_element_spherical": sph * n_sites * n_pairs,
        },
        "search": {
            "per_count": len(counts),
            "per_layout_pair": greedy_lp,
            "per_served_layout_pair": f * greedy_lp,
            "per_exhaustive_layout_pair": exhaustive_lp,
            "per_served_exhaustive_layout_pair": f * exhaustive_lp,
            "per_rescored_site_pair": rescored,
        },
        "checks": {
            "per_codebook_mac": planar * macs,
            "per_served_codebook_mac": planar * f * macs,
            "per_checked_ris_pair": planar * checked,
            "per_served_checked_ris_pair": planar * f * checked,
            "per_checked_ris_pair_element_spherical": sph * checked,
            "per_rescored_site_pair": rescored,
            "per_relaxation_site_pair": float(
                relaxed * doc.search.certificate_iterations * n_sites * n_pairs
            ),
        },
        "rollout": {"const": 1.0, "per_layout_pair": float(chain * n_pairs)},
        "fields": {
            "per_ris_pair": planar * ris_hm,
            "per_served_ris_pair": planar * f * ris_hm,
            "per_ris_pair_element_spherical": sph * ris_hm,
            "per_rx_point": n_rx,
        },
        "report": {
            "const": 1.0,
            "per_pair": n_pairs,
            "per_rx_point": n_rx,
            "per_rescored_site_pair": rescored,
        },
        "figures": {
            "const": 1.0,
            "per_rx_point": n_rx,
            "per_extra_figure": float(
                (doc.beams is not None)
                + (doc.sweep is not None)
                + (doc.sizing is not None)
                + (doc.validation is not None)
            ),
        },
        "exports": {"const": 1.0, "per_rx_point": n_rx},
    }


def checks_beside(plan: Sized) -> bool:
    """Whether the plan's checks will run on a thread beside the fields and the figures
    (:class:`ris_planner.planning.certify.checks.PendingChecks`): every count is searched
    exhaustively
    (so no relaxation bound is deferred to the checks) and in this process (no worker pool at
    this machine's core count: :func:`ris_planner.planning.prepare.needs_workers`' rule)."""
    import os

    from ris_planner.planning.search.layouts import MIN_TASK_MATRICES

    w = WorkSizes.of(plan)
    spec = w.document.search
    if not all(searched_exhaustively(w, c) for c in w.counts):
        return False
    workers = os.cpu_count() or 1
    per_count = [min(math.comb(w.sites, c), spec.max_exhaustive) * w.pairs for c in w.counts]
    splits = max(per_count, default=0) >= workers * MIN_TASK_MATRICES
    return not (workers > 1 and splits and sum(per_count) >= spec.pool_min_work)


def stage_seconds(plan: Sized) -> dict[str, float]:
    """Estimated seconds of each stage of :func:`~ris_planner.planning.pipeline.run_plan` and
    of the outputs (plan.json ``timing_s`` names): :data:`TIME_COEFFICIENTS` times
    :func:`stage_terms`, :data:`MARGIN` included; checks that run beside the later stages
    (:func:`checks_beside`) count only what those do not hide (:data:`CHECKS_BESIDE_SHARE`).
    A district plan (``search.method`` 'district') has its own stages
    (:func:`district_seconds`)."""
    w = WorkSizes.of(plan)
    doc = w.document
    if sparse_search(doc):
        return district_seconds(w)
    work = {
        stage: sum(TIME_COEFFICIENTS[stage][term] * size for term, size in sizes.items())
        for stage, sizes in stage_terms(w).items()
    }
    if doc.beams is not None:
        work["beams"] = BEAMS_PER_LAYOUT_S * (len(w.counts) + len(doc.beams.layouts))
    if checks_beside(w):
        hidden = min(work["checks"], sum(work[st] for st in CHECKS_HIDDEN_BY))
        work["checks"] -= (1.0 - CHECKS_BESIDE_SHARE) * hidden
    return {k: MARGIN * v for k, v in work.items()}


DISTRICT_COEFFICIENTS: dict[str, dict[str, float]] = {
    "inputs": {"const": 0.6, "per_site": 1.5e-4},
    "search_main": {
        "per_entry_size": 2.5e-6,
        "per_designed_entry_size": 7.5e-6,
        "per_near_element_size": 2.3e-8,
        "per_designed_near_element_size": 1.05e-7,
        "per_site_size": 7.5e-4,
        "per_path_rescore": 3.9e-7,
        "per_swap_rescore": 7e-7,
    },
    # a large solve 6e-6 (8e-6 before the parallel dual simplex: docs/validation/resources.md)
    "search_lp": {"per_lp_row_entry": 1.8e-6, "per_large_solve_row_entry": 6e-6},
    "beams": {"per_layout": 15.0, "per_ris": 0.7},
    "figures": {"const": 1.0, "per_pair": 5e-4},
    "fields": {"per_pair": 2e-6},
    "report": {"per_pair": 2e-6},
    "exports": {"per_pair": 2e-6},
}
"""Seconds per unit of the district search's work (:func:`district_terms` names the sizes),
fitted by hand to the phases of district plans on the Helsinki district of
``benchmarks/district/bench_district.py`` and ``bench_district_physics.py``
(docs/validation/resources.md, "District plans"). ``search_main`` is the main thread: each RIS
size's (pair, serving site) entries and candidates (the information and its visibility; a
designed codebook's blocks and, with the spherical wavefront, the exact per-element response
of the entries inside the Fraunhofer distance, per entry and element), the greedy path's and
the swaps' re-scores (per site placed or swapped, the search's entries of the pairs that site
serves; with ``sizing`` also the descent's swap passes below each size's answer,
:data:`~ris_planner.planning.search.district.SIZING_PROBES` of at most the most RISs a layout
takes); ``search_lp`` the relaxations on the thread beside it, per entry plus
:data:`DISTRICT_LP_ROWS_PER_PAIR` per pair: a small model per LP (one per RIS count, a lower
bound per RIS size of the sizing, which costs :data:`DISTRICT_LOWER_BOUND_LPS` of them), a
large one (:data:`~ris_planner.planning.certify.district_lp.SIMPLEX_MAX_NONZEROS`) per solve –
its first :data:`~ris_planner.planning.certify.district_lp.LARGE_SOLVES` counts, each solved
and solved again after each round of separated cuts (as many as
:data:`~ris_planner.planning.certify.district_lp.SEPARATION_NONZEROS` over the model's
nonzeros allow; a round modelled as long as a solve); ``beams``
(``beams`` set) per layout (its γ_P search and coverage under each allocation) and per RIS
(its SDP and its positions' information, a worker's seconds: shared by the plan's pool from
:data:`~ris_planner.planning.beams.SDP_POOL_MIN_RIS` RISs on); the figures per
pair."""

DISTRICT_LOWER_BOUND_LPS = 1.8
"""A sizing lower bound (min Σ z) costs this many coverage relaxations (measured 1.8 on the
Helsinki district)."""

DISTRICT_LP_ROWS_PER_PAIR = 60
"""Per pair, the relaxation's cost in entries beyond its serving sites (its rows, its cover
sets)."""

DISTRICT_NONZEROS_PER_PAIR = 50
"""The relaxation's nonzeros per pair, at least (50–191 on the Helsinki district's plans of
500 and 2122 candidates, 5 000 and 20 000 pairs): above
:data:`~ris_planner.planning.certify.district_lp.SIMPLEX_MAX_NONZEROS` the model is a large
one."""

DISTRICT_OVERLAP = 0.5
"""The search is the longer of its main thread and its relaxations' thread plus this share of
the shorter (two cores, the GIL and memory bandwidth shared)."""

DISTRICT_LOOKAHEAD_STEPS = 40
"""Re-scores of site placements a greedy path's first steps add (they try sites in pairs while
coverage needs two sites placed together)."""


def district_terms(plan: Sized) -> dict[str, dict[str, float]]:
    """The sizes of a district plan's work (:data:`DISTRICT_COEFFICIENTS`): the (pair, serving
    site) entries E = pairs × sites × :attr:`WorkSizes.pair_served`, the search's entries per
    pair K = min(:data:`~ris_planner.planning.search.district.SEARCH_SITES`, E / pairs) and a
    site's re-score K² · pairs / sites; with a target or sizing each RIS size's greedy path runs
    up to :func:`~ris_planner.planning.search.district.most_ris` (it stops at the target, which
    the estimate cannot know)."""
    from ris_planner.planning.certify.district_lp import (
        LARGE_SOLVES,
        SIMPLEX_MAX_NONZEROS,
        separation_rounds,
    )
    from ris_planner.planning.search.district import (
        SEARCH_SITES,
        SIZING_PROBES,
        SMALL_DISTRICT_SITES,
        most_ris,
    )

    w = WorkSizes.of(plan)
    doc = w.document
    n_sites, n_pairs = max(w.sites, 1), max(w.pairs, 1)
    counts = [c for c in w.counts if c <= n_sites] or [1]
    entries = w.pair_served * n_sites * n_pairs
    per_pair = min(float(SEARCH_SITES), entries / n_pairs)
    rescore = per_pair * per_pair * n_pairs / n_sites
    target = doc.sizing is not None or doc.objective.target is not None
    sizes = len(doc.sizing_ris_sizes())
    most = most_ris(doc.system.transmissions)
    longest = min(max(max(counts), most) if target else max(counts), n_sites)
    path = longest + (sizes - 1) * min(most, n_sites) if target else longest
    swaps = sum(counts) * (6 if n_sites <= SMALL_DISTRICT_SITES else 1)
    if doc.sizing is not None:  # the sizing's descent: swap passes below each size's answer
        swaps += SIZING_PROBES * sizes * min(most, n_sites)
    lp_units = entries + DISTRICT_LP_ROWS_PER_PAIR * n_pairs
    nonzeros = n_pairs * DISTRICT_NONZEROS_PER_PAIR
    if nonzeros > SIMPLEX_MAX_NONZEROS:
        # the plan's counts up to LARGE_SOLVES and the lower bound of every RIS size of the
        # sizing, each solved and solved again after each round of separated cuts
        solves = min(len(counts), LARGE_SOLVES) + (sizes if target else 0)
        small_lps, large_solves = 0.0, solves * (1.0 + separation_rounds(nonzeros))
    else:
        small_lps = len(counts) + (DISTRICT_LOWER_BOUND_LPS * sizes if target else 0.0)
        large_solves = 0.0
    designed = doc.codebook.kind != "expected_random"
    near = entries * w.elements * sizes if doc.system.wavefront == "spherical" else 0.0
    terms: dict[str, dict[str, float]] = {
        "inputs": {"const": 1.0, "per_site": float(n_sites)},
        "search_main": {
            "per_entry_size": entries * sizes,
            "per_designed_entry_size": entries * sizes if designed else 0.0,
            "per_near_element_size": 0.0 if designed else near,
            "per_designed_near_element_size": near if designed else 0.0,
            "per_site_size": float(n_sites * sizes),
            "per_path_rescore": rescore * (path + DISTRICT_LOOKAHEAD_STEPS * sizes),
            "per_swap_rescore": rescore * swaps,
        },
        "search_lp": {
            "per_lp_row_entry": lp_units * small_lps,
            "per_large_solve_row_entry": lp_units * large_solves,
        },
        "figures": {"const": 1.0, "per_pair": float(n_pairs)},
        "fields": {"per_pair": float(n_pairs) * len(counts)},
        "report": {"per_pair": float(n_pairs) * len(counts)},
        "exports": {"per_pair": float(n_pairs) * len(counts)},
    }
    if doc.beams is not None:
        import os

        from ris_planner.planning.beams import SDP_POOL_MIN_RIS

        # the per-RIS SDPs of a layout of SDP_POOL_MIN_RIS or more run on the plan's pool, one
        # worker per core
        pool = max(1, os.cpu_count() or 1)
        layouts = [*counts, *(len(lay) for lay in doc.beams.layouts)]
        rises = sum(n / pool if n >= SDP_POOL_MIN_RIS else n for n in layouts)
        terms["beams"] = {"per_layout": float(len(layouts)), "per_ris": float(rises)}
    return terms


def district_seconds(plan: Sized) -> dict[str, float]:
    """Estimated seconds of a district plan's stages (plan.json ``timing_s``: ``inputs``,
    ``search``, ``figures``, with ``beams`` its ``beams``), :data:`MARGIN` included; the
    search's two threads overlap (:data:`DISTRICT_OVERLAP`)."""
    part = {
        stage: sum(DISTRICT_COEFFICIENTS[stage][t] * v for t, v in sizes.items())
        for stage, sizes in district_terms(plan).items()
    }
    main, lp = part.pop("search_main"), part.pop("search_lp")
    part["search"] = max(main, lp) + DISTRICT_OVERLAP * min(main, lp)
    # the enumerating searches' stages that a district plan does not have: none of its time
    part |= {stage: 0.0 for stage in ("visibility", "cache", "checks", "rollout")}
    return {stage: MARGIN * value for stage, value in part.items()}


def time_estimate(plan: Sized) -> float:
    """The plan's estimated wall time [s] (the sum of :func:`stage_seconds`): within
    [0.5, 2] of the measured time on the calibration cases and the held-out real sites
    (docs/validation/resources.md)."""
    return sum(stage_seconds(plan).values())


def plan_work(plan: Sized) -> dict[str, float]:
    """Estimated seconds of :func:`~ris_planner.planning.pipeline.plan_once`'s progress stages:
    ``cache`` (visibility and site cache), ``search``, ``checks``, ``rollout`` (the nested
    chain) and (with ``beams``) ``beams``."""
    est = stage_seconds(plan)
    work = {
        "cache": est["visibility"] + est["cache"],
        "search": est["search"],
        "checks": est["checks"],
        "rollout": est["rollout"],
    }
    if "beams" in est:
        work["beams"] = est["beams"]
    return work


def report_work(plan: Sized) -> dict[str, float]:
    """Estimated seconds after the search: ``fields`` (every count's per-point bounds),
    ``report`` (the diagnosis, the summary and plan.json), ``figures`` and ``exports``
    (:func:`ris_planner.io.geoplan.plan_document`)."""
    est = stage_seconds(plan)
    return {k: est[k] for k in ("fields", "report", "figures", "exports")}


@dataclass(frozen=True)
class PlanEstimate:
    """A plan's resources, estimated from its document before any work: the wall time
    (:func:`time_estimate`) and the peak resident memory
    (:func:`~ris_planner.planning.resources.admission.estimate_plan`), with the job memory budget
    it is
    checked against – what ``ris-planner plan`` prints before it plans, a service plan job
    holds from its submission (``estimate``) and plan.json keeps (``resources``)."""

    time_s: float
    memory_mib: float
    budget_mib: int
    seconds: float = 0.0
    """How long making the estimate took (plan.json ``timing_s["estimate"]``)."""

    def to_json(self) -> dict[str, float | int]:
        """``{"time_s", "memory_mib", "budget_mib"}`` (plan.json ``resources.estimate``)."""
        return {
            "time_s": round(self.time_s, 3),
            "memory_mib": round(self.memory_mib, 1),
            "budget_mib": self.budget_mib,
        }

    def describe(self) -> str:
        """``≈ 1.2 s, ≈ 620 MiB peak (budget 6 144 MiB)``."""
        return (
            f"≈ {seconds_text(self.time_s)}, ≈ {grouped(round(self.memory_mib))} MiB peak"
            f" (budget {grouped(self.budget_mib)} MiB)"
        )


def seconds_text(seconds: float) -> str:
    """A duration as people read it: ``0.84 s``, ``12 s``, ``3 min 20 s``."""
    if seconds < 10:
        return f"{seconds:.2g} s" if seconds < 1 else f"{seconds:.1f} s"
    if seconds < 120:
        return f"{round(seconds)} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest} s" if minutes < 60 else f"{minutes // 60} h {minutes % 60} min"


def plan_estimate(plan: Admitted | PlanDocument, memory_mb: int | None = None) -> PlanEstimate:
    """The :class:`PlanEstimate` of an admitted plan (its sizes as admitted; a validated
    document is admitted first): the budget is ``memory_mb``, else
    ``RIS_PLANNER_JOB_MEMORY_MB``."""
    from ris_planner.planning.resources.admission import admit

    admitted = plan if isinstance(plan, Admitted) else admit(plan, memory_mb)
    return PlanEstimate(
        time_estimate(admitted),
        admitted.sizes.memory_bytes / 2**20,
        budget_mb(memory_mb),
    )


def peak_memory_mib() -> float:
    """This process's peak resident memory so far [MiB]: Linux's ``VmHWM`` of
    ``/proc/self/status`` – the high-water mark of this program's own memory since it was
    started – else ``getrusage``'s ``ru_maxrss`` (0 where neither is available). Not
    ``ru_maxrss`` on Linux: it survives ``exec``, so a plan started from a large process (a
    test runner of 1.1 GB) reported its parent's size at the fork as its own peak."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource
    except ImportError:  # not POSIX
        return 0.0
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kib / 1024 if sys.platform != "darwin" else kib / 2**20


def resources_json(estimate: PlanEstimate, seconds: float) -> dict[str, dict[str, float | int]]:
    """plan.json ``resources``: the estimate made before the run and what the run measured
    (``time_s``: wall seconds from the estimate to plan.json's content; ``peak_memory_mib``:
    the peak resident memory of the run's process, :func:`peak_memory_mib`)."""
    return {
        "estimate": estimate.to_json(),
        "measured": {"time_s": round(seconds, 3), "peak_memory_mib": round(peak_memory_mib(), 1)},
    }
