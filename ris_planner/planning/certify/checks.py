"""The checks stage of a plan (docs/concepts/planning.md, "Pipeline"): each count's
certificate (exhaustive optimum, branch-and-bound, or the Frank–Wolfe relaxation bound) and
the re-evaluation of its best layout with ``random`` codebooks beside the expected-random
objective the search used."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import finite_or_none
from ris_planner.model.plan import Objective, PlanDocument
from ris_planner.model.scenario import RandomCodebook, Scenario
from ris_planner.planning.beams import layout_scenario, objective_on_pairs
from ris_planner.planning.certify.branch_bound import BranchBoundOutcome
from ris_planner.planning.certify.relaxation import Certificate, relaxation_certificate
from ris_planner.planning.inputs.sites import Site
from ris_planner.planning.inputs.ue_maps import PairSet
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.scoring.visibility import Visibility
from ris_planner.planning.search.layouts import Layout, SearchOutcome

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
T = TypeVar("T")

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
    """Executor task: a relaxation bound (:func:`~ris_planner.planning.certify.relaxation.
    relaxation_certificate`) or one codebook evaluation (:func:`objective_task`)."""
    kind, args = task
    if kind == "certificate":
        return relaxation_certificate(scorer, *args)
    return objective_task(None, args)


ObjectiveTask = tuple[
    Scenario, FloatArray, FloatArray, FloatArray, Objective, bool, dict[str, BoolArray] | None
]
"""(scenario, tx [P, 3], rx [P, 3], weights [P], objective, mirror, the pairs' paths or None)
of :func:`objective_task`."""


def objective_task(_shared: object, task: ObjectiveTask) -> float:
    """Executor task: :func:`~ris_planner.planning.beams.objective_on_pairs`."""
    scenario, tx, rx, w, objective, mirror, presence = task
    return objective_on_pairs(scenario, tx, rx, w, objective, mirror, presence=presence)


def random_codebook_tasks(
    doc: PlanDocument,
    sites: list[Site],
    pairs: PairSet,
    layout: Layout,
    mirror: bool = False,
    seeds: int = RANDOM_CODEBOOK_SEEDS,
    visibility: Visibility | None = None,
) -> list[ObjectiveTask]:
    """The evaluations that re-score ``layout``'s objective with other codebooks (summed up by
    :func:`random_codebook_summary`): the expected-random codebook, then ``random`` codebooks of
    seeds 0 … seeds−1, on ≤ ``RANDOM_CODEBOOK_MAX_PAIRS`` pairs drawn ∝ weight.
    ``visibility``: the plan's
    (:func:`~ris_planner.planning.scoring.visibility.pair_visibility`, the same rules as
    ``compute_bounds``' own): each task takes its paths from it instead of walking the legs
    again."""
    tx, rx, w = pairs.tx, pairs.rx, pairs.weights
    pick = np.arange(pairs.size)
    if pairs.size > RANDOM_CODEBOOK_MAX_PAIRS:
        pick = np.random.default_rng(0).choice(pairs.size, RANDOM_CODEBOOK_MAX_PAIRS, p=w / w.sum())
        tx, rx = tx[pick], rx[pick]
        w = np.full(pick.size, 1.0 / pick.size)
    presence = None
    if visibility is not None:
        los = visibility.los[pick] if visibility.los is not None else np.zeros(pick.size, bool)
        presence = {"los": los} | {
            f"ris{j + 1}": visibility.present[s][pick] for j, s in enumerate(layout)
        }
    base = layout_scenario(doc.system, [sites[s].ris for s in layout], doc.known, doc.environment)
    return [
        (
            base if seed < 0 else base.model_copy(update={"codebook": RandomCodebook(seed=seed)}),
            tx,
            rx,
            w,
            doc.objective,
            mirror,
            presence,
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
        "expected": finite_or_none(values[0]),
        "mean": finite_or_none(float(v.mean())),
        "min": finite_or_none(float(v.min())),
        "max": finite_or_none(float(v.max())),
    }


class PendingChecks(Generic[T]):
    """The checks stage running on a thread beside the stages after it (:func:`start_checks`).

    A plan too small for the worker pool ran its checks – the random codebooks' [3G̃, N] @
    [N, P] products and phase draws, in BLAS and numpy's ``exp``, which release the GIL – in
    this process after the search, with the fields and the figures (mostly Python) waiting
    behind them on one core. On a thread they run beside those stages, on the second core
    (a city block: 7.3 → 5.1 s, docs/validation/benchmarks.md). The answers are the same
    (the same tasks, the same code; :mod:`ris_planner.runtime.kernels` keeps the compiled
    kernels one at a time). :meth:`settle` takes the tasks the thread has not started yet
    itself – the caller has nothing else to do by then, so the checks' tail runs on both
    cores – and waits for the thread's last one; :meth:`cancel` stops the thread after its
    current task."""

    def __init__(
        self,
        scorer: Scorer,
        tasks: list[PlanCheck],
        finish: Callable[[list[Any]], T],
    ) -> None:
        self._stop = threading.Event()
        self._finish = finish
        self._scorer = scorer
        self._tasks = tasks
        self._values: list[Any] = [None] * len(tasks)
        self._next = 0
        self._lock = threading.Lock()
        pool = ThreadPoolExecutor(1, thread_name_prefix="plan-checks")
        self._future = pool.submit(self._work)
        pool.shutdown(wait=False)  # the thread ends with its one task

    def _take(self) -> int | None:
        """The index of the next task nobody has started, or ``None`` when all have been."""
        with self._lock:
            if self._stop.is_set():
                raise RuntimeError("plan checks cancelled")
            if self._next >= len(self._tasks):
                return None
            self._next += 1
            return self._next - 1

    def _work(self) -> None:
        """Run tasks until none is left (the thread, then also :meth:`settle`'s caller)."""
        while (i := self._take()) is not None:
            self._values[i] = plan_check_task(self._scorer, self._tasks[i])

    def settle(self) -> T:
        """``finish`` of the checks' answers – every count with its checks: runs the tasks the
        thread has not started here, then waits for the thread (its error is raised here)."""
        try:
            self._work()
        except BaseException:
            self._stop.set()  # the thread stops after its current task
            raise
        self._future.result()
        return self._finish(self._values)

    def cancel(self) -> None:
        """Stop after the current task (the plan failed or was cancelled meanwhile)."""
        self._stop.set()


@contextmanager
def cancelled_on_error(pending: PendingChecks[Any] | None) -> Iterator[None]:
    """Run the block; if it raises, stop ``pending``'s thread (:meth:`PendingChecks.cancel`)
    before the error goes on. ``None``: no checks pending, nothing to stop."""
    try:
        yield
    except BaseException:
        if pending is not None:
            pending.cancel()
        raise
