"""Honest plans: whether a plan's recommendation is useful, and why not
(docs/concepts/diagnosis.md).

The best layout of the plan's largest searched count (the recommended one, the heatmap's) is
judged by two numbers:

* the **served fraction**: the pair weight whose bound lies at or below the objective's
  reference level – ``threshold_m`` (coverage: the coverage itself), ``cap_m`` (mean_capped),
  ``target.max`` (quantile; without a target: any finite bound);
* the **relative spread** between the best and the worst evaluated layout,
  ``|best − worst| / max(|best|, |worst|)`` (1 when only the worst is infinite, 0 when the
  best is): how much the choice of sites matters.

Verdict: ``useless`` when the served fraction is below :data:`USELESS_FRACTION`, or below
:data:`COVERAGE_FLOOR` while the spread is below :data:`SPREAD_MIN`; ``weak`` when the served
fraction is below the floor or the spread is below :data:`SPREAD_MIN` (unless the best layout
saturates: served ≥ :data:`SATURATED_FRACTION`); else ``ok``. With a verdict other than ``ok``
the causes are:

* ``link_budget`` – pairs with a finite bound above the level carry at least
  :data:`CAUSE_SHARE` of the missing weight: the RIS paths are too weak. For the expected-random
  codebook a RIS path's angle information grows as (N² − N)|ρ|² and its delay information as
  N|ρ|² with N elements (:func:`ris_planner.physics.fim.steering_gram`; |ρ| per element,
  eq. RIS_equivalent_gain_xi_zeta), so quadrupling N divides a RIS-only bound by 2 to ≈ 4
  (PEB ∝ N^(−a), ½ ≤ a ≤ 1: 1 while the angle-resolved directions dominate the error, tending
  to ½ at large N where the delay-resolved ones do; a LOS path's fixed information flattens it
  further). The suggestion starts from the angle-limited law (a = 1, optimistic), re-scores
  the smallest square grid that reaches the goal under it with ``compute_bounds``, and while
  the goal is not met extrapolates with each pair's exponent measured between the last two
  re-scorings (a secant in log–log) until it verifiably is (``suggested_ris_size``). Every
  block of the information carries 2P/σ², so the bound falls exactly as P^(−1/2)
  (``suggested_tx_power_dbm``, also re-scored).
* ``geometry`` – pairs with an infinite bound (too few RIS paths reach them, degenerate
  geometry) carry at least :data:`CAUSE_SHARE` of the missing weight: neither size nor power
  helps them, more RISs or other sites do.
* ``blocked`` – candidates whose RIS path exists for no pair of the plan: they cannot help
  it. A site serves a pair only when it serves *both* UEs (each in its field of view with a
  clear leg, :mod:`ris_planner.planning.scoring.visibility`), so each such candidate gets its true
  reason (:func:`blocked_candidates`): ``no_visible_point`` – it sees no map point at all –
  or ``no_pair_with_both_ues`` – it sees UE points, but no evaluated pair has both of its UEs
  among them (typically a few points and sampled pairs that miss them).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.model.objectives import objective_kind, weighted_quantile
from ris_planner.model.plan import Objective, Target
from ris_planner.planning.beams import layout_scenario, metric_on_pairs
from ris_planner.planning.scoring.scorer import objective_from_loss, objective_value

if TYPE_CHECKING:
    from ris_planner.planning.outputs.result import PlanResult
    from ris_planner.planning.search.layouts import Layout

FloatArray = NDArray[np.float64]

COVERAGE_FLOOR = 0.5
"""A recommendation serving less than half of the pair weight is not one (``weak``)."""
USELESS_FRACTION = 0.1
"""Below a tenth of the pair weight served the plan is ``useless`` whatever the spread."""
SPREAD_MIN = 0.05
"""Best and worst layout within 5 % of each other: the choice of sites barely matters."""
SATURATED_FRACTION = 0.95
"""A best layout serving ≥ 95 % of the pair weight is not flagged for a small spread (every
layout being good is no problem)."""
CAUSE_SHARE = 0.25
"""A cause is named when its pairs carry at least a quarter of the missing (unserved) weight."""
MAX_SIDE = 512
"""Largest square RIS side a suggestion may name (the document's limit on rows and cols)."""
SPHERICAL_PAIR_ELEMENTS = 50_000_000
"""The spherical wavefront's bounds take per-element distances (memory ∝ pairs × elements):
its size suggestions are re-scored only up to this many pairs × elements (≈ 0.8 GB), which
caps the side at √(this / pairs). The planar model's expected-random information is closed
form in the element grid (:func:`ris_planner.physics.fim.steering_gram`), so it has no such cap."""
VERIFY_STEPS = 8
"""Re-scorings the size suggestion may take before it gives up."""
GROWTH = 1.1
MIN_EXPONENT = 0.05
"""Smallest exponent a of bound ∝ N^(−a) a suggestion extrapolates with: a LOS path (whose
information does not grow with N) can flatten the decay far below ½ near its floor."""
"""When a predicted size does not verify, the next one is at least 10 % larger per side."""
POWER_STEP_DB = 0.1
"""Resolution of the suggested transmit power [dB]."""
MAX_POWER_DBM = 100.0
"""The largest transmit power a document may set [dBm]."""


def reference_level(obj: Objective) -> float:
    """The bound [m] a pair must reach to count as served (``inf``: any finite bound): the
    objective kind's
    :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.reference_level`."""
    return objective_kind(obj.kind).reference_level(obj)


def served_fraction(metric: FloatArray, weights: FloatArray, level: float) -> float:
    """Weighted fraction of the pairs with a finite bound ≤ level (weights sum to 1)."""
    ok = np.isfinite(metric) & (metric <= level)
    return float(min(1.0, weights[ok].sum()))


def relative_spread(best: float, worst: float) -> float:
    """``|best − worst| / max(|best|, |worst|)`` (1 when only the worst is infinite, 0 when the
    best is or both are 0)."""
    if not math.isfinite(best):
        return 0.0
    if not math.isfinite(worst):
        return 1.0
    scale = max(abs(best), abs(worst))
    return 0.0 if scale == 0 else abs(best - worst) / scale


def verdict(served: float, spread: float | None) -> str:
    """``ok`` / ``weak`` / ``useless`` from the served fraction and the spread (``None``: one
    layout only, no spread)."""
    flat = spread is not None and spread < SPREAD_MIN and served < SATURATED_FRACTION
    if served < USELESS_FRACTION or (served < COVERAGE_FLOOR and flat):
        return "useless"
    if served < COVERAGE_FLOOR or flat:
        return "weak"
    return "ok"


def goal_check(obj: Objective, target: Target | None) -> Callable[[FloatArray, FloatArray], bool]:
    """Whether a metric [P] with weights [P] reaches the goal of the suggestions: served
    fraction ≥ :data:`COVERAGE_FLOOR` and, with a target, the target met."""
    level = reference_level(obj)

    def reaches(metric: FloatArray, weights: FloatArray) -> bool:
        if served_fraction(metric, weights, level) < COVERAGE_FLOOR:
            return False
        return target is None or target.met(float(objective_value(obj, metric[None], weights)[0]))

    return reaches


def smallest_side(
    metric: FloatArray,
    n_elements: int,
    reaches: Callable[[FloatArray], bool],
    exponent: float | FloatArray = 1.0,
    max_side: int = MAX_SIDE,
) -> int | None:
    """Smallest square side n ≤ ``max_side`` whose predicted metric reaches the goal:
    bound(n²) = bound(N₀) · (N₀ / n²)^a per pair (a = ``exponent``: 1 the angle-limited law,
    ½ the delay-limited one); ``None`` when not even the largest does. Bisection
    (the prediction is monotone in n)."""

    def predicted(side: int) -> FloatArray:
        return np.asarray(metric * (n_elements / side**2) ** exponent)

    if not reaches(predicted(max_side)):
        return None
    return smallest_passing(0, max_side, lambda side: reaches(predicted(side)))


PAIR_SIDE_QUANTILES = (0.5, 0.9)
"""Weighted quantiles of the per-pair smallest side reported with a link_budget cause."""


def per_pair_side(
    metric: FloatArray, weights: FloatArray, n_elements: int, level: float
) -> dict[str, int | None]:
    """Weighted quantiles (:data:`PAIR_SIDE_QUANTILES`) over the pairs of the smallest square
    side that brings each pair's bound to ``level`` under the angle-limited law:
    ⌈√(N₀ · bound / level)⌉ (at least 1; ``None`` where the quantile is a blind pair)."""
    side = np.maximum(1.0, np.ceil(np.sqrt(n_elements * metric / level)))
    q = weighted_quantile(side[None], weights, np.array(PAIR_SIDE_QUANTILES))[0]
    return {
        f"{p:g}": int(v) if np.isfinite(v) else None
        for p, v in zip(PAIR_SIDE_QUANTILES, q, strict=True)
    }


def measured_exponent(m0: FloatArray, n0: int, m1: FloatArray, n1: int) -> FloatArray:
    """Per pair, the exponent a of bound ∝ N^(−a) between two re-scorings (N₀ < N₁), clipped to
    [:data:`MIN_EXPONENT`, 1] (1 where a bound is infinite in either: no information)."""
    ok = np.isfinite(m0) & np.isfinite(m1) & (m0 > 0) & (m1 > 0)
    a = np.ones_like(m0)
    a[ok] = np.log(m0[ok] / m1[ok]) / math.log(n1 / n0)
    return np.clip(a, MIN_EXPONENT, 1.0)


def smallest_power_step(
    metric: FloatArray, max_steps: int, reaches: Callable[[FloatArray], bool]
) -> int | None:
    """Smallest k ≤ max_steps with the metric scaled by 10^(−k·Δ/20) reaching the goal (Δ =
    :data:`POWER_STEP_DB`; the bound falls as P^(−1/2)); ``None`` when not even max_steps."""

    def scaled(k: int) -> FloatArray:
        return metric * 10 ** (-k * POWER_STEP_DB / 20)

    if max_steps < 0 or not reaches(scaled(max_steps)):
        return None
    return smallest_passing(-1, max_steps, lambda step: reaches(scaled(step)))


def rescore(
    result: PlanResult,
    layout: Layout,
    *,
    side: int | None = None,
    tx_power_dbm: float | None = None,
) -> tuple[FloatArray, FloatArray]:
    """(metric, weights) of a layout on the plan's pairs by ``compute_bounds`` with every RIS
    an ``side × side`` grid and/or another transmit power (the plan's visibility rules)."""
    doc = result.document
    ris = [result.sites[s].ris for s in layout]
    if side is not None:
        ris = [r.model_copy(update={"rows": side, "cols": side}) for r in ris]
    system = doc.system
    if tx_power_dbm is not None:
        system = system.model_copy(update={"tx_power_dbm": tx_power_dbm})
    scenario = layout_scenario(system, ris, list(doc.known), doc.environment)
    p = result.pairs
    return metric_on_pairs(
        scenario, p.tx, p.rx, p.weights, doc.objective.metric, result.scorer.mirror
    )


def largest_side(result: PlanResult) -> int:
    """The largest square side a size suggestion may re-score: :data:`MAX_SIDE`, for the
    spherical wavefront also √(:data:`SPHERICAL_PAIR_ELEMENTS` / pairs)."""
    if result.document.system.wavefront != "spherical":
        return MAX_SIDE
    return max(1, min(MAX_SIDE, math.isqrt(SPHERICAL_PAIR_ELEMENTS // max(1, result.pairs.size))))


def suggest_size(
    result: PlanResult,
    layout: Layout,
    metric: FloatArray,
    weights: FloatArray,
    goal: Callable[[FloatArray, FloatArray], bool],
) -> dict[str, Any]:
    """``{"suggested_ris_size": [n, n] | None, "verified_objective", "tried_sides",
    "largest_side"}``: the angle-limited law's smallest side, re-scored and raised (at least
    :data:`GROWTH` per step, extrapolating with the exponents measured between the last two
    re-scorings) until the goal verifiably holds, up to :func:`largest_side`."""
    doc = result.document
    n_elements = doc.ris.rows * doc.ris.cols
    base = metric
    exponent: float | FloatArray = 1.0
    tried: list[int] = []
    top = largest_side(result)
    for _ in range(VERIFY_STEPS):
        side = smallest_side(base, n_elements, lambda m: goal(m, weights), exponent, top)
        if side is None:
            break
        if tried:
            side = max(side, min(top, math.ceil(tried[-1] * GROWTH)))
            if side <= tried[-1]:
                break
        tried.append(side)
        verified, w = rescore(result, layout, side=side)
        if goal(verified, w):
            value = float(objective_value(doc.objective, verified[None], w)[0])
            return {
                "suggested_ris_size": [side, side],
                "verified_objective": value if math.isfinite(value) else None,
                "tried_sides": tried,
                "largest_side": top,
            }
        # the law measured per pair between the last two re-scorings (a secant in log–log)
        exponent = measured_exponent(base, n_elements, verified, side * side)
        base, n_elements = verified, side * side
    return {
        "suggested_ris_size": None,
        "verified_objective": None,
        "tried_sides": tried,
        "largest_side": top,
    }


def suggest_power(
    result: PlanResult,
    layout: Layout,
    metric: FloatArray,
    weights: FloatArray,
    goal: Callable[[FloatArray, FloatArray], bool],
) -> dict[str, Any]:
    """``{"suggested_tx_power_dbm": P | None, "verified": bool}``: the exact P^(−1/2) law's
    smallest power (on a :data:`POWER_STEP_DB` grid, ≤ :data:`MAX_POWER_DBM`), re-scored."""
    p0 = result.document.system.tx_power_dbm
    max_steps = math.floor((MAX_POWER_DBM - p0) / POWER_STEP_DB + 1e-9)
    k = smallest_power_step(metric, max_steps, lambda m: goal(m, weights))
    if k is None:
        return {"suggested_tx_power_dbm": None, "verified": False}
    power = round(p0 + k * POWER_STEP_DB, 6)
    verified, w = rescore(result, layout, tx_power_dbm=power)
    return {"suggested_tx_power_dbm": power, "verified": bool(goal(verified, w))}


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


BLOCKED_BATCH = 4_000_000
"""Site × point entries of one visibility query of :func:`blocked_candidates` (bounds its
[S, M] arrays)."""
BLOCKED_EXAMPLES = 3
"""Candidates named per reason in the ``blocked`` message (every one is in its details)."""


def _map_shares(weights: FloatArray) -> FloatArray:
    """A map's relative weights as shares summing to 1 (scaled by their largest first, so no
    sum overflows)."""
    w = weights / weights.max()
    return np.asarray(w / w.sum())


def blocked_candidates(result: PlanResult, dead: NDArray[np.int_]) -> list[dict[str, Any]]:
    """Why each candidate of ``dead`` (whose RIS path exists for no pair) serves none:
    ``{"index", "name", "reason", "visible_points", "visible_tx_points",
    "visible_rx_points", "map_pair_fraction"}`` per candidate.

    ``visible_points`` counts the distinct map points (TX and RX maps, after the points inside
    buildings were dropped) the site serves – in its field of view with a clear leg
    (:func:`~ris_planner.planning.scoring.visibility.serve_matrix`, the plan's own rule);
    ``map_pair_fraction`` is the share of the TX × RX map weight whose TX and RX are two
    distinct points it both serves (a pair sampled from the maps has a RIS path of this site
    with that chance; 0 when it sees a single point: no pair can have one).
    ``reason`` is ``no_visible_point`` when it serves no map point, else
    ``no_pair_with_both_ues``: no evaluated pair has both UEs among its visible points."""
    from ris_planner.environment import Scene
    from ris_planner.planning.scoring.visibility import serve_matrix

    scene = result.scene or Scene.from_environment(result.document.environment)
    tx, rx = result.tx_map, result.rx_map
    points, inverse = np.unique(np.concatenate([tx.points, rx.points]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    it, ir = inverse[: len(tx.points)], inverse[len(tx.points) :]
    # each distinct point's share of the TX and of the RX map weight
    share_tx = np.bincount(it, _map_shares(tx.weights), minlength=len(points))
    share_rx = np.bincount(ir, _map_shares(rx.weights), minlength=len(points))
    out: list[dict[str, Any]] = []
    batch = max(1, BLOCKED_BATCH // max(1, len(points)))
    for lo in range(0, dead.size, batch):
        chunk = [int(i) for i in dead[lo : lo + batch]]
        seen = serve_matrix(scene, [result.sites[i] for i in chunk], points)  # [s, M]
        for row, i in zip(seen, chunk, strict=True):
            n = int(np.count_nonzero(row))
            # TX × RX combinations of two distinct visible points (a pair needs two)
            both = share_tx[row].sum() * share_rx[row].sum() - share_tx[row] @ share_rx[row]
            out.append(
                {
                    "index": i,
                    "name": result.sites[i].name,
                    "reason": "no_visible_point" if n == 0 else "no_pair_with_both_ues",
                    "visible_points": n,
                    "visible_tx_points": int(np.count_nonzero(row[it])),
                    "visible_rx_points": int(np.count_nonzero(row[ir])),
                    "map_pair_fraction": max(0.0, float(both)),
                }
            )
    return out


def _examples(entries: list[dict[str, Any]]) -> str:
    """'e.g. 3 (B0-f1-0-h4), 7 (R2-p0), …' of the first :data:`BLOCKED_EXAMPLES` entries."""
    named = ", ".join(f"{e['index']} ({e['name']})" for e in entries[:BLOCKED_EXAMPLES])
    return f"e.g. {named}" + (", …" if len(entries) > BLOCKED_EXAMPLES else "")


def blocked_cause(result: PlanResult, dead: NDArray[np.int_]) -> dict[str, Any]:
    """The ``blocked`` cause of the candidates ``dead``: counts per reason in the message,
    every candidate with its reason and visible points in ``candidates``
    (:func:`blocked_candidates`)."""
    entries = blocked_candidates(result, dead)
    unseen = [e for e in entries if e["reason"] == "no_visible_point"]
    unpaired = [e for e in entries if e["reason"] == "no_pair_with_both_ues"]
    n_points = len(np.unique(np.concatenate([result.tx_map.points, result.rx_map.points]), axis=0))
    parts = []
    if unseen:
        parts.append(
            f"{len(unseen)} see no UE point (none of the {n_points} map points is in their field"
            f" of view with a clear leg; {_examples(unseen)})"
        )
    if unpaired:
        counts = [e["visible_points"] for e in unpaired]
        top = max(e["map_pair_fraction"] for e in unpaired)
        spread = f"{min(counts)}–{max(counts)}" if min(counts) < max(counts) else f"{counts[0]}"
        parts.append(
            f"{len(unpaired)} see UE points ({spread} of {n_points} each) but serve no pair: a"
            " RIS path needs both UEs of a pair in view with clear legs, and no evaluated pair"
            " has both among them (the TX–RX combinations of two points one of them sees"
            f" carry at most {_pct(top)} of the map weight; {_examples(unpaired)})"
        )
    message = (
        f"{len(entries)} of {len(result.sites)} candidates serve no pair, so they cannot help"
        " this plan: " + "; ".join(parts)
    )
    return {
        "kind": "blocked",
        "message": message,
        "no_visible_point": len(unseen),
        "no_pair_with_both_ues": len(unpaired),
        "candidates": entries,
    }


def diagnose(result: PlanResult) -> dict[str, Any]:
    """``plan.json["diagnosis"]``: ``{"verdict", "causes", "floor", "best", "worst", ...}``
    of the best layout of the plan's largest searched count (module docstring)."""
    doc = result.document
    obj = doc.objective
    cr = result.counts[-1]
    layout, best_loss = cr.ranked[0]
    losses = cr.outcome.losses
    best = objective_from_loss(obj, best_loss)
    worst = objective_from_loss(obj, float(np.max(losses)))
    spread = relative_spread(best, worst) if cr.outcome.evaluated > 1 else None
    metric, weights = cr.best_metric, result.metric_weights
    level = reference_level(obj)
    served = served_fraction(metric, weights, level)
    out: dict[str, Any] = {
        "verdict": verdict(served, spread),
        "causes": [],
        "floor": COVERAGE_FLOOR,
        "best": best if math.isfinite(best) else None,
        "worst": worst if math.isfinite(worst) else None,
        "spread": spread,
        "spread_min": SPREAD_MIN,
        "served_fraction": served,
        "level_m": level if math.isfinite(level) else None,
        "ris_count": cr.ris_count,
        "sites": [int(s) for s in layout],
        "layouts_evaluated": cr.outcome.evaluated,
    }
    if out["verdict"] == "ok":
        return out
    causes: list[dict[str, Any]] = []
    finite = np.isfinite(metric)
    weak = finite & (metric > level)
    blind = ~finite
    missing = max(1.0 - served, 0.0)
    weak_w, blind_w = float(weights[weak].sum()), float(weights[blind].sum())
    n_cols = metric.size
    if weak_w > 0 and weak_w >= CAUSE_SHARE * missing:
        goal = goal_check(obj, None if obj.target is None else result.goal(obj.target))
        size = suggest_size(result, layout, metric, weights, goal)
        power = suggest_power(result, layout, metric, weights, goal)
        rows, cols = doc.ris.rows, doc.ris.cols
        parts = [
            f"{int(weak.sum())} of {n_cols} pairs ({_pct(weak_w)} of the weight) have a finite"
            f" bound above {level:g} m with the best {cr.ris_count}-RIS layout: the {rows}×{cols}"
            " RIS paths are too weak for these distances"
        ]
        if size["suggested_ris_size"] is not None:
            n = size["suggested_ris_size"][0]
            parts.append(f"a {n}×{n} RIS reaches the goal (re-scored)")
        else:
            top = size["largest_side"]
            parts.append(f"not even a {top}×{top} RIS reaches the goal")
        if power["suggested_tx_power_dbm"] is not None:
            parts.append(
                f"or a transmit power of {power['suggested_tx_power_dbm']:g} dBm (now"
                f" {doc.system.tx_power_dbm:g} dBm)"
            )
        causes.append(
            {
                "kind": "link_budget",
                "message": "; ".join(parts),
                "pairs": int(weak.sum()),
                "fraction": weak_w,
                "per_pair_side": per_pair_side(metric, weights, rows * cols, level),
                **size,
                **power,
                "goal": {
                    "served_fraction": COVERAGE_FLOOR,
                    "target": None if obj.target is None else obj.target.model_dump(),
                },
            }
        )
    if blind_w > 0 and blind_w >= CAUSE_SHARE * missing:
        causes.append(
            {
                "kind": "geometry",
                "message": (
                    f"{int(blind.sum())} of {n_cols} pairs ({_pct(blind_w)} of the weight) are"
                    f" blind (no finite bound) with the best {cr.ris_count}-RIS layout"
                    f" {list(layout)}: too few RIS paths reach them or the geometry is"
                    " degenerate; a larger RIS or more power does not help – more RISs"
                    " (ris_count) or other candidate sites do"
                ),
                "pairs": int(blind.sum()),
                "fraction": blind_w,
            }
        )
    dead = result.scorer.idle_sites()
    if dead.size:
        causes.append(blocked_cause(result, dead))
    out["causes"] = causes
    return out


def summary_lines(diagnosis: dict[str, Any]) -> list[str]:
    """The human-readable WARNING block of a diagnosis (empty for ``ok``)."""
    if diagnosis["verdict"] == "ok":
        return []
    served = diagnosis["served_fraction"]
    lines = [
        f"WARNING: this plan is {diagnosis['verdict'].upper()}: the best"
        f" {diagnosis['ris_count']}-RIS layout {diagnosis['sites']} serves {_pct(served)} of the"
        f" pair weight (floor {_pct(diagnosis['floor'])})"
        + (
            ""
            if diagnosis["spread"] is None
            else f"; best and worst layout differ by {_pct(diagnosis['spread'])}"
        )
    ]
    lines += [f"  - {c['kind']}: {c['message']}" for c in diagnosis["causes"]]
    return lines


def smallest_passing(lo: int, hi: int, ok: Callable[[int], bool]) -> int:
    """The smallest integer in (lo, hi] where the monotone predicate ``ok`` holds, by
    bisection; ``ok(hi)`` must hold (the callers check it first)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if ok(mid):
            hi = mid
        else:
            lo = mid
    return hi
