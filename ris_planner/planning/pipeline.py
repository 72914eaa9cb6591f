"""A plan as a pipeline of named stages (docs/concepts/planning.md, "Pipeline"):

inputs → visibility → site cache → search (branch-and-bound) → checks → rollout → [beams] →
[sweep] → [sizing] → diagnosis → fields (the per-point bounds, plan.json ``points`` and
``heatmap``) → summary → a frozen :class:`~ris_planner.planning.outputs.result.PlanResult`; its
outputs (plan.json, figures, GIS files) are :func:`ris_planner.io.geoplan.plan_document`'s.

Each stage is a function of what the earlier ones produced; :class:`StageClock` times each
under its name (plan.json ``timing_s``: the stages are disjoint, so their sum is the plan's
wall time), and its share of the progress bar is its estimate in
:mod:`ris_planner.planning.resources.time_estimate`. A new stage is a function here, a
``clock.stage(name)``
around its call in :func:`plan_once` or :func:`run_plan`, and (when it is long) an estimate
in :func:`~ris_planner.planning.resources.time_estimate.plan_work`.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from typing import Any

import numpy as np

from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.limits import cache_layout
from ris_planner.model.plan import PlanDocument, Sweep
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
from ris_planner.planning.outputs.decisions import ties
from ris_planner.planning.outputs.estimator_check import run_estimator_check, validation_work
from ris_planner.planning.outputs.finalists import exact_certificate, rescore_finalists
from ris_planner.planning.outputs.points import heatmap_json, points_json
from ris_planner.planning.outputs.result import CountResult, PlanResult, summarise
from ris_planner.planning.outputs.rx_fields import rx_fields
from ris_planner.planning.prepare import (
    PlanInputs,
    needs_workers,
    prepare_plan,
    validate_document,
)
from ris_planner.planning.resources.time_estimate import plan_work, report_work, search_layouts
from ris_planner.planning.scoring.scorer import Scorer, objective_from_loss
from ris_planner.planning.scoring.site_cache import SiteCache, build_site_cache
from ris_planner.planning.scoring.visibility import Visibility, pair_visibility, serve_warnings
from ris_planner.planning.search.layouts import Layout, search
from ris_planner.planning.search.rollout import plan_rollout
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.executor import Executor, LocalExecutor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, Stages, no_progress

BETWEEN_STAGES = "progress"
"""The ``timing_s`` entry of the progress reports made between stages (each stage's start is
reported before its timer runs): a service job writes every report to its store."""


class StageClock:
    """Wall seconds per named stage (plan.json ``timing_s``) and this process's CPU seconds
    in each (``cpu``: the time estimate's calibration on a busy machine,
    docs/validation/resources.md); a stage timed twice adds up."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.cpu: dict[str, float] = {}
        self._depth = 0  # stages being timed now (nested: an inner one adds to its own too)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block under ``name``."""
        t0, c0 = time.perf_counter(), time.process_time()
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            self.add(name, time.perf_counter() - t0, time.process_time() - c0)

    @contextmanager
    def between(self) -> Iterator[None]:
        """Time the block under :data:`BETWEEN_STAGES` unless a stage is timing it already
        (:class:`~ris_planner.runtime.progress.Stages` reports a stage's start before it)."""
        if self._depth:
            yield
        else:
            with self.stage(BETWEEN_STAGES):
                yield

    def add(self, name: str, seconds: float, cpu: float = 0.0) -> None:
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds
        self.cpu[name] = self.cpu.get(name, 0.0) + cpu


def pipeline_work(inputs: PlanInputs) -> dict[str, float]:
    """The progress shares of :func:`run_plan`: ``plan`` (every search run: the base, the
    sweep's and the sizing's are in its callback), ``fields`` and ``report``."""
    sweep = inputs.document.sweep
    runs = 1 if sweep is None else 1 + len(sweep.values)
    after = report_work(inputs)
    check = inputs.document.validation
    return {
        "plan": runs * sum(plan_work(inputs).values()),
        **({"validation": validation_work(check, len(inputs.counts))} if check else {}),
        "fields": after["fields"],
        "report": after["report"],
    }


def run_plan(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
    inputs: PlanInputs | None = None,
    *,
    stages: Stages | None = None,
    clock: StageClock | None = None,
    settle: bool = True,
) -> PlanResult:
    """Run a plan document through every stage up to its frozen result: inputs, the search
    stages (:func:`plan_once`), the sweep and sizing runs, the diagnosis
    (:mod:`ris_planner.planning.outputs.diagnosis`), the estimator's validation when the document
    asks
    for it (:mod:`ris_planner.planning.outputs.estimator_check`), the per-point bounds and the
    summary.

    ``executor`` defaults to a local process pool (closed afterwards); ``inputs``: the
    document's :func:`prepare_plan` when the caller has it already. Progress goes over the
    stages ``plan``, [``validation``], ``fields``, ``report`` of :func:`pipeline_work`, 1.0 at the
    end; with
    ``stages`` (the caller's :class:`Stages` holding those three) the caller finishes it.
    ``clock`` collects the stage times (the caller's, to add its own stages).

    A plan whose checks run in this process runs them on a thread beside the stages after the
    search (:class:`PendingChecks`); ``settle=False`` returns before they are done
    (``result.pending_checks``: the caller overlaps its own stages – the figures – and then
    calls :func:`settle_checks`)."""
    from ris_planner.planning.outputs.diagnosis import diagnose
    from ris_planner.planning.resources.admission import sizing_runs
    from ris_planner.planning.search.sizing import run_sizing

    clock = StageClock() if clock is None else clock
    with clock.stage("inputs"):
        doc = validate_document(document)
        if inputs is None and doc.sweep is None:
            inputs = prepare_plan(doc, checked=True)
    own_stages = stages is None
    if stages is None:
        stages = Stages(
            progress,
            pipeline_work(inputs if inputs is not None else prepare_plan(doc, checked=True)),
            clock,
        )
    own = executor is None
    ex = LocalExecutor() if executor is None else executor
    with ExitStack() as on_error:  # stops the checks' thread if a later stage fails
        try:
            n_runs = 1 + sizing_runs(doc)
            on_plan = stages.callback("plan")
            main = on_plan if n_runs == 1 else lambda f, m: on_plan(f / n_runs, m)
            if doc.sweep is not None:
                result = _run_sweep(doc, main, ex, clock)
            else:
                result = plan_once(
                    doc, main, ex, checked=True, inputs=inputs, clock=clock, background_checks=True
                )
                on_error.enter_context(cancelled_on_error(result.pending_checks))
            if doc.sizing is not None:
                with clock.stage("sizing"):
                    sizing = run_sizing(
                        doc,
                        lambda f, m: on_plan((1 + f * (n_runs - 1)) / n_runs, m),
                        ex,
                        sweep_rows,
                    )
                result = replace(result, sizing=sizing)
            with clock.stage("diagnosis"):
                result = replace(result, diagnosis=diagnose(result))
            if doc.validation is not None:
                # one BLAS thread, as for the bounds (ris_planner.runtime.blas): the estimator's
                # products are small, and two threads on a busy 2-core machine made this stage
                # ten times slower (1.1 s against 12 s for the Helsinki candidates' 50 runs)
                with clock.stage("validation"), one_blas_thread():
                    on_check = stages.callback("validation")
                    result = replace(result, validation=run_estimator_check(result, on_check))
        finally:
            if own:
                with clock.stage("workers_close"):
                    ex.close()
        with clock.stage("fields"):
            result = fields_stage(result, stages.callback("fields"))
        with clock.stage("report"):
            stages.callback("report")
            result = replace(result, summary=summarise(result))
        if settle:
            result = settle_checks(result, clock)
    result = replace(result, timing=dict(clock.seconds))
    if own_stages:
        stages.finish("done")
    return result


def fields_stage(result: PlanResult, progress: ProgressCallback = no_progress) -> PlanResult:
    """Every count's best layout at every heatmap RX point (:func:`~ris_planner.planning.
    fields.rx_fields`) and plan.json's ``points`` and ``heatmap`` from them."""
    layouts = [cr.ranked[0][0] for cr in result.counts]
    scene = result.scene
    if scene is None:
        scene = Scene.from_environment(result.document.environment)
    fields = rx_fields(
        result.document, result.sites, scene, result.tx_map, result.rx_map, layouts, progress
    )
    result = replace(result, fields=fields)
    return replace(result, maps={"points": points_json(result), "heatmap": heatmap_json(result)})


def plan_once(
    document: PlanDocument | dict[str, Any],
    progress: ProgressCallback,
    ex: Executor,
    checked: bool = False,
    inputs: PlanInputs | None = None,
    clock: StageClock | None = None,
    background_checks: bool = False,
) -> PlanResult:
    """One plan run on an executor, the search stages only (no sweep, no sizing, no diagnosis,
    no per-point bounds): the base of :func:`run_plan`, and each run of a sweep and of the
    sizing question. ``checked``: a validated document whose sizes its parent document
    already checked (a sweep or sizing run:
    :func:`ris_planner.planning.resources.admission.plan_runs`; it
    draws no heatmap, so the heatmap's memory does not apply). ``background_checks``: checks
    that would run in this process run on a thread instead (``result.pending_checks``,
    :class:`PendingChecks`; :func:`settle_checks` completes the result) – the codebook
    evaluations only: a relaxation bound (a count searched greedily) keeps them in line, its
    memory being the scorer's
    (:func:`ris_planner.planning.resources.time_estimate.checks_beside`)."""
    clock = StageClock() if clock is None else clock
    with clock.stage("inputs"):
        doc = (
            document
            if checked and isinstance(document, PlanDocument)
            else validate_document(document)
        )
        inputs = prepare_plan(doc, checked=checked) if inputs is None else inputs
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
    counts, infeasible, deferred = search_stage(
        inputs, scorer, ex, stages.callback("search"), clock
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
) -> tuple[list[CountResult], list[int], list[tuple[int, int]]]:
    """Search each RIS count (branch-and-bound after a greedy ``auto`` search, timed as
    ``branch_and_bound``), rank its layouts, re-score the finalists exactly: (counts, the
    infeasible counts, the (index, count) whose relaxation bound :func:`checks_stage`
    computes)."""
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
        target = doc.objective.target
        if (
            doc.target_mode
            and target is not None
            and target.met(objective_from_loss(doc.objective, ranked[0][1]))
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


def settle_checks(result: PlanResult, clock: StageClock | None = None) -> PlanResult:
    """``result`` with its checks done (:class:`PendingChecks`); the wait is timed as
    ``checks`` (the stage's part that the stages after it did not hide)."""
    pending = result.pending_checks
    if pending is None:
        return result
    clock = StageClock() if clock is None else clock
    with clock.stage("checks"):
        counts = pending.settle()
    return replace(result, counts=counts, pending_checks=None, timing=dict(clock.seconds))


def _run_sweep(
    doc: PlanDocument, progress: ProgressCallback, ex: Executor, clock: StageClock
) -> PlanResult:
    """The base plan (the document's own values) and one more plan per sweep value over the
    same candidates and pairs; ``result.sweep`` holds one table of every run's counts (the
    extra runs timed as ``sweep``)."""
    assert doc.sweep is not None
    sweep = doc.sweep
    raw = doc.model_dump(mode="json")
    n_runs = 1 + len(sweep.values)
    base_raw = {k: v for k, v in raw.items() if k not in ("sweep", "sizing")}
    base = plan_once(base_raw, lambda f, m: progress(f / n_runs, f"base: {m}"), ex, clock=clock)
    if sweep.parameter == "ris_size":
        base_value: Any = [doc.ris.rows, doc.ris.cols]
    else:
        base_value = getattr(doc.system, sweep.parameter)
    rows = [dict(r, base=True) for r in base.summary_rows(base_value)]
    with clock.stage("sweep"):
        for i, value in enumerate(sweep.values, start=1):

            def sub_progress(f: float, m: str, i: int = i, value: Any = value) -> None:
                progress((i + f) / n_runs, f"{sweep.parameter}={value}: {m}")

            rows += [
                dict(r, base=False) for r in sweep_rows(base_raw, sweep, value, sub_progress, ex)
            ]
    table = {"parameter": sweep.parameter, "values": sweep.values, "table": rows}
    return replace(base, document=doc, sweep=table)


def sweep_rows(
    raw: dict[str, Any], sweep: Sweep, value: Any, progress: ProgressCallback, ex: Executor
) -> list[dict[str, Any]]:
    """The :meth:`PlanResult.summary_rows` of one sweep run: the plan document ``raw`` (a JSON
    dict) with the sweep's parameter set to ``value`` (:meth:`Sweep.apply`)."""
    sub = PlanDocument.model_validate(sweep.apply(raw, value))
    return plan_once(sub, progress, ex, checked=True).summary_rows(value)


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
