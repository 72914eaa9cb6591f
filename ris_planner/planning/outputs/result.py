"""The frozen result of a plan (docs/concepts/planning.md, "Pipeline"): what every stage
produced, and ``plan.json`` formatted from it.

Each stage of :mod:`ris_planner.planning.pipeline` returns a new :class:`PlanResult`
(:func:`dataclasses.replace`); nothing here computes a bound: :meth:`PlanResult.to_json` only
assembles what the stages stored (the per-point bounds of the maps stage, the layout
statistics of the summary stage, :func:`summarise`), so writing ``plan.json`` costs its
formatting alone.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import advice
from ris_planner.core.io_json import finite_or_none
from ris_planner.environment import Scene
from ris_planner.model.objectives import objective_kind, weighted_quantile
from ris_planner.model.plan import PlanDocument, Target, physics_json, target_goal
from ris_planner.model.search_methods import MethodChoice
from ris_planner.physics.fim import Radio
from ris_planner.planning.certify.checks import PendingChecks
from ris_planner.planning.certify.relaxation import Certificate
from ris_planner.planning.inputs.constraints import Feasibility
from ris_planner.planning.inputs.sites import Site, candidate_json
from ris_planner.planning.inputs.ue_maps import PairSet, PointMap
from ris_planner.planning.outputs.decisions import CountAnswer, decision_json, pareto
from ris_planner.planning.outputs.rx_fields import RxField, heatmap_rx_index, heatmap_tx
from ris_planner.planning.scoring.layout_scorer import LayoutScorer, PairsSummary
from ris_planner.planning.scoring.scorer import objective_from_loss, objective_value
from ris_planner.planning.scoring.site_cache import SiteCache
from ris_planner.planning.search.layouts import Layout, SearchOutcome
from ris_planner.runtime.provenance import provenance

FloatArray = NDArray[np.float64]

REPORT_QUANTILES = (0.5, 0.9, 0.95)
CDF_POINTS = 101


def _fraction(weights: FloatArray, mask: NDArray[np.bool_]) -> float:
    """Weighted fraction of the pairs in mask (weights sum to 1; rounding clipped to [0, 1])."""
    return float(min(1.0, weights[mask].sum()))


def _relative(gap: float, bound: float) -> float | None:
    """gap / |bound| (``None`` where undefined: an infinite gap or a zero or infinite bound)."""
    ok = np.isfinite(gap) and np.isfinite(bound) and bound != 0
    return float(gap / abs(bound)) if ok else None


class LayoutBeams(Protocol):
    """A layout's beams and power as plan.json reports them
    (:class:`~ris_planner.planning.beams.BeamReport` of an enumerating plan, a district plan's
    :class:`~ris_planner.planning.district_beams.DistrictBeams`)."""

    @property
    def objective(self) -> dict[str, float | None]:
        """The plan objective of the layout under each design."""
        ...

    def to_json(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class CountResult:
    """The search for one RIS count and the metric of its best layout per pair."""

    ris_count: int
    outcome: SearchOutcome
    ranked: list[tuple[Layout, float]]
    best_metric: FloatArray
    random_codebook: dict[str, Any] | None = None
    certificate: Certificate | None = None
    n_ties: int = 1
    ties: tuple[tuple[Layout, float], ...] = ()
    branch_and_bound: dict[str, Any] | None = None
    """What the branch-and-bound after a greedy search did (``None``: not run)."""
    found_by: str | None = None
    """Which part of the search found the reported layout (``None``: the method itself)."""


@dataclass(frozen=True)
class Summary:
    """The summary stage's figures (:func:`summarise`): what plan.json reports beside the
    per-point bounds."""

    stats: Mapping[Layout, dict[str, Any]]
    """:meth:`PlanResult.layout_stats` of every ranked layout."""
    cdfs: tuple[dict[str, list[float | None]], ...]
    """:meth:`PlanResult.cdf` of each count's best layout."""
    warnings: tuple[str, ...]
    provenance: dict[str, Any]


@dataclass(frozen=True)
class PlanResult:
    """Everything a plan produced; :meth:`to_json` is the content of ``plan.json``."""

    document: PlanDocument
    sites: list[Site]
    tx_map: PointMap
    rx_map: PointMap
    pairs: PairSet
    scorer: LayoutScorer
    """The scoring that searched it: the enumerating searches' site cache or the district
    search's sparse information."""
    counts: list[CountResult]
    timing: Mapping[str, float]
    """Seconds per stage (plan.json ``timing_s``; :class:`~ris_planner.planning.pipeline.
    StageClock`)."""
    scene: Scene | None = None
    dropped_points: dict[str, int] | None = None
    site_warnings: list[str] | None = None
    """Candidates that serve (almost) none of the pairs (:func:`visibility.serve_warnings`)."""
    beams: Mapping[Layout, LayoutBeams] = field(default_factory=dict)
    """Beam designs per evaluated layout (``document.beams``): the best of each count first."""
    feasibility: Feasibility | None = None
    infeasible_counts: tuple[int, ...] = ()
    sweep: dict[str, Any] | None = None
    sizing: dict[str, Any] | None = None
    """The sizing question's answer (:func:`ris_planner.planning.search.sizing.run_sizing`)."""
    diagnosis: dict[str, Any] | None = None
    """Whether the plan is useful, and why not
    (:func:`ris_planner.planning.outputs.diagnosis.diagnose`)."""
    rollout: dict[str, Any] | None = None
    """plan.json ``rollout`` (:func:`~ris_planner.planning.search.rollout.plan_rollout`)."""
    validation: dict[str, Any] | None = None
    """plan.json ``validation``: the estimator on each count's best layout
    (:func:`~ris_planner.planning.outputs.estimator_check.run_estimator_check`)."""
    fields: Mapping[Layout, RxField] = field(default_factory=dict)
    """The maps stage: each count's best layout at every heatmap RX point."""
    maps: Mapping[str, Any] | None = None
    """The maps stage: plan.json ``points`` and ``heatmap``
    (:mod:`ris_planner.planning.outputs.points`)."""
    summary: Summary | None = None
    """The summary stage (:func:`summarise`)."""
    pending_checks: PendingChecks[list[CountResult]] | None = None
    """The checks still running on their thread (each count's ``certificate`` and
    ``random_codebook`` are not set yet): :func:`~ris_planner.planning.pipeline.settle_checks`
    waits for them; :meth:`to_json` refuses a result with pending checks."""
    pairs_summary: PairsSummary | None = None
    """What the candidates can give the pairs at all: the servable pairs (the denominator of
    coverage shares and targets) and the coverable ones (plan.json ``pairs_summary``)."""
    choice: MethodChoice | None = None
    """The search that ran and why (plan.json ``search_method``)."""
    search_details: Mapping[str, Any] = field(default_factory=dict)
    """What the search method reports of its own work (plan.json ``search_details``)."""
    sizing_state: Any = None
    """What the search method keeps for the sizing question (not in plan.json)."""

    @property
    def cache(self) -> SiteCache:
        """The enumerating searches' site cache (their :class:`Scorer`'s); a district plan
        holds sparse information instead (``result.scorer.problem``)."""
        cache = getattr(self.scorer, "cache", None)
        if not isinstance(cache, SiteCache):
            raise AttributeError(
                "this plan's search holds no site cache: the district search's information is"
                " result.scorer.problem"
            )
        return cache

    @property
    def metric_weights(self) -> FloatArray:
        """Weights of the columns of a layout's metric (see :attr:`Scorer.metric_weights`)."""
        return self.scorer.metric_weights

    def layout_metric(self, layout: Layout) -> FloatArray:
        """[P] metric bound (m) of a layout (the search's own scoring, = ``compute_bounds``);
        [2P] for mirrored unordered pairs (weights: :attr:`metric_weights`); float64-exact
        with a float32 cache too (:meth:`Scorer.exact_metric`)."""
        return self.scorer.exact_metric(np.array([layout], dtype=int))[0]

    def layout_cost(self, layout: Layout) -> float:
        """Total cost of a layout (0 without a cost model)."""
        if self.feasibility is None:
            return 0.0
        return float(self.feasibility.layout_cost(np.array([layout], dtype=int))[0])

    def layout_stats(self, layout: Layout) -> dict[str, Any]:
        """plan.json's figures of one layout (objective, quantiles, cost, blind and near-field
        fractions), from its metric (:meth:`metric_stats`)."""
        return self.metric_stats(layout, self.layout_metric(layout))

    def metric_stats(self, layout: Layout, metric: FloatArray) -> dict[str, Any]:
        """:meth:`layout_stats` of ``layout`` with the metric [P] (or [2P]) given."""
        metric = metric[None, :]
        w = self.metric_weights
        obj = float(objective_value(self.document.objective, metric, w)[0])
        quant = weighted_quantile(metric, w, np.array(REPORT_QUANTILES))[0]
        far = self.scorer.far_field_of(layout)
        return {
            "ris_count": len(layout),
            "sites": [int(s) for s in layout],
            "site_names": [self.sites[int(s)].name for s in layout],
            "objective": finite_or_none(obj),
            "share_of_servable": self.share_of_servable(obj),
            "quantiles_m": {
                f"{q:g}": finite_or_none(v) for q, v in zip(REPORT_QUANTILES, quant, strict=True)
            },
            # a quantile is null only when it is itself a blind (infinite) value
            "quantiles_blind": [
                f"{q:g}" for q, v in zip(REPORT_QUANTILES, quant, strict=True) if np.isinf(v)
            ],
            "cost": self.layout_cost(layout),
            "mean_m": finite_or_none(float((metric[0] * w).sum())),
            "blind_fraction": _fraction(w, ~np.isfinite(metric[0])),
            "near_field_fraction": _fraction(self.pairs.weights, ~far),
        }

    def share_of_servable(self, value: float) -> float | None:
        """An objective value as a share of the servable pairs (coverage objectives, whose
        targets are such shares: docs/concepts/scoring.md, "One denominator"); ``None`` for
        other objectives."""
        summary = self.pairs_summary
        if summary is None or not objective_kind(self.document.objective.kind).share_of_servable:
            return None
        share = summary.share(value)
        return None if share is None else float(min(1.0, share))

    def goal(self, target: Target) -> Target:
        """A target as the objective value it asks for (:func:`~ris_planner.model.plan.
        target_goal`: coverage targets are shares of the servable pairs)."""
        summary = self.pairs_summary
        servable = 1.0 if summary is None else summary.servable_weight
        return target_goal(self.document.objective.kind, target, servable)

    def cdf(self, metric: FloatArray) -> dict[str, list[float | None]]:
        """The weighted CDF as bound values at probabilities 0.01 … 1 (``null`` = blind)."""
        probs = np.linspace(0.0, 1.0, CDF_POINTS)[1:]
        vals = weighted_quantile(metric[None, :], self.metric_weights, probs)[0]
        return {
            "probability": [float(p) for p in probs],
            "bound_m": [finite_or_none(v) for v in vals],
        }

    def heatmap_index(self) -> NDArray[np.int_]:
        """Map indices of the RX points the heatmap and ``points`` evaluate
        (:func:`~ris_planner.planning.outputs.rx_fields.heatmap_rx_index`)."""
        return heatmap_rx_index(len(self.rx_map.points))

    def heatmap_tx(self) -> tuple[FloatArray, FloatArray]:
        """(TX points [T, 3], weights [T]) of the per-point bounds
        (:func:`~ris_planner.planning.outputs.rx_fields.heatmap_tx`)."""
        return heatmap_tx(self.document, self.tx_map, len(self.heatmap_index()))

    def rx_field(self, layout: Layout) -> RxField:
        """The layout's bound at every RX map point, as the maps stage computed it (each count's
        best layout; :func:`~ris_planner.planning.outputs.rx_fields.rx_fields` for others)."""
        key = tuple(int(s) for s in layout)
        if key not in self.fields:
            raise KeyError(
                f"layout {list(key)}: no per-point bounds (the maps stage computes each"
                " count's best layout; call planning.fields.rx_fields for others)"
            )
        return self.fields[key]

    def heatmap(self) -> tuple[FloatArray, FloatArray, Layout]:
        """(RX points [M, 3], bound [M], layout) for the best layout of the largest count: the
        :meth:`rx_field` of that layout (NaN where no TX point differs from the RX point)."""
        layout = self.counts[-1].ranked[0][0]
        return self.rx_map.points[self.heatmap_index()], self.rx_field(layout).bound, layout

    def warnings(self) -> list[str]:
        """Expected-random optimism per RIS count, grating lobes of the candidate RISs, the
        near-field advice for the best layout of the largest count (planar plans: a spherical
        one already models the near field), and candidates that serve (almost) no pair."""
        doc = self.document
        out: list[str | None] = [
            advice.expected_random_warning(doc.system.transmissions, n)
            for n in self._random_phase_rises()
        ]
        wavelength = Radio.from_system(doc.system).wavelength
        out += advice.spacing_warnings([self.sites[0].ris], wavelength, ["the candidate RIS"])
        if doc.system.wavefront == "planar":  # the advice is to leave the planar model
            far = self.scorer.far_field_of(self.counts[-1].ranked[0][0])
            out.append(advice.near_field_warning(float((far * self.pairs.weights).sum())))
        out += self.site_warnings or []
        return list(dict.fromkeys(w for w in out if w is not None))

    def _random_phase_rises(self) -> list[int]:
        """Per count, the RISs whose columns of B the expected-random FIM's blocks are sized for
        (:func:`~ris_planner.bounds.advice.expected_random_warning`): the count itself, or a
        district plan's profile colours (RISs no pair hears together share a column); none for
        a district plan with a designed codebook (no random phases)."""
        timing = self.search_details.get("time_orthogonal")
        if timing is None:
            return [cr.ris_count for cr in self.counts]
        if timing.get("designed_for") is not None:
            return []
        return [int(row["colours"]) for row in timing["counts"]]

    def to_json(self) -> dict[str, Any]:
        """The plan.json content (``inf`` → ``null``), formatted from what the stages stored;
        raises when the maps or summary stage has not run (:func:`~ris_planner.planning.
        pipeline.run_plan` runs both)."""
        if self.maps is None or self.summary is None:
            raise ValueError("plan.json needs the maps and summary stages (run_plan runs them)")
        if self.pending_checks is not None:
            raise ValueError("plan.json needs the checks: settle_checks(result) first")
        doc = self.document
        summ = self.summary
        top: list[tuple[float, int, Layout]] = []
        by_count = []
        prev: float | None = None
        for cr, cdf in zip(self.counts, summ.cdfs, strict=True):
            for lay, loss in cr.ranked:
                top.append((loss, len(lay), lay))
            best_lay, best_loss = cr.ranked[0]
            gain = None
            if prev is not None and np.isfinite(prev) and np.isfinite(best_loss):
                gain = float(prev - best_loss)
            prev = best_loss
            by_count.append(
                {
                    **summ.stats[best_lay],
                    "marginal_gain": gain,
                    "method": cr.outcome.method,
                    "found_by": cr.found_by or cr.outcome.method,
                    "layouts_total": cr.outcome.total_layouts,
                    "layouts_evaluated": cr.outcome.evaluated,
                    "top_layouts": [
                        {
                            "sites": [int(s) for s in lay],
                            "objective": finite_or_none(objective_from_loss(doc.objective, loss)),
                        }
                        for lay, loss in cr.ranked
                    ],
                    "cdf": cdf,
                    **({"beams": self.beams[best_lay].to_json()} if best_lay in self.beams else {}),
                    "random_codebook": cr.random_codebook,
                    **self._decision_fields(cr),
                }
            )
        top.sort(key=lambda t: (t[0], t[1], t[2]))
        near = self.scorer.near_field_by_site(self.pairs.weights)
        return {
            "dropped_points": dict(self.dropped_points or {"tx": 0, "rx": 0}),
            "objective": doc.objective.model_dump(),
            "objective_better": objective_kind(doc.objective.kind).better,
            "objective_unit": objective_kind(doc.objective.kind).unit,
            "search_method": None if self.choice is None else self.choice.to_json(),
            "pairs_summary": None if self.pairs_summary is None else self.pairs_summary.to_json(),
            "search_details": dict(self.search_details),
            "layouts": [summ.stats[lay] for _, _, lay in top],
            "by_count": by_count,
            "candidates": [
                {
                    "index": i,
                    **candidate_json(s),
                    "near_field_fraction": float(min(1.0, near[i])),
                    "far_field_flag": bool(near[i] > 0),
                }
                for i, s in enumerate(self.sites)
            ],
            "pairs": self.pairs.size,
            "tx_points": len(self.tx_map.points),
            "rx_points": len(self.rx_map.points),
            "known": list(doc.known),
            "physics": physics_json(doc),
            "points": self.maps["points"],
            "heatmap": self.maps["heatmap"],
            "timing_s": dict(self.timing),
            "site_cache": self.scorer.storage_json(),
            "warnings": list(summ.warnings),
            **({"beams": self.beams_json()} if self.document.beams is not None else {}),
            **({"rollout": self.rollout} if self.rollout is not None else {}),
            **({"validation": self.validation} if self.validation is not None else {}),
            **self._decision_json(),
            "provenance": summ.provenance,
        }

    # --- decisions: certificates, ties, targets, cost ------------------------------------------

    def _decision_fields(self, cr: CountResult) -> dict[str, Any]:
        """by_count additions: the certificate and gap, the ties."""
        obj = self.document.objective
        best_loss = cr.ranked[0][1]
        cert = None
        if cr.certificate is not None:
            c = cr.certificate
            gap = 0.0 if c.exact or best_loss == c.loss_bound else best_loss - c.loss_bound
            cert = {
                "objective_bound": finite_or_none(objective_from_loss(obj, c.loss_bound)),
                "bound_side": objective_kind(obj.kind).bound_side,
                "gap": finite_or_none(gap),
                "relative_gap": 0.0 if gap == 0 else _relative(gap, c.loss_bound),
                "exact": bool(c.exact or gap == 0),
                "method": c.method,
            }
        return {
            "certificate": cert,
            "branch_and_bound": cr.branch_and_bound,
            "ties": {
                "tolerance_rel": self.document.search.tie_rtol,
                "count": cr.n_ties,
                "tied": cr.n_ties > 1,
                "layouts": [
                    {
                        "sites": [int(s) for s in lay],
                        "objective": finite_or_none(objective_from_loss(obj, v)),
                    }
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
                    "objective": finite_or_none(val),
                    "gap": None if fields is None else fields["gap"],
                    "cost": self.layout_cost(lay),
                    "target_met": None if obj.target is None else self.goal(obj.target).met(val),
                    "objective_bound": None if fields is None else fields["objective_bound"],
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
                        "objective": finite_or_none(objective_from_loss(obj, loss)),
                    }
                    for c, loss, lay in pareto(points)
                ],
            },
            "infeasible_counts": list(self.infeasible_counts),
        }
        if self.sweep is not None:
            out["sweep"] = self.sweep
        if self.sizing is not None:
            out["sizing"] = self.sizing
        if self.diagnosis is not None:
            out["diagnosis"] = self.diagnosis
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
                obj,
                answers,
                max(searched) if searched else 0,
                doc.target_mode,
                self.goal(obj.target),
                lambda v: self.share_of_servable(v),
            )
        return out

    def beams_json(self) -> dict[str, Any]:
        """``plan.json["beams"]``: the settings and every evaluated layout's report."""
        spec = self.document.beams
        assert spec is not None
        return {
            "settings": spec.model_dump(exclude={"layouts"}),
            "layouts": [
                {"sites": [int(s) for s in lay], **rep.to_json()} for lay, rep in self.beams.items()
            ],
        }


def summarise(result: PlanResult) -> Summary:
    """The summary stage: every ranked layout's statistics (:meth:`PlanResult.layout_stats`),
    each count's CDF, the warnings and the provenance."""
    stats: dict[Layout, dict[str, Any]] = {}
    for cr in result.counts:  # each count's ranked layouts scored in one call
        layouts = [lay for lay, _ in cr.ranked if lay not in stats]
        if not layouts:
            continue
        metrics = result.scorer.exact_metric(np.array(layouts, dtype=int))
        for lay, metric in zip(layouts, metrics, strict=True):
            stats[lay] = result.metric_stats(lay, metric)
    return Summary(
        stats,
        tuple(result.cdf(cr.best_metric) for cr in result.counts),
        tuple(result.warnings()),
        provenance(result.document),
    )
