"""A plan as one pipeline of named stages, whatever its search (docs/concepts/planning.md,
"Pipeline"):

admission (validated, its search chosen, its sizes checked – once) → inputs (sites, maps,
pairs – once) → the search method's run (:mod:`ris_planner.planning.methods`: the enumerating
searches' visibility → site cache → search → checks → roll-out → [beams], or the district
search's sparse information → path → certificate → roll-out) → [sweep] → [sizing] → diagnosis
→ [validation] → fields (the per-point bounds, plan.json ``points`` and ``heatmap``) → summary →
a frozen :class:`~ris_planner.planning.outputs.result.PlanResult`; its outputs (plan.json,
figures, GIS files) are :func:`ris_planner.io.geoplan.plan_document`'s.

Each stage is a function of what the earlier ones produced;
:class:`~ris_planner.runtime.progress.StageClock` times each under its name (plan.json
``timing_s``: the stages are disjoint, so their sum is the plan's wall time), and its share of
the progress bar is its estimate in :mod:`ris_planner.planning.resources.time_estimate`.
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import replace
from typing import Any

from ris_planner.model.plan import PlanDocument
from ris_planner.planning.certify.checks import cancelled_on_error
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.methods import Strategy, strategy_for
from ris_planner.planning.outputs.estimator_check import run_estimator_check, validation_work
from ris_planner.planning.outputs.points import heatmap_json, plan_fields, points_json
from ris_planner.planning.outputs.result import PlanResult, summarise
from ris_planner.planning.prepare import prepare_plan, rebased
from ris_planner.planning.resources.admission import Admitted, admit
from ris_planner.planning.resources.time_estimate import plan_work, report_work
from ris_planner.planning.search.sizing import sizing_json
from ris_planner.runtime.blas import one_blas_thread
from ris_planner.runtime.executor import Executor, LocalExecutor
from ris_planner.runtime.progress import ProgressCallback, StageClock, Stages, no_progress


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
    document: Admitted | PlanDocument | dict[str, Any],
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
    inputs: PlanInputs | None = None,
    *,
    stages: Stages | None = None,
    clock: StageClock | None = None,
    settle: bool = True,
) -> PlanResult:
    """Run a plan document through every stage up to its frozen result (module docstring):
    admitted once (:func:`~ris_planner.planning.resources.admission.admit`; an
    :class:`Admitted` as it is), its inputs prepared once (``inputs`` when the caller has
    them), the search method's run (:func:`~ris_planner.planning.methods.strategy_for`), the
    sweep and sizing runs, the diagnosis (:mod:`ris_planner.planning.outputs.diagnosis`), the
    estimator's validation when the document asks for it
    (:mod:`ris_planner.planning.outputs.estimator_check`), the per-point fields and the
    summary.

    ``executor`` defaults to a local process pool (closed afterwards). Progress goes over the
    stages ``plan``, [``validation``], ``fields``, ``report`` of :func:`pipeline_work`, 1.0 at
    the end; with ``stages`` (the caller's :class:`Stages` holding those) the caller finishes
    it. ``clock`` collects the stage times (the caller's, to add its own stages).

    Checks that run in this process run on a thread beside the stages after the search
    (:class:`~ris_planner.planning.certify.checks.PendingChecks`); ``settle=False`` returns
    before they are done (``result.pending_checks``: the caller overlaps its own stages – the
    figures – and then calls :func:`settle_checks`)."""
    from ris_planner.planning.outputs.diagnosis import diagnose

    clock = StageClock() if clock is None else clock
    if inputs is None:
        with clock.stage("inputs"):
            admitted = document if isinstance(document, Admitted) else admit(document)
            inputs = prepare_plan(admitted)
    doc = inputs.document
    own_stages = stages is None
    if stages is None:
        stages = Stages(progress, pipeline_work(inputs), clock)
    own = executor is None
    ex = LocalExecutor() if executor is None else executor
    method = strategy_for(doc.search.method)
    with ExitStack() as on_error:  # stops the checks' thread if a later stage fails
        try:
            n_runs = 1 + (0 if doc.sizing is None else 1)
            on_plan = stages.callback("plan")
            main = on_plan if n_runs == 1 else lambda f, m: on_plan(f / n_runs, m)
            result = method.run(inputs, main, ex, clock, background_checks=doc.sweep is None)
            on_error.enter_context(cancelled_on_error(result.pending_checks))
            if doc.sweep is not None:
                with clock.stage("sweep"):
                    result = replace(result, sweep=sweep_table(result, inputs, method, main, ex))
            if doc.sizing is not None:
                with clock.stage("sizing"):
                    on_size = lambda f, m: on_plan((1 + f) / n_runs, m)  # noqa: E731
                    result = replace(result, sizing=sizing_stage(result, inputs, on_size, ex))
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
    outputs.rx_fields.plan_fields`) and plan.json's ``points`` and ``heatmap`` from them."""
    fields = plan_fields(result, [cr.ranked[0][0] for cr in result.counts], progress)
    result = replace(result, fields=fields)
    return replace(result, maps={"points": points_json(result), "heatmap": heatmap_json(result)})


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


def sweep_table(
    base: PlanResult,
    inputs: PlanInputs,
    method: Strategy,
    progress: ProgressCallback,
    ex: Executor,
) -> dict[str, Any]:
    """plan.json ``sweep``: the base plan's counts (the document's own values) and one more
    plan per sweep value over the same pairs, each run by the plan's search method."""
    doc = inputs.document
    sweep = doc.sweep
    assert sweep is not None
    base_raw = {
        k: v for k, v in doc.model_dump(mode="json").items() if k not in ("sweep", "sizing")
    }
    n_runs = 1 + len(sweep.values)
    if sweep.parameter == "ris_size":
        base_value: Any = [doc.ris.rows, doc.ris.cols]
    else:
        base_value = getattr(doc.system, sweep.parameter)
    rows = [dict(r, base=True) for r in base.summary_rows(base_value)]
    for i, value in enumerate(sweep.values, start=1):

        def sub_progress(f: float, m: str, i: int = i, value: Any = value) -> None:
            progress((i + f) / n_runs, f"{sweep.parameter}={value}: {m}")

        sub = PlanDocument.model_validate(sweep.apply(base_raw, value))
        run = method.run(rebased(inputs, sub), sub_progress, ex, StageClock())
        rows += [dict(r, base=False) for r in run.summary_rows(value)]
    return {"parameter": sweep.parameter, "values": sweep.values, "table": rows}


def sizing_stage(
    result: PlanResult, inputs: PlanInputs, progress: ProgressCallback, ex: Executor
) -> dict[str, Any]:
    """plan.json ``sizing`` (:func:`~ris_planner.planning.search.sizing.sizing_json`, one shape
    for every method): the sizing target as an objective value – for coverage a share of this
    plan's servable pairs, the same goal at every size – answered by ``sizing.method`` (the
    search the admission chose: :func:`~ris_planner.planning.resources.admission.
    resolve_search`) at the document's RIS size and every size of ``sizing.ris_sizes``."""
    doc = inputs.document
    spec = doc.sizing
    assert spec is not None
    target = doc.sizing_target()
    goal = result.goal(target)
    summary = result.pairs_summary
    method_name = spec.method
    strategy = strategy_for(method_name)
    own = result.choice is not None and strategy is strategy_for(result.choice.used)
    sizes = sorted(doc.sizing_ris_sizes(), key=lambda rc: (rc[0] * rc[1], rc))
    raw = sizing_raw(doc)

    def run_counts(
        size: tuple[int, int], sub_progress: ProgressCallback
    ) -> tuple[list[dict[str, Any]], float | None]:
        sub = PlanDocument.model_validate(
            {**raw, "ris": {**raw["ris"], "rows": size[0], "cols": size[1]}}
        )
        run = strategy.run(rebased(inputs, sub), sub_progress, ex, StageClock(), goal=goal)
        rows = [
            dict(r, target_met=goal.met(r["objective"] or -1.0)) for r in run.summary_rows(size)
        ]
        summary = run.pairs_summary
        return rows, None if summary is None else summary.coverable_weight

    rows = strategy.size_rows(
        result if own else None, inputs, sizes, goal, progress, ex, run_counts
    )
    choice = inputs.sizing_choice
    assert choice is not None
    servable = None if summary is None else summary.servable_weight
    return sizing_json(rows, doc.objective.kind, target, goal, servable, choice)


def sizing_raw(doc: PlanDocument) -> dict[str, Any]:
    """The plan document (JSON dict) each enumerating sizing run starts from: without
    ``sweep``, ``sizing``, ``beams``, ``validation`` and the roll-out, the sizing target as
    ``objective.target`` and the sizing counts (compare mode) or 1 … ``max_ris`` in target
    mode."""
    assert doc.sizing is not None
    drop = ("sweep", "sizing", "beams", "validation", "rollout")
    raw = {k: v for k, v in doc.model_dump(mode="json").items() if k not in drop}
    target = doc.sizing_target()
    raw["objective"] = {**raw["objective"], "target": target.model_dump(exclude_none=True)}
    counts = doc.sizing.counts if doc.sizing.counts is not None else doc.ris_count
    if counts is not None:
        raw["ris_count"], raw["mode"] = list(counts), "compare"
    else:
        raw["ris_count"], raw["mode"] = None, "target"
    return raw
