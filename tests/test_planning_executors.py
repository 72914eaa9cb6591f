"""Executors: the same plan on a Dask LocalCluster (2 worker processes on 127.0.0.1) and on the
local process pool ranks the layouts identically to the in-process run (the scoring arithmetic
does not depend on the chunking; scores from other processes compare to the bounds' accuracy,
tests/tolerance.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from dask_cluster import local_cluster
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner.planning import DaskExecutor, LocalExecutor, SerialExecutor, run_plan
from ris_planner.planning.scoring.site_cache import SiteCache
from ris_planner.planning.search import layouts as search_module


def small_plan() -> dict[str, object]:
    return {
        "candidates": [
            {
                "position": [4.5 * math.cos(a), 4.5 * math.sin(a), 2.0 + k % 2],
                "orientation": [a + math.pi, 0.5, 0.0],
            }
            for k, a in enumerate(2 * math.pi * k / 7 + 0.1 for k in range(7))
        ],
        "tx_map": {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}},
        "rx_map": {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}},
        "pairs": {"sample": 200, "seed": 2},
        "objective": {"kind": "mean_capped", "metric": "max", "cap_m": 1.0},
        "ris_count": [2, 3],
        "search": {"top_k": 40},
    }


def test_dask_local_cluster_gives_identical_ranking() -> None:
    distributed = pytest.importorskip("distributed")
    doc = small_plan()
    local = run_plan(doc, executor=SerialExecutor())
    with local_cluster() as cluster, DaskExecutor(distributed.Client(cluster)) as ex:
        remote = run_plan(doc, executor=ex)
        ex.client.close()
    # the workers are other processes: layouts exactly, scores to the bounds' accuracy
    for a, b in zip(local.counts, remote.counts, strict=True):
        assert_close(a.ranked, b.ranked, accuracy=BOUND_ACCURACY)
    assert_close(local.to_json()["layouts"], remote.to_json()["layouts"], accuracy=BOUND_ACCURACY)


def test_local_process_pool_gives_identical_losses(monkeypatch: pytest.MonkeyPatch) -> None:
    # small chunks so the 35 layouts of 3 RISs go to the two workers in several tasks
    monkeypatch.setattr(search_module, "CHUNK_MATRICES", 2000)
    doc = small_plan()
    doc["search"] = {**doc["search"], "pool_min_work": 0}  # the workers, however small
    serial = run_plan(doc, executor=SerialExecutor())
    with LocalExecutor(2) as ex:
        pooled = run_plan(doc, executor=ex)
    for a, b in zip(serial.counts, pooled.counts, strict=True):
        np.testing.assert_array_equal(a.outcome.layouts, b.outcome.layouts)
        assert_close(a.outcome.losses, b.outcome.losses, accuracy=BOUND_ACCURACY)  # workers


def test_cluster_tasks_carry_only_their_site_block() -> None:
    from ris_planner.planning.search.layouts import all_layouts, evaluate

    class Recording(SerialExecutor):
        """Serial, but asks for site-block tasks and records what each task carries."""

        site_blocks = True

        def __init__(self) -> None:
            self.tasks: list[object] = []
            self.shared: list[object] = []

        def share(self, obj: object) -> object:
            self.shared.append(obj)
            return obj

        def map(self, fn, shared, chunks, on_done=None):  # type: ignore[no-untyped-def]
            self.tasks += list(chunks)
            return super().map(fn, shared, chunks, on_done)

    doc = small_plan()
    doc["candidates"] = doc["candidates"] * 3  # type: ignore[operator]
    doc["constraints"] = {"exclusive_mounts": False}
    result = run_plan({**doc, "ris_count": [2]}, executor=SerialExecutor())
    scorer = result.scorer  # 21 sites: 7 blocks of ⌈21 / 8⌉ = 3
    layouts = all_layouts(scorer.cache.n_sites, 3)
    ex = Recording()
    got = evaluate(scorer, layouts, ex)
    np.testing.assert_array_equal(got, evaluate(scorer, layouts, SerialExecutor()))  # bit for bit
    assert len(ex.shared) == 7 + 1  # every block and the base shared once
    for _, parts, local in ex.tasks:  # type: ignore[misc]
        # only blocks that hold a site of the task's layouts, ≤ size + 2L = 9 sites used
        offsets = np.cumsum([0, *(p.n_sites for p in parts)])
        assert local.max() < offsets[-1]
        assert np.all(np.isin(np.arange(len(parts)), np.searchsorted(offsets, local, "right") - 1))
        assert np.unique(local).size <= 9
    # a swap batch (one site of a layout replaced): one task per block of the candidates,
    # not one per block combination
    base = np.array([0, 9, 17])
    swaps = np.array(
        [
            np.sort(np.r_[np.delete(base, i), s])
            for i in range(3)
            for s in range(21)
            if s not in base
        ]
    )
    ex.tasks.clear()
    np.testing.assert_array_equal(
        evaluate(scorer, swaps, ex), evaluate(scorer, swaps, SerialExecutor())
    )
    assert len(ex.tasks) == 7
    evaluate(scorer, layouts[:50], ex)
    assert len(ex.shared) == 8  # the blocks are reused for the same scorer
    # a task scores on just the sites its layouts use, gathered from the blocks it carries
    cache = scorer.cache
    parts = [cache.subset(np.arange(0, 3)), cache.subset(np.arange(3, 6))]
    picked = SiteCache.concat(parts, [np.array([1]), np.array([0, 2])])
    want = cache.subset(np.array([1, 3, 5]))
    for field in ("blocks", "degenerate", "far_field", "present"):
        np.testing.assert_array_equal(getattr(picked, field), getattr(want, field))
    assert picked.source.sites == want.source.sites


def test_service_setting_sends_plan_jobs_to_dask(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    pytest.importorskip("distributed")
    from pydantic import ValidationError

    from api.kinds import plan_job
    from api.settings import Settings

    with pytest.raises(ValidationError, match="dask_scheduler"):
        Settings(dask_scheduler="not a url")
    doc = small_plan()
    local = run_plan(doc, executor=SerialExecutor()).to_json()
    with local_cluster() as cluster:
        monkeypatch.setenv("RIS_PLANNER_DASK_SCHEDULER", cluster.scheduler_address)
        out = plan_job(doc, lambda f, m: None, tmp_path)
        prefixes = set(cluster.scheduler.task_prefixes)
    # the layouts were scored on the cluster (score_block_task, or its ranked form)
    assert any(p.startswith("score_block_task") for p in prefixes), prefixes
    assert_close(out.result["layouts"], local["layouts"], accuracy=BOUND_ACCURACY)
    assert out.result["by_count"][1]["sites"] == local["by_count"][1]["sites"]
