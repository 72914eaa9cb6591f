"""Search methods bound to the code that runs them (docs/concepts/planning.md, "Search
methods"): each name of :mod:`ris_planner.model.search_methods` – where its capabilities are
declared – maps to a :class:`Strategy`, the pipeline's one dispatch
(:func:`ris_planner.planning.pipeline.run_plan`), as scipy.optimize's ``minimize`` dispatches on
``method`` and cvxpy looks a solver up in its registry.

A strategy runs one plan over prepared inputs and returns the one result type
(:class:`~ris_planner.planning.outputs.result.PlanResult`; the pipeline's later stages –
sweep, sizing, diagnosis, validation, per-point fields, summary – are every method's), and
answers the sizing question at a ladder of RIS sizes (:class:`~ris_planner.planning.search.
sizing.SizeRow`). A new method registers its :class:`~ris_planner.model.search_methods.
SearchMethod` and its strategy with :func:`register`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from ris_planner.model.plan import Target
from ris_planner.model.search_methods import (
    AUTO,
    SearchMethod,
    search_method,
)
from ris_planner.model.search_methods import register as register_method
from ris_planner.planning.enumerating import run_enumerating
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.outputs.result import PlanResult
from ris_planner.planning.search.sizing import SizeRow
from ris_planner.runtime.executor import Executor
from ris_planner.runtime.progress import ProgressCallback, StageClock

if TYPE_CHECKING:
    from ris_planner.planning.search.sizing import RunCounts


class Strategy(Protocol):
    """The code of a search method."""

    def run(
        self,
        inputs: PlanInputs,
        progress: ProgressCallback,
        executor: Executor,
        clock: StageClock,
        background_checks: bool = False,
        goal: Target | None = None,
    ) -> PlanResult:
        """One plan run over prepared inputs: every RIS count searched (in target mode up to
        the first that meets ``goal``, else the document's target), certified where the
        method certifies, with its roll-out. ``background_checks``: checks may run on a thread
        (the result's ``pending_checks``)."""
        ...

    def size_rows(
        self,
        base: PlanResult | None,
        inputs: PlanInputs,
        sizes: Sequence[tuple[int, int]],
        goal: Target,
        progress: ProgressCallback,
        executor: Executor,
        run_counts: RunCounts,
    ) -> list[SizeRow]:
        """The sizing question at each RIS size (ascending element count): the smallest count
        found to reach ``goal`` and the certified lower bound where the method has one.
        ``base``: the plan's own run when it used this method (its work is reused);
        ``run_counts``: the pipeline's plan run at one size in target mode."""
        ...


@dataclass(frozen=True)
class Enumerating:
    """``auto``, ``exhaustive``, ``greedy``: layouts scored on the site cache
    (:func:`~ris_planner.planning.enumerating.run_enumerating`)."""

    def run(
        self,
        inputs: PlanInputs,
        progress: ProgressCallback,
        executor: Executor,
        clock: StageClock,
        background_checks: bool = False,
        goal: Target | None = None,
    ) -> PlanResult:
        return run_enumerating(inputs, progress, executor, clock, background_checks, goal)

    def size_rows(
        self,
        base: PlanResult | None,
        inputs: PlanInputs,
        sizes: Sequence[tuple[int, int]],
        goal: Target,
        progress: ProgressCallback,
        executor: Executor,
        run_counts: RunCounts,
    ) -> list[SizeRow]:
        from ris_planner.planning.search.sizing import enumerating_size_rows

        first = min(inputs.document.sizing_counts())
        return enumerating_size_rows(sizes, goal, first, run_counts, progress)


@dataclass(frozen=True)
class District:
    """``district``: sparse information, greedy path and swaps, the relaxation's certificate
    (:func:`~ris_planner.planning.district_plan.run_district`)."""

    def run(
        self,
        inputs: PlanInputs,
        progress: ProgressCallback,
        executor: Executor,
        clock: StageClock,
        background_checks: bool = False,
        goal: Target | None = None,
    ) -> PlanResult:
        # on first use: an enumerating plan's start-up does not import the LP solver
        from ris_planner.planning.district_plan import run_district

        doc = inputs.document
        reused = (  # the sizing stage will reuse this run at the document's size
            doc.sizing is not None
            and strategy_for(doc.sizing.method) is self
            and inputs.choice is not None
            and strategy_for(inputs.choice.used) is self
        )
        sizing = doc.sizing_target() if reused else None
        return run_district(inputs, progress, clock, goal, executor=executor, sizing=sizing)

    def size_rows(
        self,
        base: PlanResult | None,
        inputs: PlanInputs,
        sizes: Sequence[tuple[int, int]],
        goal: Target,
        progress: ProgressCallback,
        executor: Executor,
        run_counts: RunCounts,
    ) -> list[SizeRow]:
        from ris_planner.planning.district_plan import district_size_rows, district_state

        state = base.sizing_state if base is not None else None
        if state is None:
            state = district_state(inputs, progress)
        assert goal.min is not None, "the district search plans coverage (a min target)"
        return district_size_rows(inputs, state, list(sizes), goal.min, progress)


_STRATEGIES: dict[str, Strategy] = {
    AUTO: Enumerating(),
    "exhaustive": Enumerating(),
    "greedy": Enumerating(),
    "district": District(),
}


def register(method: SearchMethod, strategy: Strategy) -> None:
    """Register a search method: its declared capabilities
    (:func:`ris_planner.model.search_methods.register`) and its code."""
    register_method(method)
    _STRATEGIES[method.name] = strategy


def unregister(name: str) -> None:
    """Remove a registered method (tests that add a toy method)."""
    from ris_planner.model.search_methods import unregister as unregister_method

    unregister_method(name)
    _STRATEGIES.pop(name, None)


def strategy_for(method: str) -> Strategy:
    """The strategy of ``search.method`` (``auto``: the enumerating searches')."""
    if method != AUTO:
        search_method(method)  # a ValueError naming the known ones
    try:
        return _STRATEGIES[method]
    except KeyError:
        raise ValueError(f"search method {method!r} is declared but has no strategy") from None
