"""The enumerating searches' plan run (``search.method`` ``auto``, ``exhaustive``, ``greedy``;
docs/concepts/planning.md, "Pipeline"): visibility → site cache → search (branch-and-bound
after a greedy ``auto`` search) → checks → roll-out → [beams], returning the
:class:`~ris_planner.planning.outputs.result.PlanResult` the pipeline's later stages complete
(:mod:`ris_planner.planning.pipeline`).

Each stage is a function of what the earlier ones produced, timed under its name by the
caller's :class:`~ris_planner.runtime.progress.StageClock` (plan.json ``timing_s``), its share
of the progress bar its estimate in :mod:`ris_planner.planning.resources.time_estimate`.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.limits import cache_layout
from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import PlanDocument, Target, target_goal
from ris_planner.planning.beams import (
    BeamReport,
    evaluate_layout_beams,
    layout_scenario,
    served_pairs,
)
from ris_planner.planning.certify.branch_bound import (
    BNB_MIN_WORK,
    BNB_WORK_FACTOR,
    branch_and_bound,
)
from ris_planner.planning.certify.checks import (
    PendingChecks,
    PlanCheck,
    bnb_certificate,
    cancelled_on_error,
    plan_check_task,
    random_codebook_summary,
    random_codebook_tasks,
    search_certificate,
)
from ris_planner.planning.certify.relaxation import Certificate
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.outputs.decisions import ties
from ris_planner.planning.outputs.finalists import exact_certificate, rescore_finalists
from ris_planner.planning.outputs.result import CountResult, PlanResult
from ris_planner.planning.prepare import needs_workers
from ris_planner.planning.resources.time_estimate import plan_work, search_layouts
from ris_planner.planning.scoring.layout_scorer import pairs_summary
from ris_planner.planning.scoring.scorer import Scorer, objective_from_loss
from ris_planner.planning.scoring.site_cache import SiteCache, build_site_cache
from ris_planner.planning.scoring.visibility import Visibility, pair_visibility, serve_warnings
from ris_planner.planning.search.layouts import Layout, search
from ris_planner.planning.search.rollout import plan_rollout
from ris_planner.runtime.executor import Executor, LocalExecutor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, StageClock, Stages, no_progress


def _level(doc: PlanDocument) -> float | None:
    """The objective's level [m] of the coverable pairs (its screen level: a coverage
    threshold), or None."""
    spec = doc.objective
    return objective_kind(spec.kind).screen_level(spec)


def run_enumerating(
    inputs: PlanInputs,
    progress: ProgressCallback,
    ex: Executor,
    clock: StageClock | None = None,
    background_checks: bool = False,
    goal: Target | None = None,
) -> PlanResult:
    """One plan run of the enumerating searches on an executor, the search stages only (no
    sweep, no sizing, no diagnosis, no per-point bounds): the run of the ``auto``,
    ``exhaustive`` and ``greedy`` methods (:mod:`ris_planner.planning.methods`) for the plan
    and for each run of a sweep and of the sizing question. ``goal``: the target as an
    objective value when the caller fixed it (the sizing question's, the same at every RIS
    size), else the document's target over this run's servable pairs.
    ``background_checks``: checks that would run in this process run on a thread instead
    (``result.pending_checks``, :class:`PendingChecks`; :func:`settle_checks` completes the
    result) – the codebook evaluations only: a relaxation bound (a count searched greedily)
    keeps them in line, its memory being the scorer's
    (:func:`ris_planner.planning.resources.time_estimate.checks_beside`)."""
    clock = StageClock() if clock is None else clock
    doc = inputs.document
    with clock.stage("inputs"):
        search = doc.search
        if needs_workers(inputs, search.max_exhaustive, ex.workers, search.pool_min_work):
            # the workers start (and import) while this process builds the site cache
            ex.start()
        elif isinstance(ex, LocalExecutor) and not ex.started:
            # below search.pool_min_work the workers cost more than they save: every batch
            # runs here, the compiled scorer on every core by threads
            ex = SerialExecutor()
    stages = Stages(progress, plan_work(inputs), clock)
    with clock.stage("visibility"):
        visibility, warnings = visibility_stage(inputs)
    with clock.stage("cache"):
        cache = cache_stage(inputs, visibility, stages.callback("cache"))
    scorer = Scorer(
        cache,
        inputs.pairs.weights,
        doc.objective,
        tuple(doc.known),
        mirror=inputs.directions == "mirror",
    )
    with clock.stage("cache"):  # what every candidate together gives the pairs
        summary = pairs_summary(scorer, inputs.pairs.weights, len(inputs.sites), _level(doc))
    target = doc.objective.target
    if goal is None and target is not None:
        goal = target_goal(doc.objective.kind, target, summary.servable_weight)
    counts, infeasible, deferred = search_stage(
        inputs, scorer, ex, stages.callback("search"), clock, goal
    )
    pending = None
    with clock.stage("checks"):
        on_checks = stages.callback("checks")
        if background_checks and not deferred and not _checks_on_pool(ex):
            pending = start_checks(inputs, scorer, counts, on_checks, visibility)
        else:
            counts = checks_stage(inputs, scorer, counts, deferred, ex, on_checks, visibility)
    with cancelled_on_error(pending):
        with clock.stage("rollout"):
            stages.callback("rollout")(0.0, doc.rollout)
            free = [(cr.ris_count, cr.ranked[0][0], cr.ranked[0][1]) for cr in counts]
            searched = sum(cr.outcome.evaluated for cr in counts) * inputs.pairs.size
            rollout = plan_rollout(
                doc.rollout,
                scorer,
                inputs.feasibility,
                free,
                doc.search,
                inputs.pairs.size,
                searched,
            )
        result = PlanResult(
            doc,
            inputs.sites,
            inputs.tx_map,
            inputs.rx_map,
            inputs.pairs,
            scorer,
            counts,
            clock.seconds,
            scene=inputs.scene,
            dropped_points=inputs.dropped,
            site_warnings=warnings,
            feasibility=inputs.feasibility,
            infeasible_counts=tuple(infeasible),
            rollout=rollout,
            pending_checks=pending,
            pairs_summary=summary,
            choice=inputs.choice,
            search_details={"layouts_scored": int(sum(cr.outcome.evaluated for cr in counts))},
        )
        if doc.beams is not None:
            with clock.stage("beams"):
                result = replace(result, beams=plan_beams(result, stages.callback("beams")))
    stages.finish("done")
    return replace(result, timing=dict(clock.seconds))


def visibility_stage(inputs: PlanInputs) -> tuple[Visibility, list[str]]:
    """Which site serves which pair, and the candidates that serve (almost) none."""
    sys = inputs.document.system
    visibility = pair_visibility(inputs.scene, inputs.sites, inputs.pairs, sys.los)
    return visibility, serve_warnings(inputs.sites, visibility.present, inputs.pairs.weights)


def cache_stage(
    inputs: PlanInputs, visibility: Visibility, progress: ProgressCallback
) -> SiteCache:
    """Every candidate site's information on every pair
    (:mod:`ris_planner.planning.scoring.site_cache`)."""
    doc = inputs.document
    return build_site_cache(
        doc.system,
        inputs.sites,
        inputs.pairs,
        progress,
        visibility,
        known=tuple(doc.known),
        layout=cache_layout(len(inputs.sites) * inputs.pairs.size, doc.system.wavefront),
    )


def search_stage(
    inputs: PlanInputs,
    scorer: Scorer,
    ex: Executor,
    on_search: ProgressCallback,
    clock: StageClock,
    goal: Target | None = None,
) -> tuple[list[CountResult], list[int], list[tuple[int, int]]]:
    """Search each RIS count (branch-and-bound after a greedy ``auto`` search, timed as
    ``branch_and_bound``), rank its layouts, re-score the finalists exactly: (counts, the
    infeasible counts, the (index, count) whose relaxation bound :func:`checks_stage`
    computes); in target mode the counts stop at the first that meets ``goal``."""
    doc, feasibility = inputs.document, inputs.feasibility
    n_sites = len(inputs.sites)
    t_search, c_search = time.perf_counter(), time.process_time()
    t_bnb = c_bnb = 0.0
    counts: list[CountResult] = []
    # search effort ∝ the layouts each count evaluates – used only for the progress fractions
    effort = [search_layouts(inputs, c) for c in inputs.counts]
    done = 0.0
    infeasible: list[int] = []
    deferred: list[tuple[int, int]] = []  # (index in counts, RIS count) of relaxation bounds
    for c, e in zip(inputs.counts, effort, strict=True):
        base = done

        def on_fraction(f: float, base: float = base, e: float = e, c: int = c) -> None:
            on_search((base + f * e) / sum(effort), f"L={c}")

        # the best layouts of the smaller counts seed the greedy search
        seeds = tuple(cr.ranked[0][0] for cr in counts)
        outcome = search(scorer, n_sites, c, doc.search, ex, on_fraction, seeds, feasibility)
        done += e
        if outcome.losses.size == 0:  # no layout satisfies the constraints
            infeasible.append(c)
            continue
        t1, c1 = time.perf_counter(), time.process_time()
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
            c_bnb += time.process_time() - c1
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
        if (
            doc.target_mode
            and goal is not None
            and goal.met(objective_from_loss(doc.objective, ranked[0][1]))
        ):
            break
    cpu = time.process_time() - c_search - c_bnb
    clock.add("search", time.perf_counter() - t_search - t_bnb, cpu)
    clock.add("branch_and_bound", t_bnb, c_bnb)
    if not counts:
        raise RisPlannerError(
            f"no layout of {inputs.counts} RISs satisfies the constraints (mounting points,"
            " min_separation_m, require/exclude, budget)"
        )
    return counts, infeasible, deferred


def checks_stage(
    inputs: PlanInputs,
    scorer: Scorer,
    counts: list[CountResult],
    deferred: list[tuple[int, int]],
    ex: Executor,
    progress: ProgressCallback,
    visibility: Visibility | None = None,
) -> list[CountResult]:
    """The relaxation bounds and every count's codebook evaluations (a task per layout and
    seed) in one executor call: independent checks that keep the pool's workers busy together
    when the search started them (else, and on a cluster, whose tasks carry site blocks, not
    the whole scorer: in this process)."""
    tasks, jobs = _check_tasks(inputs, counts, deferred, visibility)
    on = ex if _checks_on_pool(ex) else SerialExecutor()
    progress(0.0, f"{len(deferred)} relaxation bounds, {len(tasks)} tasks")
    return _checked_counts(counts, deferred, jobs, on.map(plan_check_task, scorer, tasks))


def _checks_on_pool(ex: Executor) -> bool:
    """Whether the checks run on ``ex``'s workers (started by the search, not a cluster's)."""
    return ex.started and not ex.site_blocks


def _check_tasks(
    inputs: PlanInputs,
    counts: list[CountResult],
    deferred: list[tuple[int, int]],
    visibility: Visibility | None,
) -> tuple[list[PlanCheck], list[list[Any]]]:
    """(the checks' tasks: the deferred relaxation bounds, then every count's codebook
    evaluations; those evaluations per count)."""
    doc = inputs.document
    mirror = inputs.directions == "mirror"
    iterations = doc.search.certificate_iterations
    jobs: list[list[Any]] = [
        random_codebook_tasks(
            doc, inputs.sites, inputs.pairs, cr.ranked[0][0], mirror, visibility=visibility
        )
        for cr in counts
    ]
    tasks: list[PlanCheck] = [
        ("certificate", (c, inputs.feasibility, iterations)) for _, c in deferred
    ]
    tasks += [("codebook", t) for job in jobs for t in job]
    return tasks, jobs


def _checked_counts(
    counts: list[CountResult],
    deferred: list[tuple[int, int]],
    jobs: list[list[Any]],
    values: list[Any],
) -> list[CountResult]:
    """``counts`` with the checks' answers (``values`` in the order of :func:`_check_tasks`)."""
    out = list(counts)
    for (i, _), bound in zip(deferred, values[: len(deferred)], strict=True):
        assert isinstance(bound, Certificate)
        out[i] = replace(out[i], certificate=bound)
    codebook = [float(v) for v in values[len(deferred) :] if not isinstance(v, Certificate)]
    for i, cr in enumerate(out):
        n = len(jobs[i])
        summary = random_codebook_summary(codebook[i * n : (i + 1) * n], len(jobs[i][0][1]))
        out[i] = replace(cr, random_codebook=summary)
    return out


def start_checks(
    inputs: PlanInputs,
    scorer: Scorer,
    counts: list[CountResult],
    progress: ProgressCallback,
    visibility: Visibility | None = None,
) -> PendingChecks[list[CountResult]]:
    """:func:`checks_stage` without relaxation bounds (those stay in line: their memory is the
    scorer's), in this process, on a thread (:class:`PendingChecks`)."""
    tasks, jobs = _check_tasks(inputs, counts, [], visibility)
    progress(0.0, f"{len(tasks)} codebook tasks beside the next stages")
    return PendingChecks(scorer, tasks, lambda v: _checked_counts(counts, [], jobs, v))


def plan_beams(
    result: PlanResult, progress: ProgressCallback = no_progress
) -> dict[Layout, BeamReport]:
    """Beam designs and power allocations for the best layout of each count and the
    document's extra ``beams.layouts`` (:mod:`ris_planner.planning.beams`)."""
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
