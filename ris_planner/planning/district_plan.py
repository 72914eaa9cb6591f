"""The district search as a search method of the one pipeline (docs/concepts/district.md): its
run returns the same :class:`~ris_planner.planning.outputs.result.PlanResult` as the
enumerating searches', so its plan.json, figures, GIS files, roll-out, sizing, diagnosis and
per-point fields are every plan's.

:func:`run_district` builds the sparse information
(:func:`~ris_planner.planning.scoring.sparse.build_problem`), searches each RIS count
(:func:`~ris_planner.planning.search.district.greedy_path`, swaps, and layouts rounded from
the relaxation's site weights where a count was solved), certifies it
(:mod:`ris_planner.planning.certify.district_lp`, on a thread beside the search: HiGHS
releases the GIL) and, with ``rollout: nested``, extends each
count's nested layout greedily from the previous one. :func:`district_size_rows` answers the
sizing question at each RIS size: the smallest count found to reach the target (the greedy
path's, or fewer by swaps) and the certified lower bound on any layout's count.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.model.plan import Target, target_goal
from ris_planner.model.profiles import block_count
from ris_planner.planning.certify.district_lp import (
    DistrictRelaxation,
    Needs,
    Relaxed,
    build_relaxation,
    sites_needed,
)
from ris_planner.planning.certify.relaxation import Certificate
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.outputs.result import CountResult, PlanResult
from ris_planner.planning.scoring.layout_scorer import pairs_summary
from ris_planner.planning.scoring.sparse import (
    DistrictProblem,
    LayoutState,
    SparseScorer,
    build_problem,
    exact_coverage,
)
from ris_planner.planning.scoring.time_blocks import profile_colours
from ris_planner.planning.search.district import (
    GAIN_TIE,
    SEARCH_SITES,
    SMALL_DISTRICT_SITES,
    PathStep,
    fewer_sites,
    greedy_path,
    improve,
    lp_layouts,
    most_ris,
)
from ris_planner.planning.search.layouts import Layout, SearchOutcome
from ris_planner.planning.search.rollout import NestedStep, rollout_json
from ris_planner.planning.search.sizing import SizeRow
from ris_planner.runtime.executor import Executor
from ris_planner.runtime.progress import ProgressCallback, StageClock, no_progress

BoolArray = NDArray[np.bool_]
CERTIFICATE_METHOD = "district relaxation: non-cover cuts, Lagrangian bound"
Constraints = tuple[tuple[int, ...], tuple[int, ...], BoolArray | None]
"""(required sites, excluded sites, conflict [S, S] or None)."""


def constraints_of(inputs: PlanInputs) -> Constraints:
    """The feasibility the district search honours: required, excluded and conflicting sites
    (spacing, one mounting point)."""
    feas = inputs.feasibility
    required = tuple(int(s) for s in feas.required)
    excluded = tuple(int(s) for s in np.flatnonzero(~feas.allowed))
    return required, excluded, feas.conflict if feas.conflict.any() else None


def level_of(inputs: PlanInputs) -> float:
    """The coverage objective's threshold [m] (the district search plans coverage only: its
    capabilities, :mod:`ris_planner.model.search_methods`)."""
    from ris_planner.model.objectives import objective_kind

    spec = inputs.document.objective
    level = objective_kind(spec.kind).screen_level(spec)
    assert level is not None
    return float(level)


@dataclass(frozen=True)
class DistrictSearch:
    """The district search's state that the sizing question reuses: the information, what the
    search sees, the cover sets and the greedy path already walked."""

    problem: DistrictProblem
    seen: DistrictProblem
    needs: Needs
    path: list[PathStep]
    relaxation: DistrictRelaxation | None = None
    """The plan's relaxation (built on its certificate thread), solved again for the sizing."""
    lower: tuple[float, Future[int | None]] | None = None
    """(goal, its certified lower count) when the plan started the sizing's own-size solve on
    its certificate thread as soon as its counts were certified (:func:`run_district`): it
    runs beside the plan's beams; the sizing takes its answer for that goal."""

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the sizing solve under way (a thread's future)."""
        return {**self.__dict__, "lower": None}


def run_district(
    inputs: PlanInputs,
    progress: ProgressCallback = no_progress,
    clock: StageClock | None = None,
    goal: Target | None = None,
    blocks: int | None = None,
    executor: Executor | None = None,
    sizing: Target | None = None,
) -> PlanResult:
    """The district search's plan run (module docstring): per RIS count the layout of the
    greedy path improved by swaps (or a layout rounded from the relaxation's site weights and
    improved likewise, when better), its exact coverage and the certified upper bound on any
    layout of that count; in target mode the counts up to the first that reaches the target (a
    share of the servable pairs; ``goal``: that target as an objective value, when the caller
    fixed it).

    A designed codebook is built for ``blocks`` = Γ time-orthogonal blocks (default
    ``codebook.blocks``, else :func:`initial_blocks`), fixed before its information, and each
    count's layout is held to Γ − 1 profile colours (:func:`fit_blocks`), so every reported
    layout fits the blocks its information was computed with, built once (a count no refill
    can hold is reported without a layout, saying why). ``executor``: the plan's process pool,
    for the per-RIS SDPs of ``beams`` (:func:`~ris_planner.planning.district_beams.
    district_beams`). ``sizing``: the sizing target when the plan's sizing question will
    reuse this run at the document's RIS size; its certified lower count then solves on the
    certificate thread right after the counts' bounds, beside the colours, the roll-out and
    the beams (:attr:`DistrictSearch.lower`), from the same model state as the sizing stage
    would solve it in: the same answer, earlier."""
    doc = inputs.document
    clock = StageClock() if clock is None else clock
    if blocks is None:
        blocks = doc.codebook.blocks or initial_blocks(doc)
    required, excluded, conflict = cons = constraints_of(inputs)
    share = 1.0 if doc.beams is None else 1.0 - BEAMS_PROGRESS_SHARE

    def on_search(f: float, m: str) -> None:  # the search's share of the run, beams the rest
        progress(share * f, m)

    with clock.stage("cache"):  # the sparse information, what every candidate gives
        on_search(0.0, "information")
        problem = build_problem(inputs, lambda f, m: on_search(0.4 * f, m), blocks=blocks)
        scorer = SparseScorer(problem)
        seen = problem.strongest(SEARCH_SITES)
        needs = sites_needed(problem)
        summary = pairs_summary(scorer, problem.weights, problem.n_sites, problem.threshold)
    counts = [c for c in inputs.counts if c <= problem.n_sites]
    target = doc.objective.target
    if goal is None and target is not None:
        goal = target_goal(doc.objective.kind, target, summary.servable_weight)
    level = goal.min if doc.target_mode and goal is not None else None
    lp = ThreadPoolExecutor(max_workers=1, thread_name_prefix="district-relaxation")
    fitted: list[dict[str, Any]] = []
    colouring: dict[Layout, tuple[int, ...]] = {}
    early: tuple[float, Future[int | None]] | None = None
    try:
        with clock.stage("search"):
            # one model, built and then solved count by count on the thread (in order)
            model = lp.submit(build_relaxation, problem, needs, required, excluded, conflict)
            relaxed = {c: lp.submit(_coverage, model, c) for c in counts}
            on_search(0.5, "path")
            most = most_ris(doc.system.transmissions)
            longest = max(counts) if level is None else max(max(counts), most)
            path = greedy_path(
                seen,
                min(longest, problem.n_sites),
                level,
                required,
                excluded,
                min_count=0 if level is not None else max(counts),
                conflict=conflict,
            )
            on_search(0.7, "swaps")
            found, infeasible = _count_results(problem, seen, path, counts, relaxed, cons, level)
        if problem.codebooks.designed:
            with clock.stage("colours"):  # every layout held to the Γ − 1 profile colours
                on_search(0.8, f"colours: Γ = {blocks} blocks")
                found, fitted, colouring = fit_blocks(problem, seen, found, blocks, cons)
                infeasible += [n["ris_count"] for n in fitted if not n["fits"]]
        # count solves not started are dropped and the one under way ends, as at a shutdown;
        # the counts' certificate as solved, before the sizing's solve adds its rows
        for f in relaxed.values():
            f.cancel()
        wait([f for f in relaxed.values() if not f.cancelled()])
        certificate = _certificate_details(model.result(), relaxed)
        if sizing is not None and found:
            want = target_goal(doc.objective.kind, sizing, summary.servable_weight).min
            if want is not None:
                lower = lp.submit(_lower_count, problem, needs, cons, want, model.result())
                early = (want, lower)
    finally:
        # on failure a solve under way ends first; else the sizing's own solve goes on
        lp.shutdown(wait=early is None, cancel_futures=early is None)
    if not found:
        raise RisPlannerError(no_count_message(counts, fitted, blocks))
    with clock.stage("rollout"):
        rollout = _rollout(doc, seen, problem, found, cons)
    with clock.stage("audible"):
        heard, heard_warning = audible_paths(problem, found)
    timing = time_orthogonal(problem, found, doc.system.transmissions, blocks, colouring)
    if problem.codebooks.designed:
        timing["held_to_blocks"] = fitted
    on_search(1.0, "done")
    result = PlanResult(
        doc,
        inputs.sites,
        inputs.tx_map,
        inputs.rx_map,
        inputs.pairs,
        scorer,
        found,
        clock.seconds,
        scene=inputs.scene,
        dropped_points=inputs.dropped,
        feasibility=inputs.feasibility,
        infeasible_counts=tuple(infeasible),
        rollout=rollout,
        pairs_summary=summary,
        choice=inputs.choice,
        search_details={
            "path": [{"ris_count": len(p.sites), "coverage": p.coverage} for p in path],
            "search_sites_per_pair": SEARCH_SITES,
            "pairs_with_cover_sets": int(needs.complete.sum()),
            "serving_sites_per_pair": float(np.diff(problem.pair_start).mean())
            if problem.n_pairs
            else 0.0,
            "entries": problem.n_entries,
            "time_orthogonal": timing,
            "audible_paths": heard,
            "codebook": codebook_json(problem),
            "certificate": certificate,
        },
        sizing_state=DistrictSearch(problem, seen, needs, path, model.result(), early),
        site_warnings=[heard_warning] if heard_warning else None,
    )
    if doc.beams is not None:  # the layouts' beams and power (one SDP over the slot powers)
        from ris_planner.planning.district_beams import district_beams

        with clock.stage("beams"):
            on_beams = lambda f, m: progress(share + (1.0 - share) * f, m)  # noqa: E731
            result = replace(result, beams=district_beams(result, inputs, on_beams, executor))
    return replace(result, timing=dict(clock.seconds))


BEAMS_PROGRESS_SHARE = 0.35
"""The share of a district run's progress bar its ``beams`` stage takes (the designed-beam plan
of docs/validation/benchmarks.md: beams 86 s after 156 s of information and search)."""


def no_count_message(counts: list[int], fitted: list[dict[str, Any]], blocks: int) -> str:
    """Why a district plan has no count to report: no layout of a designed plan's counts could
    be held to the Γ − 1 profile colours (:func:`fit_blocks`), or the greedy path reached none
    of them (no further site adds information)."""
    unheld = [n for n in fitted if not n["fits"]]
    if unheld:
        need = max(n["colours"] for n in unheld)
        return (
            f"no layout of {counts} RISs fits the {blocks - 1} profile colours of the designed"
            f" codebook's Γ = {blocks} blocks (the searched layouts need up to {need}, and no"
            " refill could hold them): set codebook.blocks to a larger divisor of"
            " system.transmissions, or plan fewer RISs"
        )
    return (
        f"no layout of {counts} RISs: the search's greedy path stops before the smallest count"
        " (no further candidate adds information to any pair); plan fewer RISs"
    )


AUDIBLE_WARNING_SHARE = 0.8
"""The plan warns when the largest count's coverage counting audible paths only is below this
share of its coverage (:func:`audible_paths`)."""


def audible_paths(
    problem: DistrictProblem, found: list[CountResult]
) -> tuple[dict[str, Any], str | None]:
    """plan.json ``search_details.audible_paths``: per count the layout's coverage and its
    coverage counting only the audible RIS paths (integrated SNR over the whole pilot at least
    :data:`~ris_planner.planning.scoring.sparse.AUDIBLE_SNR_DB`:
    :meth:`~ris_planner.planning.scoring.sparse.DistrictProblem.audible_only`), and the share
    of (pair, site) entries that are audible; with a warning when the largest count's covered
    weight rests mostly on the rest (:data:`AUDIBLE_WARNING_SHARE`). The bound counts every
    path, as ``compute_bounds`` does; the estimator cannot detect a path below the noise."""
    from ris_planner.planning.scoring.sparse import AUDIBLE_SNR_DB

    audible = problem.audible_only()
    rows = [
        {
            "ris_count": cr.ris_count,
            "coverage": -cr.ranked[0][1],
            "audible_only": LayoutState(audible, list(cr.ranked[0][0])).coverage(),
        }
        for cr in found
    ]
    details = {
        "snr_db": AUDIBLE_SNR_DB,
        "audible_entries_share": audible.n_entries / max(problem.n_entries, 1),
        "by_count": rows,
    }
    last = rows[-1] if rows else None
    if last is None or last["audible_only"] >= AUDIBLE_WARNING_SHARE * last["coverage"]:
        return details, None
    warning = (
        f"at {last['ris_count']} RISs the layout covers {last['coverage']:.3f} of the pairs'"
        f" weight, {last['audible_only']:.3f} counting only RIS paths heard above the noise over"
        f" the whole pilot (integrated SNR ≥ {AUDIBLE_SNR_DB:g} dB): the rest rests on paths"
        " below it, whose information the bound counts as compute_bounds does but which the"
        " estimator cannot detect (search_details.audible_paths; docs/concepts/"
        "district-physics.md, Audible paths)"
    )
    return details, warning


def _coverage(model: Future[DistrictRelaxation], count: int) -> Relaxed:
    """One count's certified bound, on the certificate thread after the model's build."""
    return model.result().coverage(count)


def _certificate_details(
    model: DistrictRelaxation, relaxed: dict[int, Future[Relaxed]]
) -> dict[str, Any]:
    """plan.json ``search_details.certificate``: the relaxation's size and, per count, its
    certified bound, the solver's own value, status, seconds and the rounds of separated cuts
    (with the rows they added)."""
    done = {c: f.result() for c, f in relaxed.items() if f.done() and not f.cancelled()}
    return {
        "model": model.size,
        "by_count": [
            {
                "ris_count": c,
                "bound": r.bound,
                "lp_value": r.lp_value,
                "status": r.status,
                "seconds": r.seconds,
                "cut_rounds": r.cut_rounds,
                "separated_rows": r.separated_rows,
            }
            for c, r in sorted(done.items())
        ],
    }


def _count_results(
    problem: DistrictProblem,
    seen: DistrictProblem,
    path: list[PathStep],
    counts: list[int],
    relaxed: dict[int, Future[Relaxed]],
    cons: Constraints,
    goal: float | None,
) -> tuple[list[CountResult], list[int]]:
    """Each count's :class:`CountResult` (the searched layout re-scored with every serving
    site, its certificate) and the counts the path never reached (no site adds information).
    Each count also tries layouts rounded from the relaxation's site weights (its own, or on a
    count answered from earlier multipliers those of the last count solved)."""
    required, excluded, conflict = cons
    small = problem.n_sites <= SMALL_DISTRICT_SITES
    rounds = 3 if small else 1
    out: list[CountResult] = []
    missing: list[int] = []
    weights: NDArray[np.float64] | None = None  # the site weights of the last count solved
    for c in counts:
        step = next((p for p in path if len(p.sites) == c), None)
        if step is None:
            missing.append(c)
            continue
        layout, cov = improve(seen, step.sites, required, excluded, rounds, conflict)
        found_by = "greedy path and swaps"
        cert = relaxed[c].result()
        ub = cert.bound
        if cert.lp_value is not None:
            weights = cert.z
        if weights is not None:  # layouts rounded from the relaxation, improved likewise
            rounded = lp_layouts(weights, c, required, excluded, conflict)
            starts = _lp_starts(seen, rounded, small)
            for start, how in starts:
                other, other_cov = improve(seen, start, required, excluded, rounds, conflict)
                if other_cov > cov + GAIN_TIE:
                    layout, cov = other, other_cov
                    found_by = f"{how} and swaps"
        out.append(count_result(problem, layout, ub, found_by))
        if goal is not None and -out[-1].ranked[0][1] >= goal - 1e-12:
            break  # target mode: the smallest count that reaches the target
    return out, missing


def _lp_starts(
    seen: DistrictProblem, starts: list[tuple[tuple[int, ...], str]], small: bool
) -> list[tuple[tuple[int, ...], str]]:
    """The roundings the swaps start from: on a small district the top-L one and the best
    randomized one (by the coverage the search sees), on a larger one only the best of all
    (each swap pass re-scores every pair of the layout's sites)."""
    if not starts:
        return []
    scored = [LayoutState(seen, list(lay)).coverage() for lay, _ in starts]
    if not small:
        return [starts[int(np.argmax(scored))]]
    rest = scored[1:]
    return starts[:1] + ([starts[1 + int(np.argmax(rest))]] if rest else [])


def fit_blocks(
    problem: DistrictProblem,
    seen: DistrictProblem,
    found: list[CountResult],
    blocks: int,
    cons: Constraints,
) -> tuple[list[CountResult], list[dict[str, Any]], dict[Layout, tuple[int, ...]]]:
    """Each count's layout held to the Γ − 1 profile colours of the ``blocks`` its designed
    information was computed with (:func:`~ris_planner.planning.search.colour_fit.
    fit_colours`), re-scored; plan.json ``time_orthogonal.held_to_blocks``: per count whose
    layout needed more colours the sites taken out and put in and the coverage before and
    after (``fits`` false, with the colours it needs, where no refill could hold it: that
    count is left out of the results, an infeasible count); and each held layout's colouring
    (the one the fit built: DSatur run again could need more)."""
    from ris_planner.planning.scoring.time_blocks import audible_incidence
    from ris_planner.planning.search.colour_fit import fit_colours

    required, excluded, conflict = cons
    heard = audible_incidence(problem)
    out: list[CountResult] = []
    notes: list[dict[str, Any]] = []
    colouring: dict[Layout, tuple[int, ...]] = {}
    for cr in found:
        layout = cr.ranked[0][0]
        fit = fit_colours(problem, seen, layout, blocks - 1, required, excluded, conflict, heard)
        if not fit.fits:
            need = int(max(fit.colour)) + 1
            notes.append({"ris_count": cr.ris_count, "fits": False, "colours": need})
            continue
        colouring[fit.layout] = fit.colour
        if not fit.removed:
            out.append(cr)
            continue
        bound = -cr.certificate.loss_bound if cr.certificate is not None else 1.0
        found_by = f"{cr.found_by}, held to {blocks - 1} profile colours"
        new = count_result(problem, fit.layout, bound, found_by)
        out.append(new)
        notes.append(
            {
                "ris_count": cr.ris_count,
                "fits": True,
                "removed": list(fit.removed),
                "added": list(fit.added),
                "coverage_before": -cr.ranked[0][1],
                "coverage_after": -new.ranked[0][1],
            }
        )
    return out, notes, colouring


INITIAL_COLOURS = 5
"""Profile colours a designed codebook's blocks are first built for (Γ ≥ 6: G̃ = 32 beams
per block at G = 192): on the street districts of docs/validation/benchmarks.md a pair hears at
most a few RISs of a layout, and the conflict graph's colourings stay within it; a layout that
needs more is held to them (:func:`fit_blocks`)."""


def initial_blocks(doc: Any) -> int:
    """Γ a designed codebook is first built for: the smallest divisor of G above
    :data:`INITIAL_COLOURS` (fewer when G is small)."""
    g = doc.system.transmissions
    colours = min(INITIAL_COLOURS, g - 1)
    return block_count(g, colours)


def time_orthogonal(
    problem: DistrictProblem,
    found: list[CountResult],
    transmissions: int,
    blocks: int,
    colouring: dict[Layout, tuple[int, ...]] | None = None,
) -> dict[str, Any]:
    """plan.json ``search_details.time_orthogonal``: per count the profile colours its layout
    needs and each RIS's colour (the column of B it takes after the LOS's: the held
    ``colouring`` of a designed plan's layout, else DSatur's), the Γ they need (the largest
    over the counts) and the Γ a designed codebook was built for with its beams per block."""
    rows: list[dict[str, Any]] = []
    for cr in found:
        layout = cr.ranked[0][0]
        held = (colouring or {}).get(tuple(sorted(layout)))
        colour = profile_colours(problem, layout) if held is None else np.array(held)
        n = int(colour.max()) + 1 if colour.size else 0
        rows.append(
            {
                "ris_count": cr.ris_count,
                "colours": n,
                "blocks_needed": block_count(transmissions, n),
                "colour_of_site": {str(s): int(c) for s, c in zip(layout, colour, strict=True)},
            }
        )
    needed = max((r["blocks_needed"] for r in rows), default=block_count(transmissions, 1))
    designed = problem.codebooks.designed
    used = max(blocks, needed) if designed else needed
    return {
        "blocks": used,
        "beams_per_block": transmissions // used,
        "blocks_needed": needed,
        "designed_for": blocks if designed else None,
        "counts": rows,
    }


def codebook_json(problem: DistrictProblem) -> dict[str, Any]:
    """plan.json ``search_details.codebook``: the codebook each site's information was
    computed with (its kind, Γ, beams per block, the slots' powers for a designed one)."""
    cb = problem.codebooks
    if not cb.designed:
        return {"kind": cb.kind}
    return {
        "kind": cb.kind,
        "blocks": cb.blocks,
        "beams_per_block": int(cb.powers.size),
        "slot_powers": [float(x) for x in cb.powers],
        "beam_types": [int(t) for t in cb.beam_types],
    }


def count_result(
    problem: DistrictProblem, layout: Layout, bound: float, found_by: str
) -> CountResult:
    """One count's result from its layout (re-scored exactly, every serving site) and the
    certified upper bound on any layout of that count."""
    layout = tuple(sorted(int(s) for s in layout))
    state = LayoutState(problem, list(layout))
    cov = state.coverage()
    loss = -cov
    outcome = SearchOutcome(
        np.array([layout], dtype=np.int64),
        np.array([loss]),
        method="district",
        total_layouts=math.comb(problem.n_sites, len(layout)),
    )
    cert = Certificate(-max(bound, cov), exact=False, method=CERTIFICATE_METHOD)
    return CountResult(
        len(layout),
        outcome,
        [(layout, loss)],
        state.metric,
        certificate=cert,
        found_by=found_by,
    )


def _rollout(
    doc: Any,
    seen: DistrictProblem,
    problem: DistrictProblem,
    found: list[CountResult],
    cons: Constraints,
) -> dict[str, Any]:
    """plan.json ``rollout``: with ``nested`` each count's layout the greedy extension of the
    previous count's nested one (the first is the free one), priced against the free layout
    – a designed plan's held to its Γ − 1 profile colours like the free layouts, the previous
    count's sites kept (:func:`~ris_planner.planning.search.colour_fit.fit_colours`; no nested
    layout where that cannot hold it); in free mode the free layouts only."""
    from ris_planner.planning.search.colour_fit import fit_colours

    required, excluded, conflict = cons
    free = [(cr.ris_count, cr.ranked[0][0], cr.ranked[0][1]) for cr in found]
    if doc.rollout != "nested":
        note = 'the nested chain is searched with rollout "nested"'
        return rollout_json(doc.rollout, doc.objective, free, None, note)
    steps: list[NestedStep] = []
    for i, (count, lay, loss) in enumerate(free):
        if i == 0:
            steps.append(NestedStep(count, lay, loss, "free", 0))
            continue
        prev = steps[-1].layout or ()
        grown = greedy_path(seen, count, None, tuple(prev), excluded, conflict=conflict)
        nested = grown[-1].sites if grown and len(grown[-1].sites) == count else None
        if nested is not None and problem.codebooks.designed:
            kept = tuple(sorted({*prev, *required}))
            colours = problem.codebooks.blocks - 1
            fit = fit_colours(problem, seen, nested, colours, kept, excluded, conflict)
            nested = fit.layout if fit.fits else None
        if nested is None:
            steps.append(NestedStep(count, None, math.inf, "district greedy", 0))
            continue
        nested_loss = -LayoutState(problem, list(nested)).coverage()
        steps.append(NestedStep(count, tuple(nested), nested_loss, "district greedy", 0))
    return rollout_json("nested", doc.objective, free, steps)


def district_size_rows(
    inputs: PlanInputs,
    state: DistrictSearch,
    sizes: list[tuple[int, int]],
    goal: float,
    progress: ProgressCallback = no_progress,
) -> list[SizeRow]:
    """The sizing question at each RIS size (ascending element count): the smallest count
    found to reach ``goal`` (an objective value: a share of the servable pairs' weight) – the
    greedy path's, or fewer by swaps on the path's layouts (:func:`_size_row`) – and the
    certified lower bound on any layout's count; a size whose lower bound
    already needs more elements than the answer so far is skipped, one that cannot reach the
    goal with every candidate says so. The other sizes' information shares the document's
    visibility; their lower bounds solve on a thread beside their paths."""
    doc = inputs.document
    required, excluded, conflict = cons = constraints_of(inputs)
    own = (doc.ris.rows, doc.ris.cols)
    lp = ThreadPoolExecutor(max_workers=1, thread_name_prefix="district-sizing")
    rows: list[SizeRow] = []
    best: int | None = None  # elements of the answer so far
    try:
        for k, (r, c) in enumerate(sizes):
            progress(k / len(sizes), f"sizing: {r}×{c}")
            model: Any = state.relaxation
            if (r, c) == own:
                pr, seen, nd, steps = state.problem, state.seen, state.needs, state.path
            else:
                model = None

                def on_build(f: float, m: str, k: int = k, r: int = r, c: int = c) -> None:
                    progress((k + 0.5 * f) / len(sizes), f"sizing {r}×{c}: {m}")

                blocks = state.problem.codebooks.blocks
                pr = build_problem(_resized(inputs, r, c), on_build, state.problem, blocks)
                seen, nd, steps = pr.strongest(SEARCH_SITES), sites_needed(pr), []
            if (r, c) == own and state.lower is not None and state.lower[0] == goal:
                lower: Callable[[], int | None] = state.lower[1].result  # under way already
            else:
                lower = lp.submit(
                    _lower_count, pr, nd, cons, goal, model if (r, c) == own else None
                ).result
            if not steps or steps[-1].coverage < goal:
                steps = greedy_path(
                    seen,
                    min(most_ris(doc.system.transmissions), pr.n_sites),
                    goal,
                    required,
                    excluded,
                    conflict=conflict,
                )
            # the descent below the path's answer runs while the lower bound solves
            tried = fewer_sites(pr, seen, steps, goal, required, excluded, conflict)
            lb = lower()
            row = _size_row((r, c), pr, seen, steps, goal, lb, best, tried)
            if pr.codebooks.designed and row.sites is not None:
                row = _held_size_row(pr, seen, row, goal, cons)
            rows.append(replace(row, coverable=float(pr.weights[nd.need > 0].sum())))
            row = rows[-1]
            if row.count is not None and (best is None or r * c * row.count < best):
                best = r * c * row.count
    finally:
        lp.shutdown(wait=False, cancel_futures=True)
    return rows


def _lower_count(
    problem: DistrictProblem,
    needs: Needs,
    cons: Constraints,
    goal: float,
    model: DistrictRelaxation | None,
) -> int | None:
    """The certified lower count of one RIS size: its relaxation (the plan's own model at the
    document's size) solved for the fewest sites reaching ``goal``."""
    if float(problem.weights[needs.need > 0].sum()) < goal - 1e-12:
        return None  # known before any model: the coverable pairs weigh less
    if model is None:
        model = build_relaxation(problem, needs, *cons)
    return model.lower_count(goal)


def _size_row(
    size: tuple[int, int],
    problem: DistrictProblem,
    seen: DistrictProblem,
    steps: list[PathStep],
    goal: float,
    lower: int | None,
    best: int | None,
    fewer: list[tuple[tuple[int, ...], float]],
) -> SizeRow:
    """One RIS size's answer: the greedy path's first layout that reaches ``goal``, or a
    smaller one of ``fewer`` (the path's layouts improved by swaps:
    :func:`~ris_planner.planning.search.district.fewer_sites`); ``counts`` lists the path's
    layout and each count tried below it."""
    r, c = size
    if lower is None:
        return SizeRow(size, None, None, note="not reachable: every candidate together covers less")
    if best is not None and lower * r * c >= best:
        note = f"skipped: at least {lower} RISs, not fewer elements than the answer"
        return SizeRow(size, None, lower, note=note)
    hit = next((p for p in steps if p.coverage >= goal - 1e-12), None)
    if hit is None:
        note = f"the greedy path stops at {len(steps)} RISs below the target"
        return SizeRow(size, None, lower, note=note)
    cov = exact_coverage(problem, hit.sites) if seen is not problem else hit.coverage
    tried = [(tuple(hit.sites), cov, "greedy path")]
    tried += [(lay, got, "greedy path and swaps") for lay, got in fewer]
    counts = tuple(
        {
            "count": len(lay),
            "objective": got,
            "reaches": got >= goal - 1e-12,
            "objective_bound": None,
            "found_by": how,
        }
        for lay, got, how in tried
    )
    sites, cov, how = min((t for t in tried if t[1] >= goal - 1e-12), key=lambda t: len(t[0]))
    said = None if how == "greedy path" else f"{how}; the path alone: {len(hit.sites)} RISs"
    return SizeRow(size, len(sites), lower, cov, sites, note=said, counts=counts)


def _held_size_row(
    problem: DistrictProblem, seen: DistrictProblem, row: SizeRow, goal: float, cons: Constraints
) -> SizeRow:
    """A designed plan's sizing answer held to the Γ − 1 profile colours its information was
    computed with (:func:`~ris_planner.planning.search.colour_fit.fit_colours`): the held
    layout when it still reaches ``goal``, else no count, saying why."""
    from ris_planner.planning.search.colour_fit import fit_colours

    assert row.sites is not None and row.count is not None
    colours = problem.codebooks.blocks - 1
    fit = fit_colours(problem, seen, row.sites, colours, *cons)
    if not fit.removed:
        return row if fit.fits else _unheld(problem, row, colours)
    cov = LayoutState(problem, list(fit.layout)).coverage()
    if cov < goal - 1e-12:
        return _unheld(problem, row, colours)
    note = f"held to {colours} profile colours: {len(fit.removed)} sites exchanged"
    return replace(row, sites=fit.layout, objective=cov, note=note)


def _unheld(problem: DistrictProblem, row: SizeRow, colours: int) -> SizeRow:
    assert row.sites is not None
    need = int(profile_colours(problem, row.sites).max()) + 1
    note = (
        f"the greedy path reaches the target at {row.count} RISs with {need} profile colours,"
        f" more than the Γ − 1 = {colours} its designed information was computed with"
    )
    return replace(row, count=None, objective=None, sites=None, note=note)


def _resized(inputs: PlanInputs, rows: int, cols: int) -> PlanInputs:
    """The same plan with every candidate a ``rows`` × ``cols`` RIS."""
    ris = inputs.document.ris.model_copy(update={"rows": rows, "cols": cols})
    sites = [
        replace(s, ris=s.ris.model_copy(update={"rows": rows, "cols": cols})) for s in inputs.sites
    ]
    return replace(inputs, sites=sites, document=inputs.document.model_copy(update={"ris": ris}))


def district_state(inputs: PlanInputs, progress: ProgressCallback = no_progress) -> DistrictSearch:
    """The :class:`DistrictSearch` of prepared inputs, no path walked (the sizing question of a
    plan whose own search was another method)."""
    problem = build_problem(
        inputs, progress, blocks=inputs.document.codebook.blocks or initial_blocks(inputs.document)
    )
    return DistrictSearch(problem, problem.strongest(SEARCH_SITES), sites_needed(problem), [])
