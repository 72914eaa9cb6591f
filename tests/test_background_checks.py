"""A plan's checks on a thread beside the later stages (interactive planning of a city block):
the same answers as in line, plan.json only once they are in, a failed stage stops the thread,
and numba's parallel kernels one at a time (its workqueue layer aborts on concurrent
launches)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest
from test_plan_timing import timed_plan
from tolerance import assert_close
from waits import HANG_S

from ris_planner.planning import pipeline
from ris_planner.planning.certify.checks import plan_check_task
from ris_planner.planning.enumerating import run_enumerating
from ris_planner.planning.outputs.result import PlanResult
from ris_planner.planning.pipeline import run_plan, settle_checks
from ris_planner.planning.prepare import prepare_plan
from ris_planner.runtime.executor import SerialExecutor
from ris_planner.runtime.progress import no_progress

ROOT = Path(__file__).resolve().parents[1]


def checks_of(result: PlanResult) -> list[tuple[object, ...]]:
    """Each count's random-codebook summary and certificate."""
    return [
        (cr.ris_count, cr.random_codebook, cr.certificate and cr.certificate.loss_bound)
        for cr in result.counts
    ]


def test_checks_on_a_thread_give_the_in_line_answers() -> None:
    doc = timed_plan()
    inline = run_enumerating(prepare_plan(doc), no_progress, SerialExecutor())
    assert inline.pending_checks is None
    background = run_enumerating(
        prepare_plan(doc), no_progress, SerialExecutor(), background_checks=True
    )
    assert background.pending_checks is not None  # they did run on the thread
    assert all(cr.random_codebook is None for cr in background.counts)
    settled = settle_checks(background)
    assert settled.pending_checks is None
    got, want = checks_of(settled), checks_of(inline)
    assert [g[0] for g in got] == [w[0] for w in want]
    for (count, g_cb, g_cert), (_, w_cb, w_cert) in zip(got, want, strict=True):
        assert isinstance(g_cb, dict) and isinstance(w_cb, dict)
        assert_close(g_cb, w_cb, where=f"random codebooks of {count} RISs")
        assert_close(g_cert, w_cert, where=f"certificate of {count} RISs")
    # the layouts and objectives are the search's: untouched by where the checks ran
    ranked = [[[list(lay), v] for lay, v in cr.ranked] for cr in settled.counts]
    assert_close(ranked, [[[list(lay), v] for lay, v in cr.ranked] for cr in inline.counts])


def test_plan_json_waits_for_the_checks() -> None:
    result = run_plan(timed_plan(), executor=SerialExecutor(), settle=False)
    assert result.pending_checks is not None
    with pytest.raises(ValueError, match="settle_checks"):
        result.to_json()
    done = settle_checks(result)
    plan = done.to_json()
    assert all(entry["random_codebook"] is not None for entry in plan["by_count"])


def test_a_failed_stage_stops_the_checks(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fields stage fails at once: the checks' thread stops after its current task
    instead of running every remaining one (each made slow here, so a run of all of them
    would be seen)."""
    ran: list[int] = []

    def slow_task(scorer: object, task: object) -> object:
        time.sleep(0.2)
        ran.append(1)
        return plan_check_task(scorer, task)  # type: ignore[arg-type]

    def failing_fields(*_: object, **__: object) -> None:
        raise RuntimeError("fields failed")

    monkeypatch.setattr("ris_planner.planning.certify.checks.plan_check_task", slow_task)
    monkeypatch.setattr(pipeline, "fields_stage", failing_fields)
    with pytest.raises(RuntimeError, match="fields failed"):
        run_plan(timed_plan(), executor=SerialExecutor())
    deadline = time.monotonic() + HANG_S
    while any(t.name.startswith("plan-checks") for t in threading.enumerate()):
        assert time.monotonic() < deadline, "the checks' thread did not stop"
        time.sleep(0.05)
    n_tasks = 2 * 6  # two counts × (expected + 5 seeds)
    assert 1 <= len(ran) <= 3 < n_tasks


def test_settle_runs_the_tasks_left_beside_the_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    """The caller of settle() takes the tasks the thread has not started (it has nothing else
    to do): both threads run some, and every answer lands at its task's place."""
    from ris_planner.planning.certify import checks

    runners: dict[int, str] = {}
    took = {True: threading.Event(), False: threading.Event()}  # by the caller / by the thread

    def task_of(scorer: object, task: object) -> object:
        # each side's first task waits until the other side has one: whatever the scheduler
        # does, both run some
        mine = threading.current_thread() is threading.main_thread()
        took[mine].set()
        took[not mine].wait(30)
        time.sleep(0.01)
        runners[int(task)] = threading.current_thread().name  # type: ignore[call-overload]
        return 10 * int(task)  # type: ignore[call-overload]

    monkeypatch.setattr(checks, "plan_check_task", task_of)
    pending = checks.PendingChecks(None, list(range(12)), list)  # type: ignore[arg-type]
    assert pending.settle() == [10 * i for i in range(12)]
    names = set(runners.values())
    assert threading.current_thread().name in names, "settle() only waited"
    assert any(n.startswith("plan-checks") for n in names), "the thread ran nothing"
    assert sorted(runners) == list(range(12))  # each task once


def test_a_failing_task_in_settle_stops_the_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    from ris_planner.planning.certify import checks

    ran: list[int] = []
    caller_failed = threading.Event()

    def task_of(scorer: object, task: object) -> object:
        ran.append(int(task))  # type: ignore[call-overload]
        if threading.current_thread() is threading.main_thread():
            caller_failed.set()
            raise ValueError("a task failed")
        caller_failed.wait(30)  # the thread's first task ends once the caller's has failed
        return task

    monkeypatch.setattr(checks, "plan_check_task", task_of)
    pending = checks.PendingChecks(None, list(range(40)), list)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="a task failed"):
        pending.settle()
    deadline = time.monotonic() + HANG_S
    while any(t.name.startswith("plan-checks") for t in threading.enumerate()):
        assert time.monotonic() < deadline, "the checks' thread did not stop"
        time.sleep(0.05)
    assert 1 <= len(ran) <= 2 < 40  # the caller's and the thread's first: none after


CONCURRENT_KERNELS = textwrap.dedent(
    """
    import threading
    import numba
    import numpy as np
    from ris_planner.inversion import crb

    rng = np.random.default_rng(0)
    x = rng.standard_normal((20_000, 9, 7))
    f = np.einsum("pri,prj->pij", x, x)
    il = np.tril_indices(7)
    packed = np.ascontiguousarray(np.moveaxis(f[:, il[0], il[1]], 0, 1))
    want = crb.fast_diagonal(packed, 7, engine="numba")[0]
    bad = []

    def run():
        for _ in range(20):
            if not np.array_equal(crb.fast_diagonal(packed, 7, engine="numba")[0], want):
                bad.append(1)

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(numba.threading_layer(), len(bad))
    """
)


def test_parallel_kernels_from_two_threads_on_the_workqueue_layer() -> None:
    """Two threads launch the compiled CRB kernel 20 times each under numba's workqueue layer,
    which aborts the process on a concurrent launch (without runtime.kernels' lock this
    process dies with SIGABRT); every answer equals the first (same process, same code)."""
    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue", "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-c", CONCURRENT_KERNELS],
        env=env,
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["workqueue", "0"]
