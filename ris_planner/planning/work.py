"""Estimated seconds of a plan's stages: the plan's time estimate and the weights of honest
progress (:class:`ris_planner.runtime.progress.Stages`; docs/concepts/planning-physics.md,
"Progress").

:func:`stage_seconds` models each stage of the pipeline (the names of plan.json's
``timing_s``) from the sizes that drive it – sites, pairs, layouts searched, RIS elements and
first-block beams of the codebook checks, heatmap pairs, and for the spherical model the
per-element terms; :func:`plan_work` and :func:`report_work` group them into the progress
stages. Each stage's share of the bar is its estimate over the sum, so the bar moves at a
roughly even pace and reaches 100 % only when plan.json's figures and exports are written.

The constants are calibrated with ``python benchmarks/bench_memory.py --stages`` (one process
per case, ``SerialExecutor``) so that the estimate is never below the measured time and within
2× of it on its cases (docs/validation/resources.md), with :data:`MARGIN` for a loaded machine.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

from ris_planner.physics.codebooks import block_length
from ris_planner.planning.resources import HEATMAP_MAX_PAIRS

if TYPE_CHECKING:
    from ris_planner.planning.inputs import PlanInputs

MARGIN = 1.3
"""Every stage's model times this: the estimate stays above the measured time on a machine
somewhat busier than the calibration's (docs/validation/resources.md)."""

INPUTS_S = 0.02
INPUTS_PER_POINT_S = 2e-5
"""Inputs: the document checked, sites and maps built, pairs drawn – per UE map point."""

VISIBILITY_PER_SITE_POINT_S = 2e-6
VISIBILITY_PER_OBSTACLE = 0.01
"""Visibility: a leg per (site, UE point), each walk longer with more obstacles."""

SPHERICAL_PER_ELEMENT = 0.16
SPHERICAL_EXPONENT = 0.75
"""The spherical model's per-pair cost grows with the RIS elements N (its expected Gram and
Jacobians sum over them, beside fixed per-pair work): a per-pair term costs
1 + 0.16 · N^0.75 planar ones (≈ 6 at 10 × 10, ≈ 83 at 64 × 64)."""

CACHE_S = 0.02
CACHE_PER_SITE_PAIR_S = 1.5e-6
"""Site cache: fixed cost plus per (site, pair)."""

ROLLOUT_S = 0.02
"""The rollout stage's fixed cost (the nested chain's layouts are search work)."""

SEARCH_S = 0.3
SEARCH_PER_LAYOUT_PAIR_S = 3e-7
"""Search per RIS count: fixed cost plus per (evaluated layout, pair) – hall: 0.84 s for
6 600 layouts × 400 pairs."""

CHECKS_PER_COUNT_S = 0.05
CODEBOOK_PER_MAC_S = 2e-10
CHECK_PER_RIS_PAIR_S = 5e-6
FRANK_WOLFE_PER_SITE_PAIR_S = 1e-7
"""Checks: per count the ``random``-codebook evaluations (:func:`codebook_macs` complex
multiply-adds each, one per seed) and ``compute_bounds`` on the checked pairs (per RIS and
pair, the expected-random one included); a relaxation bound costs iterations × sites ×
pairs."""

BEAMS_PER_LAYOUT_S = 2.0
"""Beam design and power allocation per layout (the SDPs dominate)."""

FIELD_S = 0.02
FIELD_PER_RIS_PAIR_S = 4e-6
"""Per-point bounds of one count's best layout (heatmap, ``points``): compute_bounds over the
heatmap's TX × RX pairs, per RIS and pair (the visibility decided once per point)."""

REPORT_S = 0.05
REPORT_PER_LAYOUT_S = 0.005
"""The diagnosis, the summary (statistics of every ranked layout: top_k per count) and
plan.json's formatting."""

FIGURES_S = 1.5
FIGURE_EXTRA_S = 0.5
"""The three figures (top view, heatmap, CDF), with matplotlib's first import; beams and
sweep figures each more."""

EXPORTS_S = 0.2
EXPORTS_PER_POINT_S = 1e-5
"""GIS files (GeoJSON, GeoTIFF, points CSV): small, ∝ the heatmap points."""


def greedy_layouts(n_sites: int, count: int, restarts: int, rounds: int) -> int:
    """Layouts a greedy search evaluates, roughly: the greedy build (count × sites) and, per
    start, a few swap rounds over count × (sites − count) neighbours (3 rounds: typical)."""
    swaps = count * max(n_sites - count, 0)
    return count * n_sites + (restarts + 1) * min(rounds, 3) * swaps


def search_layouts(inputs: PlanInputs, count: int) -> int:
    """Layouts the search for ``count`` RISs evaluates (all of them when exhaustive)."""
    s = inputs.document.search
    n = len(inputs.sites)
    total = math.comb(n, count)
    exhaustive = s.method == "exhaustive" or (s.method == "auto" and total <= s.max_exhaustive)
    if exhaustive:
        return total
    return min(total, greedy_layouts(n, count, s.restarts, s.max_rounds))


def heatmap_pairs(inputs: PlanInputs) -> int:
    """TX × RX pairs of the per-point bounds (:func:`~ris_planner.planning.fields.rx_fields`)."""
    doc = inputs.document
    n_rx = min(len(inputs.rx_map.points), HEATMAP_MAX_PAIRS)
    n_tx = 1 if doc.heatmap_tx is not None else len(inputs.tx_map.points)
    return min(n_tx * n_rx, max(HEATMAP_MAX_PAIRS, n_rx))


def codebook_macs(inputs: PlanInputs, count: int) -> float:
    """Complex multiply-adds of one ``random``-codebook evaluation of a ``count``-RIS layout:
    per RIS the first block's 3·G̃ derivative-weighted profiles times the N-element steering
    vectors of every checked pair (:func:`ris_planner.physics.fim.planar_transmission_gram`)."""
    from ris_planner.planning.checks import RANDOM_CODEBOOK_MAX_PAIRS

    doc = inputs.document
    n_el = doc.ris.rows * doc.ris.cols
    pairs = min(inputs.pairs.size, RANDOM_CODEBOOK_MAX_PAIRS)
    try:
        g_tilde = block_length(doc.system.transmissions, count)
    except ValueError:  # G < L+1: the document's check refuses it before any work
        g_tilde = 1
    return float(count * 3 * g_tilde * n_el * pairs)


def stage_seconds(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds of each stage of :func:`~ris_planner.planning.pipeline.run_plan` and
    of the outputs (plan.json ``timing_s`` names), :data:`MARGIN` included."""
    from ris_planner.planning.checks import RANDOM_CODEBOOK_MAX_PAIRS, RANDOM_CODEBOOK_SEEDS

    doc = inputs.document
    n_sites, n_pairs = len(inputs.sites), inputs.pairs.size
    counts = inputs.counts
    n_el = doc.ris.rows * doc.ris.cols
    spherical = doc.system.wavefront == "spherical"
    # the spherical model's expected Gram and Jacobians sum over the elements per pair
    per_pair = 1.0 + SPHERICAL_PER_ELEMENT * n_el**SPHERICAL_EXPONENT if spherical else 1.0
    n_points = len(inputs.tx_map.points) + len(inputs.rx_map.points)
    obstacles = 0 if doc.environment is None else len(doc.environment.obstacles)
    check_pairs = min(n_pairs, RANDOM_CODEBOOK_MAX_PAIRS)
    checks = sum(
        CHECKS_PER_COUNT_S
        + CODEBOOK_PER_MAC_S * RANDOM_CODEBOOK_SEEDS * codebook_macs(inputs, c)
        + CHECK_PER_RIS_PAIR_S * (1 + RANDOM_CODEBOOK_SEEDS) * c * check_pairs * per_pair
        for c in counts
    )
    checks += FRANK_WOLFE_PER_SITE_PAIR_S * doc.search.certificate_iterations * n_sites * n_pairs
    chain = sum(
        min(math.comb(n_sites - a, b - a), doc.search.max_exhaustive)
        for a, b in itertools.pairwise(counts)
    )
    hm = heatmap_pairs(inputs)
    extra = (doc.beams is not None) + (doc.sweep is not None)
    work = {
        "inputs": INPUTS_S + INPUTS_PER_POINT_S * n_points,
        "visibility": VISIBILITY_PER_SITE_POINT_S
        * n_sites
        * n_points
        * (1 + VISIBILITY_PER_OBSTACLE * obstacles),
        "cache": CACHE_S + CACHE_PER_SITE_PAIR_S * n_sites * n_pairs * per_pair,
        "search": sum(
            SEARCH_S + SEARCH_PER_LAYOUT_PAIR_S * search_layouts(inputs, c) * n_pairs
            for c in counts
        ),
        "checks": checks,
        # the nested chain (planning.rollout): every superset of the previous count's layout,
        # at most search.max_exhaustive per count (beyond it: a greedy extension, fewer); free
        # mode searches it only when cheap, so this overestimates there at most by that little
        "rollout": ROLLOUT_S + SEARCH_PER_LAYOUT_PAIR_S * chain * n_pairs,
        "fields": sum(FIELD_S + FIELD_PER_RIS_PAIR_S * c * hm * per_pair for c in counts),
        "report": REPORT_S + REPORT_PER_LAYOUT_S * len(counts) * doc.search.top_k,
        "figures": FIGURES_S + FIGURE_EXTRA_S * extra,
        "exports": EXPORTS_S + EXPORTS_PER_POINT_S * min(len(inputs.rx_map.points), hm),
    }
    if doc.beams is not None:
        work["beams"] = BEAMS_PER_LAYOUT_S * (len(counts) + len(doc.beams.layouts))
    return {k: MARGIN * v for k, v in work.items()}


def time_estimate(inputs: PlanInputs) -> float:
    """The plan's estimated wall time [s] (the sum of :func:`stage_seconds`): never below the
    measured time, within 2× of it on the calibration cases (docs/validation/resources.md)."""
    return sum(stage_seconds(inputs).values())


def plan_work(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds of :func:`~ris_planner.planning.pipeline.plan_once`'s progress stages:
    ``cache`` (visibility and site cache), ``search``, ``checks``, ``rollout`` (the nested
    chain) and (with ``beams``) ``beams``."""
    est = stage_seconds(inputs)
    work = {
        "cache": est["visibility"] + est["cache"],
        "search": est["search"],
        "checks": est["checks"],
        "rollout": est["rollout"],
    }
    if "beams" in est:
        work["beams"] = est["beams"]
    return work


def report_work(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds after the search: ``fields`` (every count's per-point bounds),
    ``report`` (the diagnosis, the summary and plan.json), ``figures`` and ``exports``
    (:func:`ris_planner.io.geoplan.plan_document`)."""
    est = stage_seconds(inputs)
    return {k: est[k] for k in ("fields", "report", "figures", "exports")}
