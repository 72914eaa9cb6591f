"""Estimated work of a plan's stages, in seconds, for honest progress
(:class:`ris_planner.progress.Stages`; docs/concepts/planning-physics.md, "Progress").

Each stage's share of the progress bar is its estimate over the sum, so the bar moves at a
roughly even pace and reaches 100 % only when plan.json's figures and exports are written.
The constants were measured with ``SerialExecutor`` on the development machine (2 cores) on
a 6-site test plan, the hall preset (32 sites) and the junction preset (64 sites), 300–400
pairs each: only their ratios matter, and they hold within about a factor 2 on those plans.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

from ris_planner.limits import HEATMAP_MAX_PAIRS

if TYPE_CHECKING:
    from ris_planner.planning.inputs import PlanInputs

CACHE_S = 0.05
CACHE_PER_SITE_PAIR_S = 5e-6
"""Site cache: fixed cost plus per (site, pair) – junction: 0.135 s for 64 × 400."""

SEARCH_S = 0.3
SEARCH_PER_LAYOUT_PAIR_S = 3e-7
"""Search per RIS count: fixed cost plus per (evaluated layout, pair) – hall: 0.84 s for
6 600 layouts × 400 pairs."""

CHECKS_PER_COUNT_S = 0.3
FRANK_WOLFE_PER_SITE_PAIR_S = 1e-6
"""Checks (codebook evaluations per count, relaxation bounds): hall, junction ≈ 2 s for
three counts; a relaxation bound costs iterations × sites × pairs."""

BEAMS_PER_LAYOUT_S = 2.0
"""Beam design and power allocation per layout (the SDPs dominate)."""

FIELD_S = 0.1
FIELD_PER_RIS_PAIR_S = 2.5e-5
"""Per-point bounds of one count's best layout (heatmap, ``points``): compute_bounds over the
heatmap's TX × RX pairs – junction: 2.0 s for 3 counts (9 RISs) × 126 × 126 pairs."""

REPORT_S = 0.1
REPORT_PER_LAYOUT_S = 0.03
"""plan.json's content besides the fields: statistics of every ranked layout (top_k per
count) – the 6-site test plan: 0.76 s for 2 × 10 layouts."""

FIGURES_S = 2.0
FIGURE_EXTRA_S = 0.5
"""The three figures (top view, heatmap, CDF) ≈ 1.5 s, 2–4 s with matplotlib's first import;
beams and sweep figures each more."""

EXPORTS_S = 0.05
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


def plan_work(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds of :func:`~ris_planner.planning.plan.run_plan`'s stages: ``cache``,
    ``search``, ``checks``, ``rollout`` (the nested chain) and (with ``beams``) ``beams``."""
    doc = inputs.document
    n_sites, n_pairs = len(inputs.sites), inputs.pairs.size
    counts = inputs.counts
    work = {
        "cache": CACHE_S + CACHE_PER_SITE_PAIR_S * n_sites * n_pairs,
        "search": sum(
            SEARCH_S + SEARCH_PER_LAYOUT_PAIR_S * search_layouts(inputs, c) * n_pairs
            for c in counts
        ),
        "checks": len(counts) * CHECKS_PER_COUNT_S
        + FRANK_WOLFE_PER_SITE_PAIR_S * doc.search.certificate_iterations * n_sites * n_pairs,
    }
    # the nested chain (planning.rollout): every superset of the previous count's layout,
    # at most search.max_exhaustive per count (beyond it: a greedy extension, fewer); free
    # mode searches it only when cheap, so this overestimates there at most by that little
    chain = sum(
        min(math.comb(n_sites - a, b - a), doc.search.max_exhaustive)
        for a, b in itertools.pairwise(counts)
    )
    work["rollout"] = SEARCH_PER_LAYOUT_PAIR_S * chain * n_pairs
    if doc.beams is not None:
        work["beams"] = BEAMS_PER_LAYOUT_S * (len(counts) + len(doc.beams.layouts))
    return work


def report_work(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds after the search: ``fields`` (every count's per-point bounds),
    ``report`` (the rest of plan.json), ``figures`` and ``exports``
    (:func:`ris_planner.io.geoplan.plan_document`)."""
    doc = inputs.document
    n_rx = min(len(inputs.rx_map.points), HEATMAP_MAX_PAIRS)
    n_tx = 1 if doc.heatmap_tx is not None else len(inputs.tx_map.points)
    pairs = min(n_tx * n_rx, HEATMAP_MAX_PAIRS)
    extra = (doc.beams is not None) + (doc.sweep is not None)
    return {
        "fields": sum(FIELD_S + FIELD_PER_RIS_PAIR_S * c * pairs for c in inputs.counts),
        "report": REPORT_S + REPORT_PER_LAYOUT_S * len(inputs.counts) * doc.search.top_k,
        "figures": FIGURES_S + FIGURE_EXTRA_S * extra,
        "exports": EXPORTS_S + EXPORTS_PER_POINT_S * n_rx,
    }
