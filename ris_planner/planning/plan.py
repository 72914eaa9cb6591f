"""``run_plan``: maps → pairs → site cache → search per RIS count → ranked result."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import compute_bounds
from ris_planner.errors import LimitExceededError, RisPlannerError
from ris_planner.planning.certificates import Certificate, relaxation_certificate
from ris_planner.planning.constraints import Feasibility, build_feasibility
from ris_planner.planning.decisions import CountAnswer, decision_json, pareto, ties
from ris_planner.planning.document import MAX_CACHE_ENTRIES, PlanDocument
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
HEATMAP_MAX_PAIRS = 200_000
"""TX–RX pairs the heatmap evaluates (about a second with expected_random): beyond it each RX
point is evaluated against a seeded weighted sample of the TX map."""


def _fraction(weights: FloatArray, mask: NDArray[np.bool_]) -> float:
    """Weighted fraction of the pairs in mask (weights sum to 1; rounding clipped to [0, 1])."""
    return float(min(1.0, weights[mask].sum()))


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _relative(gap: float, bound: float) -> float | None:
    """gap / |bound| (``None`` where undefined: an infinite gap or a zero or infinite bound)."""
    ok = np.isfinite(gap) and np.isfinite(bound) and bound != 0
    return float(gap / abs(bound)) if ok else None


@dataclass
class CountResult:
    """The search for one RIS count and the metric of its best layout per pair."""

    ris_count: int
    outcome: SearchOutcome
    ranked: list[tuple[Layout, float]]
    best_metric: FloatArray
    certificate: Certificate | None = None
    n_ties: int = 1
    ties: tuple[tuple[Layout, float], ...] = ()


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
    feasibility: Feasibility | None = None
    infeasible_counts: tuple[int, ...] = ()
    sweep: dict[str, Any] | None = None

    @property
    def cache(self) -> SiteCache:
        return self.scorer.cache

    def layout_metric(self, layout: Layout) -> FloatArray:
        """[P] metric bound (m) of a layout (the search's own scoring, = ``compute_bounds``)."""
        return self.scorer.metric(np.array([layout], dtype=int))[0]

    def layout_cost(self, layout: Layout) -> float:
        """Total cost of a layout (0 without a cost model)."""
        if self.feasibility is None:
            return 0.0
        return float(self.feasibility.layout_cost(np.array([layout], dtype=int))[0])

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
            # a quantile is null only when it is itself a blind (infinite) value
            "quantiles_blind": [
                f"{q:g}" for q, v in zip(REPORT_QUANTILES, quant, strict=True) if np.isinf(v)
            ],
            "cost": self.layout_cost(layout),
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

        Each RX map point is evaluated against the whole TX map (a seeded weighted sample of it
        when the product exceeds :data:`HEATMAP_MAX_PAIRS`) or against the document's fixed
        ``heatmap_tx``, whatever pairs the plan itself used, so every point of the map gets a
        value from the same TX population; the value is the weighted median over TX (a mean is
        undefined where some bounds are infinite). NaN where no TX point differs from the RX
        point."""
        layout = self.counts[-1].ranked[0][0]
        doc = self.document
        pts = self.rx_map.points
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
                    **self._decision_fields(cr),
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
            **self._decision_json(),
        }

    # --- decisions (issue 14): certificates, ties, targets, cost ------------------------------

    def _decision_fields(self, cr: CountResult) -> dict[str, Any]:
        """by_count additions: the certificate and gap, the ties."""
        obj = self.document.objective
        best_loss = cr.ranked[0][1]
        cert = None
        if cr.certificate is not None:
            c = cr.certificate
            gap = 0.0 if c.exact or best_loss == c.loss_bound else best_loss - c.loss_bound
            cert = {
                "objective_bound": _num(objective_from_loss(obj, c.loss_bound)),
                "bound_side": "upper" if obj.kind == "coverage" else "lower",
                "gap": _num(gap),
                "relative_gap": 0.0 if gap == 0 else _relative(gap, c.loss_bound),
                "exact": bool(c.exact or gap == 0),
                "method": c.method,
            }
        return {
            "certificate": cert,
            "ties": {
                "tolerance_rel": self.document.search.tie_rtol,
                "count": cr.n_ties,
                "tied": cr.n_ties > 1,
                "layouts": [
                    {"sites": [int(s) for s in lay], "objective": _num(objective_from_loss(obj, v))}
                    for lay, v in cr.ties
                ],
            },
        }

    def summary_rows(self, value: Any) -> list[dict[str, Any]]:
        """One row per searched count for the sweep table: value, count, layout, objective,
        certificate gap, cost (and whether the target is met)."""
        obj = self.document.objective
        rows = []
        for cr in self.counts:
            lay, loss = cr.ranked[0]
            fields = self._decision_fields(cr)["certificate"]
            val = objective_from_loss(obj, loss)
            rows.append(
                {
                    "value": value,
                    "ris_count": cr.ris_count,
                    "sites": [int(s) for s in lay],
                    "objective": _num(val),
                    "gap": None if fields is None else fields["gap"],
                    "cost": self.layout_cost(lay),
                    "target_met": None if obj.target is None else obj.target.met(val),
                }
            )
        return rows

    def _decision_json(self) -> dict[str, Any]:
        """Top-level additions: ``decision`` (with a target), ``pareto``, ``infeasible_counts``."""
        doc = self.document
        obj = doc.objective
        cost_model = self.feasibility is not None and bool(np.any(self.feasibility.cost > 0))
        points = [
            (self.layout_cost(lay) if cost_model else float(len(lay)), loss, lay)
            for cr in self.counts
            for lay, loss in cr.ranked
        ]
        out: dict[str, Any] = {
            "pareto": {
                "cost_unit": "cost" if cost_model else "ris_count",
                "points": [
                    {
                        "cost": c,
                        "ris_count": len(lay),
                        "sites": [int(s) for s in lay],
                        "objective": _num(objective_from_loss(obj, loss)),
                    }
                    for c, loss, lay in pareto(points)
                ],
            },
            "infeasible_counts": list(self.infeasible_counts),
        }
        if self.sweep is not None:
            out["sweep"] = self.sweep
        if obj.target is not None:
            answers = [
                CountAnswer(
                    cr.ris_count,
                    cr.ranked[0][1],
                    cr.ranked[0][0],
                    self.layout_cost(cr.ranked[0][0]),
                    cr.certificate,
                )
                for cr in self.counts
            ] + [CountAnswer(c, None, None, 0.0, None) for c in self.infeasible_counts]
            answers.sort(key=lambda a: a.ris_count)
            searched = [a.ris_count for a in answers]
            out["decision"] = decision_json(
                obj, answers, max(searched) if searched else 0, doc.target_mode
            )
        return out


def run_plan(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
) -> PlanResult:
    """Run a plan document: build maps and pairs, cache every site's information, search each
    RIS count, rank. ``executor`` defaults to a local process pool (closed afterwards)."""
    doc = document if isinstance(document, PlanDocument) else PlanDocument.model_validate(document)
    if doc.sweep is not None:
        return _run_sweep(doc, progress, executor)
    t0 = time.perf_counter()
    sites = expand_sites(doc)
    wanted = doc.max_counts
    if doc.ris_count is None:  # target mode up to max_ris: at most every candidate
        wanted = [c for c in wanted if c <= len(sites)]
    elif max(wanted) > len(sites):
        raise RisPlannerError(f"ris_count {max(wanted)} exceeds the {len(sites)} candidate sites")
    feasibility = build_feasibility(sites, doc.constraints, doc.cost)
    wanted = [c for c in wanted if c >= len(feasibility.required)]
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
    effort = [min(math.comb(len(sites), c), doc.search.max_exhaustive) for c in wanted]
    done = 0.0
    infeasible: list[int] = []
    t_cert = 0.0
    try:
        for c, e in zip(wanted, effort, strict=True):
            base = done

            def on_fraction(f: float, base: float = base, e: float = e, c: int = c) -> None:
                progress(0.2 + 0.75 * (base + f * e) / sum(effort), f"search L={c}")

            # the best layouts of the smaller counts seed the greedy search
            seeds = tuple(cr.ranked[0][0] for cr in counts)
            outcome = search(scorer, len(sites), c, doc.search, ex, on_fraction, seeds, feasibility)
            done += e
            if outcome.evaluated == 0:  # no layout satisfies the constraints
                infeasible.append(c)
                continue
            ranked = outcome.ranked(doc.search.top_k)
            best_metric = scorer.metric(np.array([ranked[0][0]], dtype=int))[0]
            t1 = time.perf_counter()
            cert = count_certificate(
                scorer, c, outcome, feasibility, doc.search.certificate_iterations
            )
            t_cert += time.perf_counter() - t1
            n_ties, tied = ties(outcome, doc.search.tie_rtol)
            counts.append(CountResult(c, outcome, ranked, best_metric, cert, n_ties, tuple(tied)))
            target = doc.objective.target
            if (
                doc.target_mode
                and target is not None
                and target.met(objective_from_loss(doc.objective, ranked[0][1]))
            ):
                break
    finally:
        if own:
            ex.close()
    if not counts:
        raise RisPlannerError(
            f"no layout of {wanted} RISs satisfies the constraints (mounting points,"
            " min_separation_m, require/exclude, budget)"
        )
    t_search = time.perf_counter() - t0 - t_cache - t_cert
    progress(1.0, "done")
    timing = {"cache": t_cache, "search": t_search, "certificate": t_cert}
    return PlanResult(
        doc, sites, tx_map, rx_map, pairs, scorer, counts, timing, feasibility, tuple(infeasible)
    )


def count_certificate(
    scorer: Scorer, n_ris: int, outcome: SearchOutcome, feasible: Feasibility, iterations: int
) -> Certificate | None:
    """The optimum itself after an exhaustive search, else the relaxation bound (``None`` with
    zero iterations)."""
    if outcome.method == "exhaustive":
        return Certificate(float(outcome.losses.min()), exact=True, method="exhaustive")
    if iterations == 0:
        return None
    return relaxation_certificate(scorer, n_ris, feasible, iterations)


def _run_sweep(
    doc: PlanDocument, progress: ProgressCallback, executor: Executor | None
) -> PlanResult:
    """The base plan (the document's own values) and one more plan per sweep value over the
    same candidates and pairs; ``result.sweep`` holds one table of every run's counts."""
    assert doc.sweep is not None
    sweep = doc.sweep
    raw = doc.model_dump(mode="json")
    own = executor is None
    ex = LocalExecutor() if executor is None else executor
    n_runs = 1 + len(sweep.values)
    try:
        base_raw = {k: v for k, v in raw.items() if k != "sweep"}
        base = run_plan(base_raw, lambda f, m: progress(f / n_runs, f"base: {m}"), ex)
        if sweep.parameter == "ris_size":
            base_value: Any = [doc.ris.rows, doc.ris.cols]
        else:
            base_value = getattr(doc.system, sweep.parameter)
        rows = [dict(r, base=True) for r in base.summary_rows(base_value)]
        for i, value in enumerate(sweep.values, start=1):

            def sub_progress(f: float, m: str, i: int = i, value: Any = value) -> None:
                progress((i + f) / n_runs, f"{sweep.parameter}={value}: {m}")

            sub = run_plan(sweep.apply(raw, value), sub_progress, ex)
            rows += [dict(r, base=False) for r in sub.summary_rows(value)]
    finally:
        if own:
            ex.close()
    base.document = doc
    base.sweep = {"parameter": sweep.parameter, "values": sweep.values, "table": rows}
    return base
