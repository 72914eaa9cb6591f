"""``run_plan``: maps → pairs → site cache → search per RIS count → ranked result."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import compute_bounds
from ris_planner.errors import LimitExceededError
from ris_planner.limits import HEATMAP_MAX_PAIRS, MAX_CACHE_ENTRIES
from ris_planner.planning.document import PlanDocument
from ris_planner.planning.executor import Executor, LocalExecutor
from ris_planner.planning.maps import PairSet, PointMap, build_map, build_pairs
from ris_planner.planning.objectives import (
    Scorer,
    objective_from_loss,
    objective_value,
    select_metric,
    weighted_quantile,
)
from ris_planner.planning.search import Layout, SearchOutcome, search
from ris_planner.planning.site_cache import SiteCache, build_site_cache
from ris_planner.planning.sites import Site, candidate_json, expand_sites
from ris_planner.progress import ProgressCallback, no_progress
from ris_planner.scenario import ExpectedRandomCodebook, Scenario

FloatArray = NDArray[np.float64]

REPORT_QUANTILES = (0.5, 0.9, 0.95)
CDF_POINTS = 101


def _fraction(weights: FloatArray, mask: NDArray[np.bool_]) -> float:
    """Weighted fraction of the pairs in mask (weights sum to 1; rounding clipped to [0, 1])."""
    return float(min(1.0, weights[mask].sum()))


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


@dataclass
class CountResult:
    """The search for one RIS count and the metric of its best layout per pair."""

    ris_count: int
    outcome: SearchOutcome
    ranked: list[tuple[Layout, float]]
    best_metric: FloatArray


@dataclass
class PlanResult:
    """Everything a plan produced; :meth:`to_json` is the content of ``plan.json``."""

    document: PlanDocument
    sites: list[Site]
    tx_map: PointMap
    rx_map: PointMap
    pairs: PairSet
    scorer: Scorer
    counts: list[CountResult]
    timing: dict[str, float]

    @property
    def cache(self) -> SiteCache:
        return self.scorer.cache

    def layout_metric(self, layout: Layout) -> FloatArray:
        """[P] metric bound (m) of a layout (the search's own scoring, = ``compute_bounds``)."""
        return self.scorer.metric(np.array([layout], dtype=int))[0]

    def layout_stats(self, layout: Layout) -> dict[str, Any]:
        metric = self.layout_metric(layout)[None, :]
        w = self.pairs.weights
        obj = float(objective_value(self.document.objective, metric, w)[0])
        quant = weighted_quantile(metric, w, np.array(REPORT_QUANTILES))[0]
        far = np.all(self.cache.far_field[list(layout)], axis=0)
        return {
            "ris_count": len(layout),
            "sites": [int(s) for s in layout],
            "objective": _num(obj),
            "quantiles_m": {
                f"{q:g}": _num(v) for q, v in zip(REPORT_QUANTILES, quant, strict=True)
            },
            "mean_m": _num(float((metric[0] * w).sum())),
            "blind_fraction": _fraction(w, ~np.isfinite(metric[0])),
            "near_field_fraction": _fraction(w, ~far),
        }

    def cdf(self, metric: FloatArray) -> dict[str, list[float | None]]:
        """The weighted CDF as bound values at probabilities 0.01 … 1 (``null`` = blind)."""
        probs = np.linspace(0.0, 1.0, CDF_POINTS)[1:]
        vals = weighted_quantile(metric[None, :], self.pairs.weights, probs)[0]
        return {"probability": [float(p) for p in probs], "bound_m": [_num(v) for v in vals]}

    def heatmap(self) -> tuple[FloatArray, FloatArray, Layout]:
        """(RX points [M, 3], bound [M], layout) for the best layout of the largest count.

        Each RX map point (a seeded sample of :data:`HEATMAP_MAX_PAIRS` of them for a larger
        map, :func:`heatmap_rx_points`) is evaluated against the whole TX map (a seeded
        weighted sample of it when the product exceeds :data:`HEATMAP_MAX_PAIRS`) or against
        the document's fixed
        ``heatmap_tx``, whatever pairs the plan itself used, so every point of the map gets a
        value from the same TX population; the value is the weighted median over TX (a mean is
        undefined where some bounds are infinite). NaN where no TX point differs from the RX
        point."""
        layout = self.counts[-1].ranked[0][0]
        doc = self.document
        pts = heatmap_rx_points(self.rx_map.points)
        if doc.heatmap_tx is not None:
            tx_pts, tx_w = np.asarray(doc.heatmap_tx, dtype=float)[None], np.ones(1)
        else:
            tx_pts, tx_w = self.tx_map.points, self.tx_map.weights
            max_tx = max(1, HEATMAP_MAX_PAIRS // len(pts))
            if len(tx_pts) > max_tx:
                rng = np.random.default_rng(0)
                pick = rng.choice(len(tx_pts), max_tx, replace=False, p=tx_w / tx_w.sum())
                tx_pts, tx_w = tx_pts[pick], tx_w[pick]
        n_tx, n_rx = len(tx_pts), len(pts)
        tx = np.repeat(tx_pts, n_rx, axis=0)
        rx = np.tile(pts, (n_tx, 1))
        scenario = Scenario.model_construct(  # parts already validated; pairs checked below
            system=doc.system,
            ris=[self.sites[s].ris for s in layout],
            tx=tx_pts[0].tolist(),
            rx=pts[0].tolist(),
            codebook=ExpectedRandomCodebook(),
            known=list(doc.known),
        )
        res = compute_bounds(scenario, tx=tx, rx=rx)  # degenerate pairs: inf with a reason
        metric = select_metric(doc.objective.metric, res.peb_tx, res.peb_rx).reshape(n_tx, n_rx)
        w = np.where(np.linalg.norm(tx - rx, axis=1) > 0, np.repeat(tx_w, n_rx), 0.0)
        w = w.reshape(n_tx, n_rx).T
        empty = w.sum(axis=1) <= 0
        w[empty] = 1.0
        vals = weighted_quantile(metric.T, w, 0.5)
        vals[empty] = np.nan
        return pts, vals, layout

    def to_json(self) -> dict[str, Any]:
        """The plan.json content (``inf`` → ``null``)."""
        doc = self.document
        top: list[tuple[float, int, Layout]] = []
        by_count = []
        prev: float | None = None
        stats_of = {lay: self.layout_stats(lay) for cr in self.counts for lay, _ in cr.ranked}
        for cr in self.counts:
            for lay, loss in cr.ranked:
                top.append((loss, len(lay), lay))
            best_lay, best_loss = cr.ranked[0]
            stats = stats_of[best_lay]
            gain = None
            if prev is not None and np.isfinite(prev) and np.isfinite(best_loss):
                gain = float(prev - best_loss)
            prev = best_loss
            by_count.append(
                {
                    **stats,
                    "marginal_gain": gain,
                    "method": cr.outcome.method,
                    "layouts_total": cr.outcome.total_layouts,
                    "layouts_evaluated": cr.outcome.evaluated,
                    "top_layouts": [
                        {
                            "sites": [int(s) for s in lay],
                            "objective": _num(objective_from_loss(doc.objective, loss)),
                        }
                        for lay, loss in cr.ranked
                    ],
                    "cdf": self.cdf(cr.best_metric),
                }
            )
        top.sort(key=lambda t: (t[0], t[1], t[2]))
        near = ~self.cache.far_field
        return {
            "objective": doc.objective.model_dump(),
            "objective_better": "higher" if doc.objective.kind == "coverage" else "lower",
            "layouts": [stats_of[lay] for _, _, lay in top],
            "by_count": by_count,
            "candidates": [
                {
                    "index": i,
                    **candidate_json(s),
                    "near_field_fraction": _fraction(self.pairs.weights, near[i]),
                    "far_field_flag": bool(np.any(near[i])),
                }
                for i, s in enumerate(self.sites)
            ],
            "pairs": self.pairs.size,
            "tx_points": len(self.tx_map.points),
            "rx_points": len(self.rx_map.points),
            "known": list(doc.known),
            "timing_s": self.timing,
        }


def heatmap_rx_points(points: FloatArray) -> FloatArray:
    """The RX points the heatmap evaluates: all of them up to :data:`HEATMAP_MAX_PAIRS`, else a
    seeded uniform sample of that many (map order kept), so the heatmap's pairs never exceed
    the limit whatever the map's size."""
    if len(points) <= HEATMAP_MAX_PAIRS:
        return points
    pick = np.sort(np.random.default_rng(0).choice(len(points), HEATMAP_MAX_PAIRS, replace=False))
    return points[pick]


def run_plan(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
) -> PlanResult:
    """Run a plan document: build maps and pairs, cache every site's information, search each
    RIS count, rank. ``executor`` defaults to a local process pool (closed afterwards)."""
    from ris_planner.validation import validate_plan

    doc = validate_plan(document)  # the CLI's and the service's checks, sizes before work
    t0 = time.perf_counter()
    sites = expand_sites(doc)
    tx_map = build_map(doc.tx_map, "tx_map")
    rx_map = build_map(doc.rx_map, "rx_map")
    pairs = build_pairs(tx_map, rx_map, doc.pairs, doc.max_pairs)
    if len(sites) * pairs.size > MAX_CACHE_ENTRIES:
        raise LimitExceededError(
            f"{len(sites)} sites × {pairs.size} pairs exceed the site-cache limit of"
            f" {MAX_CACHE_ENTRIES} entries; sample fewer pairs or use fewer candidates"
        )
    progress(0.0, "caching site information")
    cache = build_site_cache(
        doc.system, sites, pairs, lambda f, m: progress(0.2 * f, f"cache: {m}")
    )
    t_cache = time.perf_counter() - t0
    scorer = Scorer(cache, pairs.weights, doc.objective, tuple(doc.known))
    own = executor is None
    ex = LocalExecutor() if executor is None else executor
    counts: list[CountResult] = []
    # search effort ∝ number of layouts (exhaustive) – used only for the progress fractions
    effort = [min(math.comb(len(sites), c), doc.search.max_exhaustive) for c in doc.ris_count]
    done = 0.0
    try:
        for c, e in zip(doc.ris_count, effort, strict=True):
            base = done

            def on_fraction(f: float, base: float = base, e: float = e, c: int = c) -> None:
                progress(0.2 + 0.75 * (base + f * e) / sum(effort), f"search L={c}")

            # the best layouts of the smaller counts seed the greedy search
            seeds = tuple(cr.ranked[0][0] for cr in counts)
            outcome = search(scorer, len(sites), c, doc.search, ex, on_fraction, seeds)
            ranked = outcome.ranked(doc.search.top_k)
            best_metric = scorer.metric(np.array([ranked[0][0]], dtype=int))[0]
            counts.append(CountResult(c, outcome, ranked, best_metric))
            done += e
    finally:
        if own:
            ex.close()
    t_search = time.perf_counter() - t0 - t_cache
    progress(1.0, "done")
    timing = {"cache": t_cache, "search": t_search}
    return PlanResult(doc, sites, tx_map, rx_map, pairs, scorer, counts, timing)
