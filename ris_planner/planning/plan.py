"""``run_plan``: maps → pairs → site cache → search per RIS count → ranked result."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import advice
from ris_planner.bounds.compute import compute_bounds
from ris_planner.bounds.paths import ris_serves
from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.limits import cache_layout
from ris_planner.model.plan import Objective, PlanDocument, Sweep, physics_json
from ris_planner.model.scenario import RandomCodebook, Scenario
from ris_planner.physics.fim import Radio
from ris_planner.planning.beam_design import (
    BeamReport,
    evaluate_layout_beams,
    layout_scenario,
    objective_on_pairs,
    served_pairs,
)
from ris_planner.planning.branch_bound import (
    BNB_MIN_WORK,
    BNB_WORK_FACTOR,
    BranchBoundOutcome,
    branch_and_bound,
)
from ris_planner.planning.certificates import Certificate, relaxation_certificate
from ris_planner.planning.constraints import Feasibility, build_feasibility
from ris_planner.planning.decisions import CountAnswer, decision_json, pareto, ties
from ris_planner.planning.finalists import exact_certificate, rescore_finalists
from ris_planner.planning.maps import (
    PairSet,
    PointMap,
    build_map,
    build_pairs,
    unordered_directions,
)
from ris_planner.planning.objectives import (
    Scorer,
    objective_from_loss,
    objective_kind,
    objective_value,
    select_metric,
    weighted_quantile,
)
from ris_planner.planning.points import heatmap_json, points_json
from ris_planner.planning.resources import HEATMAP_MAX_PAIRS
from ris_planner.planning.rollout import plan_rollout
from ris_planner.planning.search import MIN_TASK_MATRICES, Layout, SearchOutcome, search
from ris_planner.planning.site_cache import SiteCache, build_site_cache
from ris_planner.planning.sites import Site, candidate_json, expand_sites
from ris_planner.planning.visibility import (
    check_sites_outside,
    drop_inside,
    pair_visibility,
    serve_warnings,
)
from ris_planner.planning.work import plan_work, search_layouts
from ris_planner.runtime.executor import Executor, LocalExecutor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, Stages, no_progress
from ris_planner.runtime.provenance import provenance

FloatArray = NDArray[np.float64]

REPORT_QUANTILES = (0.5, 0.9, 0.95)
CDF_POINTS = 101
RANDOM_CODEBOOK_SEEDS = 5
"""Seeds (0 … 4) of the ``random`` codebooks that re-evaluate each count's best layout beside
the expected-random objective the search used (``by_count[i]["random_codebook"]``): enough for
the spread at the G/Γ where the optimism matters, cheap next to the search."""
RANDOM_CODEBOOK_MAX_PAIRS = 2_000
"""Above this many pairs the random-codebook re-evaluation uses a seeded sample of this many
pairs drawn ∝ weight (with replacement, equal weights: an unbiased estimate), and reports the
expected-random objective on the same sample beside it. 2000 pairs give a coverage fraction
to ±1.1 % (one standard deviation, √(0.25/2000)) and the same pairs carry both values, so
their difference – the optimism the re-evaluation reports – is sharper still; the hall's
6400 pairs cost 3.0 s per plan at 20 000 (quiet machine), ≈ 1 s at 2000."""
REASON_NO_TX = "no TX point of the heatmap differs from this RX point"


def _fraction(weights: FloatArray, mask: NDArray[np.bool_]) -> float:
    """Weighted fraction of the pairs in mask (weights sum to 1; rounding clipped to [0, 1])."""
    return float(min(1.0, weights[mask].sum()))


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _relative(gap: float, bound: float) -> float | None:
    """gap / |bound| (``None`` where undefined: an infinite gap or a zero or infinite bound)."""
    ok = np.isfinite(gap) and np.isfinite(bound) and bound != 0
    return float(gap / abs(bound)) if ok else None


def _dominant_reason(
    reason: NDArray[np.object_], weights: FloatArray, blind: NDArray[np.bool_]
) -> list[str | None]:
    """Per row (an RX point, [M, T] reasons and weights): for a blind point the reason carried by
    the largest weight of its infinite pairs (ties: the first reason in sorted order), else None."""
    out: list[str | None] = [None] * reason.shape[0]
    if not np.any(blind):
        return out
    r, w = reason[blind], weights[blind]  # [B, T]
    names = sorted({str(x) for x in r.ravel() if x is not None})
    if not names:
        return out
    # [K, B] weight of each distinct reason per blind point
    mass = np.stack([((r == name) * w).sum(axis=1) for name in names])
    best = np.argmax(mass, axis=0)
    for b, m in enumerate(np.nonzero(blind)[0]):
        out[m] = names[best[b]] if mass[best[b], b] > 0 else None
    return out


@dataclass(frozen=True)
class RxField:
    """One layout evaluated at every RX map point (:meth:`PlanResult.rx_field`)."""

    layout: Layout
    bound: FloatArray
    """[M] weighted median over TX of the objective's metric [m]; inf = blind, NaN = no TX."""
    reason: list[str | None]
    """[M] why the bound is infinite (the dominant reason over TX) or absent; None otherwise."""
    serving: list[list[int]]
    """[M] the layout's sites (candidate indices) with a RIS path to the point from ≥ 1 TX."""


@dataclass
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
    scene: Scene | None = None
    dropped_points: dict[str, int] | None = None
    site_warnings: list[str] | None = None
    """Candidates that serve (almost) none of the pairs (:func:`visibility.serve_warnings`)."""
    beams: dict[Layout, BeamReport] = field(default_factory=dict)
    """Beam designs per evaluated layout (``document.beams``): the best of each count first."""
    _rx_fields: dict[Layout, RxField] = field(default_factory=dict, repr=False)
    feasibility: Feasibility | None = None
    infeasible_counts: tuple[int, ...] = ()
    sweep: dict[str, Any] | None = None
    sizing: dict[str, Any] | None = None
    """The sizing question's answer (:func:`ris_planner.planning.sizing.run_sizing`)."""
    diagnosis: dict[str, Any] | None = None
    """Whether the plan is useful, and why not (:func:`ris_planner.planning.diagnosis.diagnose`)."""
    rollout: dict[str, Any] | None = None
    """plan.json ``rollout`` (:func:`~ris_planner.planning.rollout.plan_rollout`)."""
    validation: dict[str, Any] | None = None
    """plan.json ``validation`` (:func:`~ris_planner.planning.estimator_check.
    run_estimator_check`)."""

    @property
    def cache(self) -> SiteCache:
        return self.scorer.cache

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
        metric = self.layout_metric(layout)[None, :]
        w = self.metric_weights
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
            "near_field_fraction": _fraction(self.pairs.weights, ~far),
        }

    def cdf(self, metric: FloatArray) -> dict[str, list[float | None]]:
        """The weighted CDF as bound values at probabilities 0.01 … 1 (``null`` = blind)."""
        probs = np.linspace(0.0, 1.0, CDF_POINTS)[1:]
        vals = weighted_quantile(metric[None, :], self.metric_weights, probs)[0]
        return {"probability": [float(p) for p in probs], "bound_m": [_num(v) for v in vals]}

    def heatmap_index(self) -> NDArray[np.int_]:
        """Map indices of the RX points the heatmap and ``points`` evaluate
        (:func:`heatmap_rx_index`: all of them up to :data:`HEATMAP_MAX_PAIRS`)."""
        return heatmap_rx_index(len(self.rx_map.points))

    def heatmap_tx(self) -> tuple[FloatArray, FloatArray]:
        """(TX points [T, 3], weights [T]) every RX map point is evaluated against: the document's
        fixed ``heatmap_tx``, else the whole TX map – a seeded weighted sample of it when
        T × M would exceed :data:`HEATMAP_MAX_PAIRS` (the same sample for every layout)."""
        doc = self.document
        if doc.heatmap_tx is not None:
            return np.asarray(doc.heatmap_tx, dtype=float)[None], np.ones(1)
        tx_pts, tx_w = self.tx_map.points, self.tx_map.weights
        max_tx = max(1, HEATMAP_MAX_PAIRS // len(self.heatmap_index()))
        if len(tx_pts) > max_tx:
            rng = np.random.default_rng(0)
            pick = rng.choice(len(tx_pts), max_tx, replace=False, p=tx_w / tx_w.sum())
            tx_pts, tx_w = tx_pts[pick], tx_w[pick]
        return tx_pts, tx_w

    def rx_field(self, layout: Layout) -> RxField:
        """The layout's bound at every RX map point against the :meth:`heatmap_tx` population,
        with its blind reason and serving sites (computed once per layout, then cached).

        The value is the weighted median over TX (a mean is undefined where some bounds are
        infinite); TX points that coincide with the RX point carry no weight, and a point with
        none left is NaN."""
        layout = tuple(int(s) for s in layout)
        cached = self._rx_fields.get(layout)
        if cached is not None:
            return cached
        doc = self.document
        pts = self.rx_map.points[self.heatmap_index()]  # [M, 3]
        tx_pts, tx_w = self.heatmap_tx()  # [T, 3], [T]
        n_tx, n_rx = len(tx_pts), len(pts)
        tx = np.repeat(tx_pts, n_rx, axis=0)  # [T·M, 3], TX-major
        rx = np.tile(pts, (n_tx, 1))
        environment = doc.environment
        layout_ris = [self.sites[s].ris for s in layout]
        scenario = layout_scenario(doc.system, layout_ris, list(doc.known), environment)
        # the plan's visibility rules through compute_bounds; degenerate pairs: inf, a reason
        res = compute_bounds(scenario, tx=tx, rx=rx, profiles=None)
        metric = select_metric(doc.objective.metric, res.peb_tx, res.peb_rx).reshape(n_tx, n_rx)
        w = np.where(np.linalg.norm(tx - rx, axis=1) > 0, np.repeat(tx_w, n_rx), 0.0)
        w = w.reshape(n_tx, n_rx).T  # [M, T]
        empty = w.sum(axis=1) <= 0
        w_med = w.copy()
        w_med[empty] = 1.0
        vals = weighted_quantile(metric.T, w_med, 0.5)  # [M]
        vals[empty] = np.nan
        reasons = _dominant_reason(res.reason.reshape(n_tx, n_rx).T, w, np.isinf(vals))
        for m in np.nonzero(empty)[0]:
            reasons[m] = REASON_NO_TX
        # RIS path for (TX, RX) iff the RIS serves both (contract); serving: with ≥ 1 weighted TX
        scene = self.scene if self.scene is not None else Scene.from_environment(environment)
        serves = np.zeros((len(layout), n_rx), dtype=bool)  # [L, M]
        for j, s in enumerate(layout):
            ris = self.sites[s].ris
            any_tx = ((w > 0) & ris_serves(scene, ris, tx_pts)[None, :]).any(axis=1)  # [M]
            serves[j] = ris_serves(scene, ris, pts) & any_tx
        serving = [[layout[j] for j in np.nonzero(serves[:, m])[0]] for m in range(n_rx)]
        out = RxField(layout, vals, reasons, serving)
        self._rx_fields[layout] = out
        return out

    def heatmap(self) -> tuple[FloatArray, FloatArray, Layout]:
        """(RX points [M, 3], bound [M], layout) for the best layout of the largest count: the
        :meth:`rx_field` of that layout (NaN where no TX point differs from the RX point)."""
        layout = self.counts[-1].ranked[0][0]
        return self.rx_map.points[self.heatmap_index()], self.rx_field(layout).bound, layout

    def warnings(self) -> list[str]:
        """Expected-random optimism per RIS count, grating lobes of the candidate RISs, the
        near-field advice for the best layout of the largest count, and candidates that serve
        (almost) no pair."""
        doc = self.document
        out: list[str | None] = [
            advice.expected_random_warning(doc.system.transmissions, cr.ris_count)
            for cr in self.counts
        ]
        wavelength = Radio.from_system(doc.system).wavelength
        out += advice.spacing_warnings([self.sites[0].ris], wavelength, ["the candidate RIS"])
        lay = list(self.counts[-1].ranked[0][0])
        far = np.all(self.cache.far_field[lay], axis=0)
        out.append(advice.near_field_warning(float((far * self.pairs.weights).sum())))
        out += self.site_warnings or []
        return list(dict.fromkeys(w for w in out if w is not None))

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
                    **({"beams": self.beams[best_lay].to_json()} if best_lay in self.beams else {}),
                    "random_codebook": cr.random_codebook,
                    **self._decision_fields(cr),
                }
            )
        top.sort(key=lambda t: (t[0], t[1], t[2]))
        near = ~self.cache.far_field
        return {
            "dropped_points": dict(self.dropped_points or {"tx": 0, "rx": 0}),
            "objective": doc.objective.model_dump(),
            "objective_better": objective_kind(doc.objective.kind).better,
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
            "physics": physics_json(doc),
            "points": points_json(self),
            "heatmap": heatmap_json(self),
            "timing_s": self.timing,
            "site_cache": {
                "storage": self.cache.storage,
                "rows_stored": self.cache.factor is not None,
                "bytes": self.cache.nbytes,
            },
            "warnings": self.warnings(),
            **({"beams": self.beams_json()} if self.document.beams is not None else {}),
            **({"rollout": self.rollout} if self.rollout is not None else {}),
            **({"validation": self.validation} if self.validation is not None else {}),
            **self._decision_json(),
            "provenance": provenance(doc),
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
                "bound_side": "upper" if objective_kind(obj.kind).higher_is_better else "lower",
                "gap": _num(gap),
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
                obj, answers, max(searched) if searched else 0, doc.target_mode
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


@dataclass(frozen=True)
class PlanInputs:
    """A plan's checked inputs before any bound is computed (:func:`prepare_plan`)."""

    document: PlanDocument
    sites: list[Site]
    tx_map: PointMap
    rx_map: PointMap
    pairs: PairSet
    scene: Scene
    dropped: dict[str, int]
    """UE map points dropped inside prisms, per map."""
    directions: str
    """How unordered pairs count both directions (:func:`maps.unordered_directions`)."""
    counts: list[int]
    """The RIS counts to search (``ris_count``, or 1 … ``max_ris`` in target mode)."""
    feasibility: Feasibility
    """Constraints and costs of the candidate sites."""


def validate_document(document: PlanDocument | dict[str, Any]) -> PlanDocument:
    """The plan document with the CLI's and the service's checks, sizes before work
    (:func:`ris_planner.planning.resources.validate_plan`)."""
    from ris_planner.planning.resources import validate_plan

    return validate_plan(document)


def prepare_plan(document: PlanDocument | dict[str, Any], checked: bool = False) -> PlanInputs:
    """Validate a plan document, expand its sites and maps, build its pairs and check every limit
    that :func:`run_plan` checks before its work (RIS counts vs sites, ``max_pairs``, the site
    cache) – a dry run: raises what ``run_plan`` would raise, computes no bound. ``checked``:
    the document's sizes were checked already (:func:`plan_once`)."""
    doc = (
        document if checked and isinstance(document, PlanDocument) else validate_document(document)
    )
    # the fields of view apply in free space too (an empty scene); obstacles where given
    scene = Scene.from_environment(doc.environment)
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
    dropped = {"tx": 0, "rx": 0}
    if not scene.empty:
        check_sites_outside(scene, sites)
        tx_map, dropped["tx"], rx_map, dropped["rx"] = _drop_points(scene, doc, tx_map, rx_map)
    directions = unordered_directions(doc.pairs, doc.objective.metric, tuple(doc.known))
    pairs = build_pairs(tx_map, rx_map, doc.pairs, doc.max_pairs, directions == "explicit")
    cache_layout(len(sites) * pairs.size, doc.system.wavefront)  # the budget, before any work
    return PlanInputs(
        doc, sites, tx_map, rx_map, pairs, scene, dropped, directions, wanted, feasibility
    )


def heatmap_rx_index(n_points: int) -> NDArray[np.int_]:
    """Map indices of the RX points the heatmap and the per-point results evaluate: all of them
    up to :data:`HEATMAP_MAX_PAIRS`, else a seeded uniform sample of that many (map order
    kept), so the heatmap's pairs never exceed the limit whatever the map's size."""
    if n_points <= HEATMAP_MAX_PAIRS:
        return np.arange(n_points)
    rng = np.random.default_rng(0)
    return np.sort(rng.choice(n_points, HEATMAP_MAX_PAIRS, replace=False))


def run_plan(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
    inputs: PlanInputs | None = None,
) -> PlanResult:
    """Run a plan document: build maps and pairs, cache every site's information, search each
    RIS count, rank; then the sizing question (``document.sizing``) and the diagnosis
    (:mod:`ris_planner.planning.diagnosis`). ``executor`` defaults to a local process pool
    (closed afterwards); ``inputs``: the document's :func:`prepare_plan` when the caller has it
    already. Progress goes over the stages of :func:`~ris_planner.planning.work.plan_work` by
    their estimated work, 1.0 at the end."""
    from ris_planner.planning.diagnosis import diagnose
    from ris_planner.planning.resources import sizing_runs
    from ris_planner.planning.sizing import run_sizing

    doc = validate_document(document)
    own = executor is None
    ex = LocalExecutor() if executor is None else executor
    progress, on_check = split_for_validation(doc, progress, inputs)
    try:
        n_runs = 1 + sizing_runs(doc)
        main = progress if n_runs == 1 else lambda f, m: progress(f / n_runs, m)
        result = (
            _run_sweep(doc, main, ex)
            if doc.sweep is not None
            else plan_once(doc, main, ex, inputs=inputs)
        )
        if doc.sizing is not None:
            result.sizing = run_sizing(
                doc, lambda f, m: progress((1 + f * (n_runs - 1)) / n_runs, m), ex
            )
        result.diagnosis = diagnose(result)
        if doc.validation is not None:
            validation_stage(result, on_check)
        return result
    finally:
        if own:
            ex.close()


def split_for_validation(
    doc: PlanDocument, progress: ProgressCallback, inputs: PlanInputs | None
) -> tuple[ProgressCallback, ProgressCallback]:
    """(the plan's progress, the validation stage's) sharing ``progress`` by estimated work
    (:func:`~ris_planner.planning.work.plan_work`, :func:`~ris_planner.planning.
    estimator_check.validation_work`); without a validation the plan has it all."""
    if doc.validation is None:
        return progress, no_progress
    from ris_planner.planning.estimator_check import validation_work

    inp = prepare_plan(doc) if inputs is None else inputs
    w_plan = sum(plan_work(inp).values())
    w_check = validation_work(doc.validation, len(inp.counts))
    share = w_plan / (w_plan + w_check)

    def on_plan(f: float, m: str) -> None:
        progress(share * f, m)

    def on_check(f: float, m: str) -> None:
        progress(share + (1 - share) * f, f"validation: {m}" if m else "validation")

    return on_plan, on_check


def validation_stage(result: PlanResult, progress: ProgressCallback = no_progress) -> None:
    """The plan-validation stage (``document.validation``): the estimator on each count's best
    layout (:func:`~ris_planner.planning.estimator_check.run_estimator_check`) into
    ``result.validation``, its time in ``timing_s["validation"]``."""
    from ris_planner.planning.estimator_check import run_estimator_check

    t0 = time.perf_counter()
    progress(0.0, "estimator on the recommended layouts")
    result.validation = run_estimator_check(result, progress)
    result.timing["validation"] = time.perf_counter() - t0
    progress(1.0, "done")


def plan_once(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback,
    ex: Executor,
    checked: bool = False,
    inputs: PlanInputs | None = None,
) -> PlanResult:
    """One plan run on an executor (no sweep, no sizing, no diagnosis): the base of
    :func:`run_plan`, and each run of a sweep and of the sizing question. ``checked``: a
    validated document whose sizes its parent document already checked (a sweep or sizing run:
    :func:`ris_planner.planning.resources.plan_runs`; it draws no heatmap, so the heatmap's memory
    does
    not apply)."""
    doc = (
        document if checked and isinstance(document, PlanDocument) else validate_document(document)
    )
    t0 = time.perf_counter()
    inputs = prepare_plan(doc, checked=checked) if inputs is None else inputs
    if needs_workers(inputs, doc.search.max_exhaustive, ex.workers):
        # the workers start (and import) while this process builds the site cache
        ex.start()
    return _plan_with(doc, progress, ex, inputs, t0)


def needs_workers(inputs: PlanInputs, max_exhaustive: int, workers: int) -> bool:
    """Whether the search will split a batch over the workers (:func:`~ris_planner.planning.
    search.chunk_count`): some count's layouts – all of them, or ``max_exhaustive`` as many as
    a greedy search's rounds come to at most – times the pairs reach one minimal task per
    worker. Small plans then never start a pool (their batches run in-process)."""
    n_sites, n_pairs = len(inputs.sites), inputs.pairs.size
    work = max((min(math.comb(n_sites, c), max_exhaustive) for c in inputs.counts), default=0)
    return workers > 1 and work * n_pairs >= workers * MIN_TASK_MATRICES


def _plan_with(
    doc: PlanDocument,
    progress: ProgressCallback,
    ex: Executor,
    inputs: PlanInputs,
    t0: float,
) -> PlanResult:
    """:func:`run_plan` after the inputs, on a started executor (closed by the caller)."""
    sites, tx_map, rx_map, pairs = inputs.sites, inputs.tx_map, inputs.rx_map, inputs.pairs
    scene, dropped, directions = inputs.scene, inputs.dropped, inputs.directions
    wanted, feasibility = inputs.counts, inputs.feasibility
    stages = Stages(progress, plan_work(inputs))
    on_cache = stages.callback("cache")
    t_vis = time.perf_counter()
    visibility = pair_visibility(scene, sites, pairs, doc.system.los)
    warnings = serve_warnings(sites, visibility.present, pairs.weights)
    t_vis = time.perf_counter() - t_vis
    cache = build_site_cache(
        doc.system,
        sites,
        pairs,
        on_cache,
        visibility,
        known=tuple(doc.known),
        layout=cache_layout(len(sites) * pairs.size, doc.system.wavefront),
    )
    t_cache = time.perf_counter() - t0
    scorer = Scorer(
        cache, pairs.weights, doc.objective, tuple(doc.known), mirror=directions == "mirror"
    )
    counts: list[CountResult] = []
    # search effort ∝ the layouts each count evaluates – used only for the progress fractions
    effort = [search_layouts(inputs, c) for c in wanted]
    on_search = stages.callback("search")
    done = 0.0
    infeasible: list[int] = []
    t_bnb = 0.0
    deferred: list[tuple[int, int]] = []  # (index in counts, RIS count) of relaxation bounds
    for c, e in zip(wanted, effort, strict=True):
        base = done

        def on_fraction(f: float, base: float = base, e: float = e, c: int = c) -> None:
            on_search((base + f * e) / sum(effort), f"L={c}")

        # the best layouts of the smaller counts seed the greedy search
        seeds = tuple(cr.ranked[0][0] for cr in counts)
        outcome = search(scorer, len(sites), c, doc.search, ex, on_fraction, seeds, feasibility)
        done += e
        if outcome.losses.size == 0:  # no layout satisfies the constraints
            infeasible.append(c)
            continue
        t1 = time.perf_counter()
        bnb = None
        later = False
        if outcome.method == "greedy" and doc.search.method == "auto":
            # where exhaustive search is out of reach: branch-and-bound from greedy's best
            bnb = branch_and_bound(
                scorer,
                c,
                feasibility,
                outcome,
                ex,
                max(1, doc.search.certificate_iterations),
                max_work=max(BNB_MIN_WORK, BNB_WORK_FACTOR * outcome.evaluated),
            )
            outcome = bnb.outcome
            cert = bnb_certificate(bnb) if doc.search.certificate_iterations else None
            t_bnb += time.perf_counter() - t1
            if bnb.nodes == 0 and not bnb.finished:  # not begun: it would not pay
                cert, later = search_certificate(outcome, doc.search.certificate_iterations)
        else:
            cert, later = search_certificate(outcome, doc.search.certificate_iterations)
        if later:  # the relaxation bound: computed after the search, beside the other checks
            deferred.append((len(counts), c))
        # a float32 cache: the reported layouts re-scored in float64
        outcome, _ = rescore_finalists(scorer, outcome, doc.search.top_k, doc.search.tie_rtol)
        ranked = outcome.ranked(doc.search.top_k)
        cert = exact_certificate(scorer, cert, ranked[0][1])
        best_metric = scorer.exact_metric(np.array([ranked[0][0]], dtype=int))[0]
        n_ties, tied = ties(outcome, doc.search.tie_rtol)
        counts.append(
            CountResult(
                c,
                outcome,
                ranked,
                best_metric,
                certificate=cert,
                n_ties=n_ties,
                ties=tuple(tied),
                branch_and_bound=None if bnb is None else bnb.to_json(),
            )
        )
        target = doc.objective.target
        if (
            doc.target_mode
            and target is not None
            and target.met(objective_from_loss(doc.objective, ranked[0][1]))
        ):
            break
    if not counts:
        raise RisPlannerError(
            f"no layout of {wanted} RISs satisfies the constraints (mounting points,"
            " min_separation_m, require/exclude, budget)"
        )
    t_search = time.perf_counter() - t0 - t_cache - t_bnb
    t1 = time.perf_counter()
    mirror = directions == "mirror"
    # the relaxation bounds and every count's codebook evaluations (a task per layout and seed)
    # in one executor call: independent checks that keep the pool's workers busy together when
    # the search started them (else, and on a cluster, whose tasks carry site blocks, not the
    # whole scorer: in this process)
    iterations = doc.search.certificate_iterations
    jobs = [random_codebook_tasks(doc, sites, pairs, cr.ranked[0][0], mirror) for cr in counts]
    tasks: list[PlanCheck] = [("certificate", (c, feasibility, iterations)) for _, c in deferred]
    tasks += [("codebook", t) for job in jobs for t in job]
    on = ex if ex.started and not ex.site_blocks else SerialExecutor()
    stages.callback("checks")(0.0, f"{len(deferred)} relaxation bounds, {len(tasks)} tasks")
    values = on.map(plan_check_task, scorer, tasks)
    for (i, _), bound in zip(deferred, values[: len(deferred)], strict=True):
        assert isinstance(bound, Certificate)
        counts[i].certificate = bound
    codebook = [float(v) for v in values[len(deferred) :] if not isinstance(v, Certificate)]
    for i, cr in enumerate(counts):
        n = len(jobs[i])
        cr.random_codebook = random_codebook_summary(
            codebook[i * n : (i + 1) * n], len(jobs[i][0][1])
        )
    t_checks = time.perf_counter() - t1
    t_roll = time.perf_counter()
    stages.callback("rollout")(0.0, doc.rollout)
    free = [(cr.ris_count, cr.ranked[0][0], cr.ranked[0][1]) for cr in counts]
    searched = sum(cr.outcome.evaluated for cr in counts) * pairs.size
    rollout = plan_rollout(doc.rollout, scorer, feasibility, free, doc.search, pairs.size, searched)
    t_roll = time.perf_counter() - t_roll
    timing = {
        "cache": t_cache,
        "search": t_search,
        "branch_and_bound": t_bnb,
        "visibility": t_vis,
        "checks": t_checks,
        "rollout": t_roll,
    }
    result = PlanResult(
        doc,
        sites,
        tx_map,
        rx_map,
        pairs,
        scorer,
        counts,
        timing,
        scene=scene,
        dropped_points=dropped,
        site_warnings=warnings,
        feasibility=feasibility,
        infeasible_counts=tuple(infeasible),
        rollout=rollout,
    )
    if doc.beams is not None:
        t1 = time.perf_counter()
        result.beams = plan_beams(result, stages.callback("beams"))
        timing["beams"] = time.perf_counter() - t1
    stages.finish("done")
    return result


def fill_fields(result: PlanResult, progress: ProgressCallback = no_progress) -> None:
    """Compute every count's per-point bounds (:meth:`PlanResult.rx_field` of its best layout:
    the heatmap and ``points`` of plan.json) with progress per count, so that
    :meth:`PlanResult.to_json` finds them cached."""
    layouts = list(dict.fromkeys(cr.ranked[0][0] for cr in result.counts))
    for i, layout in enumerate(layouts):
        progress(i / len(layouts), f"per-point bounds of {len(layout)} RISs")
        result.rx_field(layout)
    progress(1.0, "per-point bounds")


def bnb_certificate(bnb: BranchBoundOutcome) -> Certificate:
    """The certificate a branch-and-bound gives: the optimum when it finished, else the
    smallest bound left open (the root relaxation's when it stopped at the root)."""
    if bnb.finished:
        return Certificate(bnb.loss_bound, exact=True, method="branch_and_bound")
    method = "branch_and_bound_open_nodes" if bnb.nodes > 1 else "frank_wolfe_pair_relaxation"
    return Certificate(bnb.loss_bound, exact=False, method=method)


def search_certificate(outcome: SearchOutcome, iterations: int) -> tuple[Certificate | None, bool]:
    """(the optimum itself after an exhaustive search, else ``None``; whether the relaxation
    bound is wanted instead – not with zero iterations)."""
    if outcome.method == "exhaustive":
        return Certificate(float(outcome.losses.min()), exact=True, method="exhaustive"), False
    return None, iterations > 0


PlanCheck = tuple[str, Any]
"""("certificate", (n_ris, feasibility, iterations)) or ("codebook", an ObjectiveTask)."""


def plan_check_task(scorer: Scorer, task: PlanCheck) -> Certificate | float:
    """Executor task: a relaxation bound (:func:`~ris_planner.planning.certificates.
    relaxation_certificate`) or one codebook evaluation (:func:`objective_task`)."""
    kind, args = task
    if kind == "certificate":
        return relaxation_certificate(scorer, *args)
    return objective_task(None, args)


def _run_sweep(doc: PlanDocument, progress: ProgressCallback, ex: Executor) -> PlanResult:
    """The base plan (the document's own values) and one more plan per sweep value over the
    same candidates and pairs; ``result.sweep`` holds one table of every run's counts."""
    assert doc.sweep is not None
    sweep = doc.sweep
    raw = doc.model_dump(mode="json")
    n_runs = 1 + len(sweep.values)
    base_raw = {k: v for k, v in raw.items() if k not in ("sweep", "sizing")}
    base = plan_once(base_raw, lambda f, m: progress(f / n_runs, f"base: {m}"), ex)
    if sweep.parameter == "ris_size":
        base_value: Any = [doc.ris.rows, doc.ris.cols]
    else:
        base_value = getattr(doc.system, sweep.parameter)
    rows = [dict(r, base=True) for r in base.summary_rows(base_value)]
    for i, value in enumerate(sweep.values, start=1):

        def sub_progress(f: float, m: str, i: int = i, value: Any = value) -> None:
            progress((i + f) / n_runs, f"{sweep.parameter}={value}: {m}")

        rows += [dict(r, base=False) for r in sweep_rows(base_raw, sweep, value, sub_progress, ex)]
    base.document = doc
    base.sweep = {"parameter": sweep.parameter, "values": sweep.values, "table": rows}
    return base


def sweep_rows(
    raw: dict[str, Any], sweep: Sweep, value: Any, progress: ProgressCallback, ex: Executor
) -> list[dict[str, Any]]:
    """The :meth:`PlanResult.summary_rows` of one sweep run: the plan document ``raw`` (a JSON
    dict) with the sweep's parameter set to ``value`` (:meth:`Sweep.apply`)."""
    sub = PlanDocument.model_validate(sweep.apply(raw, value))
    return plan_once(sub, progress, ex, checked=True).summary_rows(value)


def _drop_points(
    scene: Scene, doc: PlanDocument, tx_map: PointMap, rx_map: PointMap
) -> tuple[PointMap, int, PointMap, int]:
    """The UE maps without their points inside prisms (and the counts); raises when a map or
    the fixed heatmap TX lies inside."""
    tx_map, n_tx = drop_inside(tx_map, scene)
    rx_map, n_rx = drop_inside(rx_map, scene)
    for what, pm in (("tx_map", tx_map), ("rx_map", rx_map)):
        if len(pm.points) == 0:
            raise RisPlannerError(f"{what}: every point lies inside a prism of the environment")
    if doc.heatmap_tx is not None:
        hit = int(scene.inside(np.asarray(doc.heatmap_tx, dtype=float))[0])
        if hit >= 0:
            raise RisPlannerError(
                f"heatmap_tx {doc.heatmap_tx} lies inside environment"
                f" {scene.environment.label(hit)}"
            )
    return tx_map, n_tx, rx_map, n_rx


def plan_beams(
    result: PlanResult, progress: ProgressCallback = no_progress
) -> dict[Layout, BeamReport]:
    """Beam designs and power allocations for the best layout of each count and the
    document's extra ``beams.layouts`` (:mod:`ris_planner.planning.beam_design`)."""
    doc = result.document
    spec = doc.beams
    assert spec is not None
    n_sites = len(result.sites)
    layouts: list[Layout] = [cr.ranked[0][0] for cr in result.counts]
    for extra in spec.layouts:
        if len(set(extra)) != len(extra) or any(not 0 <= s < n_sites for s in extra):
            raise RisPlannerError(
                f"beams.layouts entry {extra} must list distinct candidate indices 0…{n_sites - 1}"
            )
        layouts.append(tuple(sorted(extra)))
    layouts = list(dict.fromkeys(layouts))
    scene = Scene.from_environment(doc.environment)
    served = served_pairs(scene, [s.ris for s in result.sites], result.pairs)
    out: dict[Layout, BeamReport] = {}
    for i, lay in enumerate(layouts):

        def on_layout(f: float, m: str, i: int = i) -> None:
            progress((i + f) / len(layouts), m)

        ris = [result.sites[s].ris for s in lay]
        scenario = layout_scenario(doc.system, ris, list(doc.known), doc.environment)
        out[lay] = evaluate_layout_beams(
            scenario,
            result.pairs,
            doc.objective,
            result.layout_metric(lay),
            served[list(lay)],
            seed=spec.seed,
            positions=spec.design_positions,
            random_seeds=spec.random_seeds,
            solver=spec.solver,
            mirror=result.scorer.mirror,
            progress=on_layout,
        )
    return out


ObjectiveTask = tuple[Scenario, FloatArray, FloatArray, FloatArray, Objective, bool]
"""(scenario, tx [P, 3], rx [P, 3], weights [P], objective, mirror) of :func:`objective_task`."""


def objective_task(_shared: object, task: ObjectiveTask) -> float:
    """Executor task: :func:`~ris_planner.planning.beam_design.objective_on_pairs`."""
    return objective_on_pairs(*task)


def random_codebook_tasks(
    doc: PlanDocument,
    sites: list[Site],
    pairs: PairSet,
    layout: Layout,
    mirror: bool = False,
    seeds: int = RANDOM_CODEBOOK_SEEDS,
) -> list[ObjectiveTask]:
    """The evaluations that re-score ``layout``'s objective with other codebooks (summed up by
    :func:`random_codebook_summary`): the expected-random codebook, then ``random`` codebooks of
    seeds 0 … seeds−1, on ≤ ``RANDOM_CODEBOOK_MAX_PAIRS`` pairs drawn ∝ weight."""
    tx, rx, w = pairs.tx, pairs.rx, pairs.weights
    if pairs.size > RANDOM_CODEBOOK_MAX_PAIRS:
        pick = np.random.default_rng(0).choice(pairs.size, RANDOM_CODEBOOK_MAX_PAIRS, p=w / w.sum())
        tx, rx = tx[pick], rx[pick]
        w = np.full(pick.size, 1.0 / pick.size)
    base = layout_scenario(doc.system, [sites[s].ris for s in layout], doc.known, doc.environment)
    return [
        (
            base if seed < 0 else base.model_copy(update={"codebook": RandomCodebook(seed=seed)}),
            tx,
            rx,
            w,
            doc.objective,
            mirror,
        )
        for seed in range(-1, seeds)
    ]


def random_codebook_summary(values: list[float], n_pairs: int) -> dict[str, Any]:
    """``{"seeds", "pairs", "expected", "mean", "min", "max"}`` of the values of
    :func:`random_codebook_tasks` (``null`` for an infinite value)."""
    v = np.array(values[1:])
    return {
        "seeds": len(values) - 1,
        "pairs": n_pairs,
        "expected": _num(values[0]),
        "mean": _num(float(v.mean())),
        "min": _num(float(v.min())),
        "max": _num(float(v.max())),
    }
