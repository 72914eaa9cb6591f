"""The local pool's shared memory (``planning.executor``): the shared object's large arrays
reach the workers mapped from one anonymous memory file, the plan is the in-process one
(decisions exactly, figures to the bounds' accuracy: tests/tolerance.py), and nothing stays
behind – no file descriptor, no ``/dev/shm`` entry, no worker – after a plan, a failed task, a
lost worker or an interrupt."""

from __future__ import annotations

import gc
import os
import pickle
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.model.plan import POOL_MIN_WORK
from ris_planner.planning import LocalExecutor, SerialExecutor, run_plan
from ris_planner.planning.search import layouts as search_module
from ris_planner.runtime.executor import (
    MEMFD_PREFIX,
    SHARE_MIN_BYTES,
    load_shared,
    share_pickle,
    sharing_supported,
)

pytestmark = pytest.mark.skipif(not sharing_supported(), reason="memfd sharing is Linux-only")


def hall_like_plan() -> dict[str, Any]:
    """A small hall (20 × 12 m, 2 heights × 2 tilts every 5 m: 48 candidates, 300 pairs,
    coverage): L=2 exhaustive, L=3 greedy with swaps, as the 156-candidate hall runs."""
    corners = ([0, 0], [20, 0], [20, 12], [0, 12])
    walls = [
        {
            "start": corners[i],
            "end": corners[(i + 1) % 4],
            "side": "left",
            "heights_m": [3, 6],
            "spacing_m": 5,
            "tilts_rad": [0.0, 0.35],
        }
        for i in range(4)
    ]
    grid = {"grid": {"x": [2, 18, 2], "y": [2, 10, 2], "z": [1.5, 1.5, 1]}}
    return {
        "walls": walls,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 300, "seed": 0},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [2, 3],
        "search": {"max_exhaustive": 2000, "restarts": 2, "pool_min_work": 0},
    }


def memfds() -> list[str]:
    """This process's open descriptors of the executor's memory files."""
    out = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            link = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if MEMFD_PREFIX in link:
            out.append(link)
    return out


def dev_shm() -> set[str]:
    """The names in ``/dev/shm`` but other processes' semaphores (``sem.*``: the machine is
    shared; a pool's own semaphores are unlinked as they are made)."""
    names = set(os.listdir("/dev/shm")) if os.path.isdir("/dev/shm") else set()
    return {n for n in names if not n.startswith("sem.")}


def gone(pids: list[int]) -> bool:
    return not any(Path(f"/proc/{pid}").exists() for pid in pids)


def worker_view(shared: Any, chunk: Any) -> dict[str, Any]:
    """Task: how the worker holds ``shared`` (the scorer)."""
    maps = Path("/proc/self/maps").read_text()
    packed = shared.cache.packed
    return {
        "pid": os.getpid(),
        "mapped": MEMFD_PREFIX in maps,
        "writeable": bool(packed.flags.writeable),
        "blocks_shared": "_kernel_inputs" in shared.__dict__,
        "sum": float(packed.sum()),
    }


def failing(shared: Any, chunk: Any) -> None:
    raise ValueError(f"task {chunk} failed")


def dying(shared: Any, chunk: Any) -> None:
    os._exit(3)


def test_share_pickle_round_trip_keeps_values_layout_and_privacy() -> None:
    big = np.arange(3 * 6000, dtype=np.float64).reshape(3, 6000)
    fortran = np.asfortranarray(big)
    obj = {
        "c": big,
        "f": fortran,
        "strided": big[:, ::2],  # not contiguous: shared as a contiguous copy
        "mask": np.arange(SHARE_MIN_BYTES) % 3 == 0,
        "small": np.arange(10),  # stays inside the pickle
        "same": big,  # one array, one copy
        "text": "kept",
    }
    payload = share_pickle(obj)
    try:
        # the arrays are not in the pickle: it is a few hundred bytes plus the small array
        assert len(payload.data) < 2000
        assert len(pickle.dumps(obj)) > 200_000
        back = load_shared(payload)
        for key in ("c", "f", "strided", "mask", "small"):
            np.testing.assert_array_equal(back[key], obj[key])
            assert back[key].dtype == obj[key].dtype
            assert back[key].flags.writeable
        assert back["f"].flags.f_contiguous and not back["f"].flags.c_contiguous
        assert back["same"] is back["c"]
        assert back["text"] == "kept"
        # copy-on-write: a write stays in this mapping, the next load sees the original
        back["c"][0, 0] = -1.0
        assert load_shared(payload)["c"][0, 0] == 0.0
        assert big[0, 0] == 0.0
    finally:
        payload.arrays.close()
    with pytest.raises(RuntimeError, match="are gone"):
        load_shared(payload)
    # a mapping holds its own descriptor (as a worker's does) until its arrays are dropped
    assert len(memfds()) == 1
    del back
    gc.collect()
    assert memfds() == []


@pytest.mark.parametrize("share_memory", [True, False])
def test_hall_like_plan_on_the_pool_is_the_serial_plan(
    monkeypatch: pytest.MonkeyPatch, share_memory: bool
) -> None:
    # small chunks: the L=2 layouts and the greedy rounds go to both workers in many tasks
    monkeypatch.setattr(search_module, "CHUNK_MATRICES", 30_000)
    monkeypatch.setattr(search_module, "MIN_TASK_MATRICES", 2_000)
    doc = hall_like_plan()
    shm_before = dev_shm()
    serial = run_plan(doc, executor=SerialExecutor())
    with LocalExecutor(2, share_memory=share_memory) as ex:
        pooled = run_plan(doc, executor=ex)
        pids = ex.worker_pids()
    assert [c.outcome.method for c in serial.counts] == ["exhaustive", "greedy"]
    # the workers are other processes: decisions exactly, figures to the bounds' accuracy
    for a, b in zip(serial.counts, pooled.counts, strict=True):
        np.testing.assert_array_equal(a.outcome.layouts, b.outcome.layouts)
        assert_close(a.outcome.losses, b.outcome.losses, accuracy=BOUND_ACCURACY)
    s, p = serial.to_json(), pooled.to_json()
    s.pop("timing_s")
    p.pop("timing_s")
    assert_close(p, s, accuracy=BOUND_ACCURACY)
    assert len(pids) == 2 and gone(pids)
    assert memfds() == []
    assert dev_shm() == shm_before


def test_workers_map_the_scorer_and_its_pair_blocks() -> None:
    from test_planning import setup

    _, _, _, scorer = setup(hall_like_plan())
    with LocalExecutor(2) as ex:
        ex.start()
        started = ex.worker_pids()  # started before any task, without the scorer
        views = ex.map(worker_view, scorer, list(range(6)))
        assert len(memfds()) == 1  # one file for the whole scorer
        assert ex.worker_pids() == started
    assert {v["pid"] for v in views} <= set(started)
    assert all(v["mapped"] and v["writeable"] and v["blocks_shared"] for v in views)
    assert {v["sum"] for v in views} == {float(scorer.cache.packed.sum())}
    assert memfds() == [] and gone(started)


@pytest.mark.parametrize("task", [failing, dying])
def test_a_failed_task_or_a_lost_worker_leaves_nothing(task: Any) -> None:
    shared = {"big": np.ones(SHARE_MIN_BYTES)}
    shm_before = dev_shm()
    with LocalExecutor(2) as ex:
        ex.start()
        pids = ex.worker_pids()
        with pytest.raises(ValueError if task is failing else BrokenProcessPool):
            ex.map(task, shared, [1, 2, 3])
        assert memfds() == [] and gone(pids)
        # the executor starts afresh on its next call
        assert ex.map(worker_sum, shared, [0, 1]) == [float(SHARE_MIN_BYTES)] * 2
        again = ex.worker_pids()
    assert memfds() == [] and gone(again)
    assert dev_shm() == shm_before


def worker_sum(shared: Any, chunk: Any) -> float:
    return float(shared["big"].sum())


def test_an_interrupt_leaves_nothing() -> None:
    def interrupt(n: int) -> None:
        raise KeyboardInterrupt

    shared = {"big": np.ones(SHARE_MIN_BYTES)}
    ex = LocalExecutor(2)
    ex.start()
    pids = ex.worker_pids()
    with pytest.raises(KeyboardInterrupt):
        ex.map(worker_sum, shared, list(range(8)), on_done=interrupt)
    assert memfds() == [] and gone(pids)
    ex.close()


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_chunk_count_bounds_and_balances_the_tasks(workers: int) -> None:
    from ris_planner.planning.search.layouts import (
        CHUNK_MATRICES,
        MIN_TASK_MATRICES,
        TASKS_PER_WORKER,
        chunk_count,
    )

    for n_layouts in (1, 2, 5, 77, 459, 2295, 11700, 123_457):
        for n_pairs in (1, 300, 6400, 50_000):
            n = chunk_count(n_layouts, n_pairs, workers)
            work = n_layouts * n_pairs
            assert 1 <= n <= n_layouts
            # np.array_split's largest part stays within a chunk (up to one layout's pairs)
            assert -(-n_layouts // n) * n_pairs <= CHUNK_MATRICES + n_pairs
            if 1 < n < n_layouts:
                assert n % workers == 0  # every worker gets as many tasks
            if workers == 1:
                assert n == min(n_layouts, -(-work // CHUNK_MATRICES))
            elif work >= TASKS_PER_WORKER * workers * MIN_TASK_MATRICES:
                assert n >= min(n_layouts, TASKS_PER_WORKER * workers)
            elif work < workers * MIN_TASK_MATRICES:
                assert n == 1  # too small to be worth a second task


def test_only_a_plan_that_splits_its_batches_starts_workers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from ris_planner.planning.prepare import needs_workers, prepare_plan

    big = hall_like_plan()
    big["pairs"] = {"sample": 3000, "seed": 0}  # 1128 layouts of 2 × 3000 pairs: 3.4 M
    assert needs_workers(prepare_plan(big), 2000, 2)
    assert not needs_workers(prepare_plan(big), 2000, 1)
    small = hall_like_plan()
    small["pairs"] = {"sample": 100, "seed": 0}  # ≤ 2000 layouts × 100 pairs: all in-process
    assert not needs_workers(prepare_plan(small), 2000, 2)

    def no_pool(*args: object) -> None:
        raise AssertionError("a small plan started a pool")

    monkeypatch.setattr(LocalExecutor, "_spawn", no_pool)
    with LocalExecutor(2) as ex:
        run_plan(small, executor=ex)
    run_plan(small)  # the default executor too
    # below the document's search.pool_min_work (default: minutes of scoring) a plan whose
    # batches would split runs in-process too: the scorer's threads use the cores
    default = {**big, "search": {"max_exhaustive": 2000}}
    assert not needs_workers(prepare_plan(default), 2000, 2, POOL_MIN_WORK)
    with LocalExecutor(2) as ex:
        run_plan(default, executor=ex)


def test_shared_arrays_never_closed_are_closed_with_their_object() -> None:
    payload = share_pickle({"big": np.ones(SHARE_MIN_BYTES)})
    assert len(memfds()) == 1
    del payload
    gc.collect()
    assert memfds() == []
