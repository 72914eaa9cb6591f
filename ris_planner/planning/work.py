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

CHECKS_HIDDEN_BY = ("fields", "figures")
"""The stages that checks running beside them (:func:`checks_beside`) overlap."""

CHECKS_BESIDE_SHARE = 0.25
"""Of checks that run on their thread beside the fields and the figures (:func:`checks_beside`),
the share of the overlapped time that still lengthens the plan (the GIL and the core they
share): ``checks`` is estimated as the part the later stages do not hide plus this share of
the rest (docs/validation/resources.md)."""

MARGIN = 1.3
"""Every stage's model times this: the estimate stays above the measured time on a machine
somewhat busier than the calibration's (docs/validation/resources.md)."""

TIME_COEFFICIENTS: dict[str, dict[str, float]] = {
    "inputs": {"const": 0.0302, "per_site": 0.000224},
    "visibility": {"per_site_point": 2.22e-09, "per_site_point_obstacle": 2e-08},
    "cache": {
        "const": 0.0137,
        "per_site_pair": 1.63e-06,
        "per_site_pair_element_spherical": 2.58e-08,
    },
    "search": {
        "per_count": 0.319,
        "per_layout_pair": 2.83e-07,
        "per_exhaustive_layout_pair": 1.27e-07,
        "per_rescored_site_pair": 1.46e-06,
    },
    "checks": {
        "per_codebook_mac": 4.06e-10,
        "per_checked_ris_pair": 1.68e-05,
        "per_checked_ris_pair_element_spherical": 4.45e-07,
        "per_rescored_site_pair": 5.21e-06,
        "per_relaxation_site_pair": 2.89e-08,
    },
    "rollout": {"const": 0, "per_layout_pair": 2e-07},
    "fields": {
        "per_ris_pair": 5.09e-06,
        "per_ris_pair_element_spherical": 2.68e-08,
        "per_rx_point": 7.39e-06,
    },
    "report": {
        "const": 0.0229,
        "per_pair": 5.06e-06,
        "per_rx_point": 0,
        "per_rescored_site_pair": 1.65e-06,
    },
    "figures": {"const": 1.29, "per_rx_point": 1.71e-05, "per_extra_figure": 0.5},
    "exports": {"const": 0.145, "per_rx_point": 4.24e-05},
}
"""Seconds per unit of each size that drives a stage (:func:`stage_terms` names the sizes),
fitted to the per-stage times of ``python benchmarks/bench_memory.py --stages --json F``
by ``python benchmarks/fit_time_model.py F`` (docs/validation/resources.md, "The time
estimate per stage"): ``const`` once, ``per_count`` per RIS count, the rest per unit of the
size of the same name. ``…_element_spherical`` terms are the spherical model's (its expected
Gram and Jacobians sum over the N elements per pair), ``per_rescored_site_pair`` the float32
cache's float64 re-score of the reported layouts (their sites × pairs, per count), and
``per_relaxation_site_pair`` the Frank–Wolfe bounds (iterations × sites × pairs; fitted to 0:
its cost hides in the others on these cases). The visibility's obstacle term is not fitted
(no calibration case has obstacles): 2·10⁻⁸ s per leg and obstacle, the earlier hand-set
model's figure, kept until a case with buildings is in the calibration table."""

BEAMS_PER_LAYOUT_S = 2.0
"""Beam design and power allocation per layout (the SDPs dominate)."""


def greedy_layouts(n_sites: int, count: int, restarts: int, rounds: int) -> int:
    """Layouts a greedy search evaluates, roughly: the greedy build (count × sites) and, per
    start, a few swap rounds over count × (sites − count) neighbours (3 rounds: typical)."""
    swaps = count * max(n_sites - count, 0)
    return count * n_sites + (restarts + 1) * min(rounds, 3) * swaps


def searched_exhaustively(inputs: PlanInputs, count: int) -> bool:
    """Whether the search for ``count`` RISs is exhaustive (``auto`` within
    ``max_exhaustive`` layouts)."""
    s = inputs.document.search
    total = math.comb(len(inputs.sites), count)
    return s.method == "exhaustive" or (s.method == "auto" and total <= s.max_exhaustive)


def search_layouts(inputs: PlanInputs, count: int) -> int:
    """Layouts the search for ``count`` RISs evaluates (all of them when exhaustive)."""
    s = inputs.document.search
    n = len(inputs.sites)
    total = math.comb(n, count)
    if searched_exhaustively(inputs, count):
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


def stage_terms(inputs: PlanInputs) -> dict[str, dict[str, float]]:
    """The sizes that drive each stage's time, by the names of :data:`TIME_COEFFICIENTS`."""
    from ris_planner.model.limits import cache_layout
    from ris_planner.planning.checks import RANDOM_CODEBOOK_MAX_PAIRS, RANDOM_CODEBOOK_SEEDS

    doc = inputs.document
    n_sites, n_pairs = len(inputs.sites), inputs.pairs.size
    counts = inputs.counts
    n_el = doc.ris.rows * doc.ris.cols
    wave = doc.system.wavefront
    sph = float(n_el if wave == "spherical" else 0)
    planar = float(wave != "spherical")
    n_points = len(inputs.tx_map.points) + len(inputs.rx_map.points)
    n_rx = min(len(inputs.rx_map.points), heatmap_pairs(inputs))
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
    chain = sum(
        min(math.comb(n_sites - a, b - a), doc.search.max_exhaustive)
        for a, b in itertools.pairwise(counts)
    )
    ris_hm = float(sum(counts) * heatmap_pairs(inputs))
    exhaustive = {c: searched_exhaustively(inputs, c) for c in counts}
    return {
        "inputs": {"const": 1.0, "per_site": n_sites},
        "visibility": {
            "per_site_point": n_sites * n_points,
            "per_site_point_obstacle": n_sites * n_points * obstacles,
        },
        "cache": {
            "const": 1.0,
            "per_site_pair": planar * n_sites * n_pairs,
            "per_site_pair_element_spherical": sph * n_sites * n_pairs,
        },
        "search": {
            "per_count": len(counts),
            "per_layout_pair": float(
                sum(search_layouts(inputs, c) for c in counts if not exhaustive[c]) * n_pairs
            ),
            "per_exhaustive_layout_pair": float(
                sum(search_layouts(inputs, c) for c in counts if exhaustive[c]) * n_pairs
            ),
            "per_rescored_site_pair": rescored,
        },
        "checks": {
            "per_codebook_mac": planar
            * RANDOM_CODEBOOK_SEEDS
            * sum(codebook_macs(inputs, c) for c in counts),
            "per_checked_ris_pair": planar * checked,
            "per_checked_ris_pair_element_spherical": sph * checked,
            "per_rescored_site_pair": rescored,
            "per_relaxation_site_pair": float(
                doc.search.certificate_iterations * n_sites * n_pairs
            ),
        },
        "rollout": {"const": 1.0, "per_layout_pair": float(chain * n_pairs)},
        "fields": {
            "per_ris_pair": planar * ris_hm,
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
            "per_extra_figure": float((doc.beams is not None) + (doc.sweep is not None)),
        },
        "exports": {"const": 1.0, "per_rx_point": n_rx},
    }


def checks_beside(inputs: PlanInputs) -> bool:
    """Whether the plan's checks will run on a thread beside the fields and the figures
    (:class:`ris_planner.planning.checks.PendingChecks`): every count is searched exhaustively
    (so no relaxation bound is deferred to the checks) and in this process (no worker pool at
    this machine's core count)."""
    import os

    from ris_planner.planning.inputs import needs_workers

    spec = inputs.document.search
    exhaustive = all(searched_exhaustively(inputs, c) for c in inputs.counts)
    workers = os.cpu_count() or 1
    return exhaustive and not needs_workers(
        inputs, spec.max_exhaustive, workers, spec.pool_min_work
    )


def stage_seconds(inputs: PlanInputs) -> dict[str, float]:
    """Estimated seconds of each stage of :func:`~ris_planner.planning.pipeline.run_plan` and
    of the outputs (plan.json ``timing_s`` names): :data:`TIME_COEFFICIENTS` times
    :func:`stage_terms`, :data:`MARGIN` included; checks that run beside the later stages
    (:func:`checks_beside`) count only what those do not hide (:data:`CHECKS_BESIDE_SHARE`)."""
    doc = inputs.document
    work = {
        stage: sum(TIME_COEFFICIENTS[stage][term] * size for term, size in sizes.items())
        for stage, sizes in stage_terms(inputs).items()
    }
    if doc.beams is not None:
        work["beams"] = BEAMS_PER_LAYOUT_S * (len(inputs.counts) + len(doc.beams.layouts))
    if checks_beside(inputs):
        hidden = min(work["checks"], sum(work[st] for st in CHECKS_HIDDEN_BY))
        work["checks"] -= (1.0 - CHECKS_BESIDE_SHARE) * hidden
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
