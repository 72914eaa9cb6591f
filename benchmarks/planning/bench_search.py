"""Placement-search benchmark: a synthetic hall and a synthetic city block grid.

For each case, in the same run:
* today's search (``search.search`` without constraints or certificates, the best layout of
  each smaller count seeding the next, as ``run_plan`` did before the decisions work);
* the plan as it runs now on the same problem (``exclusive_mounts`` off: the same layouts are
  allowed), with its certificates: time, memory peak (tracemalloc, in-process), layouts
  evaluated, the certified gap, and whether it returns today's best layouts;
* the default plan (shared mounting points exclusive);
* optionally (``--dask``) the same plan on a Dask LocalCluster with 2 workers on 127.0.0.1:
  identical answer and throughput per worker.

    python benchmarks/planning/bench_search.py --quick   # the hall at 800 pairs, 2 RISs
    python benchmarks/planning/bench_search.py [--case hall|city|both] [--dask]
        [--city-blocks 4] [--city-pairs 50000] [--counts 2 3 4] [--hall-pairs 6400]
    python benchmarks/planning/bench_search.py --greedy-workers 2 --counts 3 [--hall-pairs 2000]
    python benchmarks/planning/bench_search.py --storage-check 2000 [--hall-pairs 6400]
    python benchmarks/planning/bench_search.py --city-memory 40 [--city-blocks 4]
        [--city-pairs 50000]
    python benchmarks/planning/bench_search.py --pool-start 2 [--whole-plan] [--hall-pairs 6400]
    python benchmarks/planning/bench_search.py --swap-rates [--city-pairs 50000] [--counts 2 3 4]

Hall: 40 × 25 m, candidates on the 4 inner walls every 5 m at 3 heights × 2 tilts (156), a 2 m
UE grid at 1.5 m, 6400 sampled pairs. City: a grid of square buildings (facade sites every
10 m at 2 heights, ≥ 500 with ``--city-blocks 4``; the buildings are obstacles), UEs on the
streets.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from ris_planner.environment import Scene
from ris_planner.planning import DaskExecutor, PlanDocument, SerialExecutor, run_plan
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.scorer import Scorer, score_chunk
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility
from ris_planner.planning.search.layouts import Layout, exhaustive

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import city_grid_document as city_doc
from fixtures import hall_document as hall_doc
from old_search import old_greedy


def site_scorer(doc: PlanDocument, budget: bool = False) -> tuple[list[Any], Any, Scorer]:
    """(sites, pairs, scorer) of a plan document: its candidates, sampled pairs and the site
    cache with the plan's fields of view and obstacles – float64 with the square-root rows, as
    before the cache's memory budget, or with ``budget`` the layout the plan's budget picks."""
    from ris_planner.model.limits import cache_layout
    from ris_planner.planning.scoring.site_cache import FULL

    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**7)
    vis = pair_visibility(Scene.from_environment(doc.environment), sites, pairs, doc.system.los)
    entries = len(sites) * pairs.size
    layout = cache_layout(entries, doc.system.wavefront) if budget else FULL
    cache = build_site_cache(
        doc.system, sites, pairs, visibility=vis, known=tuple(doc.known), layout=layout
    )
    return sites, pairs, Scorer(cache, pairs.weights, doc.objective, tuple(doc.known))


def todays_search(doc: PlanDocument) -> tuple[dict[int, tuple[Layout, float, int]], float, int]:
    """Today's search on the same problem: best (layout, loss, evaluated) per count, time,
    memory peak [B]."""
    tracemalloc.start()
    t0 = time.perf_counter()
    # the plan's fields of view (and obstacles), as run_plan applied them before the decisions
    sites, _, scorer = site_scorer(doc)
    out: dict[int, tuple[Layout, float, int]] = {}
    seeds: list[Layout] = []
    assert doc.ris_count is not None
    for c in doc.ris_count:
        ex = SerialExecutor()
        if math.comb(len(sites), c) <= doc.search.max_exhaustive:
            res = exhaustive(scorer, len(sites), c, ex)
        else:
            res = old_greedy(scorer, len(sites), c, doc.search, ex, None, tuple(seeds))
        lay, loss = res.ranked(1)[0]
        out[c] = (lay, loss, res.evaluated)
        seeds.append(lay)
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, dt, peak


def timed_plan(raw: dict[str, Any], executor: Any) -> tuple[Any, float, int]:
    tracemalloc.start()
    t0 = time.perf_counter()
    res = run_plan(raw, executor=executor)
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return res, dt, peak


def peak_rss_mib() -> float:
    """The process's peak resident set so far [MiB] (Linux: ru_maxrss in KiB; numba's and
    numpy's buffers included, which tracemalloc does not all see)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def report(name: str, raw: dict[str, Any], dask: bool, default: bool = True) -> None:
    raw_same = {**raw, "constraints": {"exclusive_mounts": False}}
    doc = PlanDocument.model_validate(raw_same)
    n_sites = len(expand_sites(doc))
    print(f"\n== {name}: {n_sites} candidates, counts {doc.ris_count}")
    today, t_today, m_today = todays_search(doc)
    print(f"today's search: {t_today:.1f} s, peak {m_today / 2**20:.0f} MiB")
    res, t_new, m_new = timed_plan(raw_same, SerialExecutor())
    print(
        f"plan now (same layouts allowed): {t_new:.1f} s ("
        + ", ".join(f"{k} {v:.1f}" for k, v in res.timing.items())
        + "),"
        f" peak {m_new / 2**20:.0f} MiB, {res.pairs.size} pairs"
    )
    entries = res.cache.n_sites * res.pairs.size
    print(
        f"  site cache {res.cache.storage}, {res.cache.blocks.nbytes / 2**20:.0f} MiB (before"
        f" the cache's memory budget: {entries * (28 + 21 + 28) * 8 / 2**20:.0f} MiB, 28 + 21"
        " float64 per site-pair in the cache + 28 per scoring process);"
        f" peak RSS so far {peak_rss_mib():.0f} MiB"
    )
    plan = res.to_json()
    for entry in plan["by_count"]:
        c = entry["ris_count"]
        lay, loss, ev = today[c]
        cert = entry["certificate"] or {}
        same = tuple(entry["sites"]) == lay
        old = -loss if doc.objective.kind == "coverage" else loss
        print(
            f"  L={c}: {entry['method']:10s} evaluated {entry['layouts_evaluated']:7d}"
            f" (today {ev:7d}) of {entry['layouts_total']:10d}; objective"
            f" {entry['objective']} (today {old:.6g},"
            f" same layout: {same}); bound {cert.get('objective_bound')} gap {cert.get('gap')}"
            f" exact {cert.get('exact')}; ties {entry['ties']['count']};"
            f" B&B {entry['branch_and_bound']}"
        )
    if default:
        res_x, t_x, m_x = timed_plan(raw, SerialExecutor())
        print(f"default plan (exclusive mounting points): {t_x:.1f} s, peak {m_x / 2**20:.0f} MiB")
        for entry in res_x.to_json()["by_count"]:
            cert = entry["certificate"] or {}
            print(
                f"  L={entry['ris_count']}: sites {entry['sites']} objective {entry['objective']}"
                f" gap {cert.get('gap')} ({entry['layouts_evaluated']} layouts)"
            )
    if dask:
        import distributed

        with (
            distributed.LocalCluster(
                n_workers=2,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address="127.0.0.1:0",
            ) as cluster,
            DaskExecutor(distributed.Client(cluster)) as ex,
        ):
            t0 = time.perf_counter()
            remote = run_plan(raw_same, executor=ex)
            # the search's own time: every stage but the search's (timing_s is per stage)
            t_d = time.perf_counter() - t0
            t_d -= sum(v for k, v in remote.timing.items() if k != "search")
            ex.client.close()
        same = remote.to_json()["layouts"] == plan["layouts"]
        n_eval = sum(cr.outcome.evaluated for cr in remote.counts)
        rate = n_eval * remote.pairs.size / t_d / 2
        print(
            f"dask LocalCluster (2 workers, 127.0.0.1): identical answer {same}; search"
            f" {t_d:.1f} s vs {res.timing['search']:.1f} s in-process;"
            f" {rate / 1e6:.2f} M layout-pairs/s per worker"
        )


def storage_check(raw: dict[str, Any], n_layouts: int) -> None:
    """float32 against float64 storage on the same problem: the scores of n_layouts random
    layouts per count (max relative error, same inf pattern) and the plan's answers (best
    layouts, objectives) with the cache budget set just below float64's storage."""
    from ris_planner.model.limits import CACHE_MEMORY_ENV, CacheLayout
    from ris_planner.planning.search.layouts import all_layouts

    doc = PlanDocument.model_validate(raw)
    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**7)
    vis = pair_visibility(Scene.from_environment(doc.environment), sites, pairs, doc.system.los)
    known = tuple(doc.known)
    scorers = {}
    for storage in ("float64", "float32"):
        t0 = time.perf_counter()
        layout = CacheLayout(storage, False)
        cache = build_site_cache(
            doc.system, sites, pairs, visibility=vis, known=known, layout=layout
        )
        scorers[storage] = Scorer(cache, pairs.weights, doc.objective, known)
        print(
            f"{storage}: cache {cache.blocks.nbytes / 2**20:.0f} MiB built in"
            f" {time.perf_counter() - t0:.1f} s"
        )
    rng = np.random.default_rng(0)
    assert doc.ris_count is not None
    for c in doc.ris_count:
        lay = all_layouts(len(sites), c)
        lay = lay[np.sort(rng.choice(len(lay), min(n_layouts, len(lay)), replace=False))]
        m64, m32 = scorers["float64"].metric(lay), scorers["float32"].metric(lay)
        ok = np.isfinite(m64)
        err = np.abs(m32[ok] - m64[ok]) / m64[ok]
        l64, l32 = scorers["float64"].loss(lay), scorers["float32"].loss(lay)
        print(
            f"  L={c}: {lay.shape[0]} layouts × {pairs.size} pairs: same inf pattern"
            f" {bool(np.array_equal(ok, np.isfinite(m32)))}, max relative error of the metric"
            f" {err.max():.2e} (median {np.median(err):.1e}), max |Δ loss|"
            f" {np.max(np.abs(l32 - l64)):.2e}; same best of the sample"
            f" {int(np.argmin(l64)) == int(np.argmin(l32))}"
        )
    blocks = scorers["float64"].cache.blocks.nbytes >> 20
    answers = {}
    tiers = (("float64", None), ("float64, rows recomputed", blocks + 1), ("float32", blocks - 1))
    for name, budget in tiers:
        if budget is not None:  # the budget just above / below float64's block storage
            os.environ[CACHE_MEMORY_ENV] = str(budget)
        res, dt, _ = timed_plan(raw, SerialExecutor())
        os.environ.pop(CACHE_MEMORY_ENV, None)
        answers[name] = res.to_json()["by_count"]
        print(f"plan with {name} ({res.to_json()['site_cache']}): {dt:.1f} s {res.timing}")
    for a, r, b in zip(*answers.values(), strict=True):
        print(
            f"  L={a['ris_count']}: rows recomputed: same top layouts and objectives"
            f" {a['top_layouts'] == r['top_layouts']}"
        )
        print(
            f"  L={a['ris_count']}: float64 {a['sites']} {a['objective']}, float32"
            f" {b['sites']} {b['objective']}; same top layouts and objectives"
            f" {a['top_layouts'] == b['top_layouts']}"
        )


def city_memory(raw: dict[str, Any], n_layouts: int) -> None:
    """The city's site cache at full size without the searches: the layout the budget picks,
    its build time and bytes, the peak RSS, the scoring rate on it and the exact float64
    re-score of a few layouts (what the plan does for its finalists)."""
    from ris_planner.model.limits import cache_layout

    doc = PlanDocument.model_validate(raw)
    t0 = time.perf_counter()
    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**7)
    vis = pair_visibility(Scene.from_environment(doc.environment), sites, pairs, doc.system.los)
    entries = len(sites) * pairs.size
    layout = cache_layout(entries, doc.system.wavefront)
    t_vis = time.perf_counter() - t0
    t0 = time.perf_counter()
    cache = build_site_cache(
        doc.system, sites, pairs, visibility=vis, known=tuple(doc.known), layout=layout
    )
    t_cache = time.perf_counter() - t0
    print(
        f"city cache: {len(sites)} × {pairs.size} = {entries / 1e6:.1f} M site-pairs, {layout},"
        f" {cache.nbytes / 2**30:.2f} GiB (before the cache's memory budget:"
        f" {entries * 77 * 8 / 2**30:.1f} GiB, 28 + 21 float64 in the cache + 28 per process);"
        f" maps/pairs/visibility {t_vis:.1f} s, cache {t_cache:.1f} s; peak RSS"
        f" {peak_rss_mib():.0f} MiB"
    )
    scorer = Scorer(cache, pairs.weights, doc.objective, tuple(doc.known))
    rng = np.random.default_rng(0)
    for c in (2, 4, 6):
        lay = np.sort(
            np.stack([rng.choice(len(sites), c, replace=False) for _ in range(n_layouts)]), axis=1
        )
        scorer.metric(lay[:1])
        t0 = time.perf_counter()
        m32 = scorer.metric(lay)
        t_m = time.perf_counter() - t0
        t0 = time.perf_counter()
        m64 = scorer.exact_metric(lay[:3])
        t_x = time.perf_counter() - t0
        ok = np.isfinite(m64)
        err = np.abs(m32[:3][ok] - m64[ok]) / m64[ok]
        print(
            f"  L={c}: {n_layouts} layouts in {t_m:.1f} s"
            f" ({n_layouts * pairs.size / t_m / 1e6:.2f} M layout-pairs/s);"
            f" exact float64 re-score of 3 in {t_x:.1f} s, same inf pattern"
            f" {bool(np.array_equal(ok, np.isfinite(m32[:3])))}, relative error of the"
            f" stored-precision metric median {np.median(err) if err.size else 0:.1e} max"
            f" {err.max() if err.size else 0:.1e}; peak RSS {peak_rss_mib():.0f} MiB"
        )


def swap_rates(name: str, raw: dict[str, Any], counts: list[int], repeats: int = 2) -> None:
    """Scoring rate of greedy swap batches (one random base layout and all its L × (S − L)
    single-site swaps: what a greedy round scores) with ``Scorer.loss`` (the screen, losses
    one kernel block at a time) against the unscreened whole-batch metric and its losses,
    in the same run; the losses must agree bit for bit."""
    from ris_planner.planning.scoring.scorer import loss_from_metric

    doc = PlanDocument.model_validate({**raw, "constraints": {"exclusive_mounts": False}})
    sites, pairs, sc = site_scorer(doc, budget=True)
    print(
        f"\n== swap batches, {name}: {len(sites)} candidates × {pairs.size} pairs,"
        f" {sc.cache.storage} storage"
    )
    rng = np.random.default_rng(0)
    for c in counts:
        base = rng.choice(len(sites), c, replace=False)
        others = np.setdiff1d(np.arange(len(sites)), base)
        lays = np.array([np.sort(np.r_[np.delete(base, i), s]) for i in range(c) for s in others])
        sc.loss(lays[:2])
        t_new, t_ref = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            new = sc.loss(lays)
            t_new.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            ref = loss_from_metric(sc.objective, sc.metric(lays), sc.metric_weights)
            t_ref.append(time.perf_counter() - t0)
        work = lays.shape[0] * pairs.size / 1e6
        print(
            f"  L={c}: {lays.shape[0]} swaps; loss {work / min(t_new):.1f} M layout-pairs/s,"
            f" unscreened whole-batch metric {work / min(t_ref):.1f} M/s"
            f" ({min(t_ref) / min(t_new):.2f}×); same losses {np.array_equal(new, ref)}"
        )


def greedy_workers(raw: dict[str, Any], workers: int) -> None:
    """Today's greedy and the new one (starts in lockstep, rounds split over the workers) with
    the same LocalExecutor: same layouts, wall time of each."""
    from old_search import old_greedy as today

    from ris_planner.planning import LocalExecutor
    from ris_planner.planning.search.layouts import greedy

    doc = PlanDocument.model_validate(raw)
    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**7)
    scorer = Scorer(build_site_cache(doc.system, sites, pairs), pairs.weights, doc.objective, ())
    assert doc.ris_count is not None
    with LocalExecutor(workers) as ex:
        warm = [np.array([[0, 1, 2]]), np.array([[0, 1, 3]])]
        ex.map(score_chunk, scorer, warm)  # start the pool (and ship the cache) before timing
        for c in doc.ris_count:
            t0 = time.perf_counter()
            old = today(scorer, len(sites), c, doc.search, ex)
            t_old = time.perf_counter() - t0
            t0 = time.perf_counter()
            new = greedy(scorer, len(sites), c, doc.search, ex)
            t_new = time.perf_counter() - t0
            same = old.as_dict() == new.as_dict()
            print(
                f"greedy L={c}, {workers} workers, {pairs.size} pairs: today {t_old:.1f} s,"
                f" now {t_new:.1f} s ({t_old / t_new:.2f}×), {new.evaluated} layouts,"
                f" identical outcome {same}"
            )


def memory_mib(pids: list[int]) -> tuple[float, float]:
    """(Σ RSS, Σ PSS) of the processes in MiB: PSS counts a page shared by k processes 1/k
    times in each, so its sum is the RAM they use together."""
    rss = pss = 0.0
    for pid in pids:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            key, *rest = line.split()
            if key in ("Rss:", "Pss:"):
                kib = float(rest[0]) / 1024
                rss, pss = (rss + kib, pss) if key == "Rss:" else (rss, pss + kib)
    return rss, pss


def cpu_seconds() -> tuple[float, float]:
    """(this process's, its finished children's) user + system CPU seconds: a pool's workers
    count once it is closed. Their sum over two cores bounds an idle machine's wall time from
    below whatever the load now."""
    import resource

    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime


def pool_start(raw: dict[str, Any], workers: int, whole: bool) -> None:
    """The local pool with the site cache pickled to each worker (the pool initializer) and
    with its arrays in shared memory, in the same run: time to the first scored chunk (pool
    start, imports, the cache reaching every worker, their scorer set-up), the exhaustive L=2
    search on the started pool, and the memory of the main process and its workers; with
    ``whole``, the whole hall plan both ways too."""
    import os

    from ris_planner.planning import LocalExecutor
    from ris_planner.planning.search.layouts import all_layouts, evaluate

    doc = PlanDocument.model_validate(raw)
    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**7)
    scorer = Scorer(build_site_cache(doc.system, sites, pairs), pairs.weights, doc.objective, ())
    size = sum(a.nbytes for a in vars(scorer.cache).values() if isinstance(a, np.ndarray))
    layouts = all_layouts(len(sites), 2)
    print(
        f"pool start: {len(sites)} candidates × {pairs.size} pairs, site cache"
        f" {size / 2**20:.0f} MiB, {workers} workers, {len(os.sched_getaffinity(0))} cores"
    )
    print("  mode          first chunk   L=2 exhaustive        RSS sum   PSS sum (MiB)")
    reference = None
    for share in (False, True):
        with LocalExecutor(workers, share_memory=share) as ex:
            t0 = time.perf_counter()
            ex.map(score_chunk, scorer, [layouts[i : i + 1] for i in range(workers)])
            t_first = time.perf_counter() - t0
            t0 = time.perf_counter()
            losses = evaluate(scorer, layouts, ex)
            t_l2 = time.perf_counter() - t0
            rss, pss = memory_mib([os.getpid(), *ex.worker_pids()])
        if reference is None:
            reference = losses
        rate = layouts.shape[0] * pairs.size / t_l2
        print(
            f"  {'shared memory' if share else 'pickled':13s} {t_first:8.2f} s"
            f" {t_l2:8.2f} s ({rate / 1e6:4.1f} M/s) {rss:9.0f} {pss:9.0f}"
            f"   identical {bool(np.array_equal(losses, reference))}"
        )
    if not whole:
        return
    plan_raw = hall_doc([2, 3, 4], pairs.size)
    print("  the whole 2/3/4-RIS plan (run_plan: the pool started before the site cache):")
    answers = []
    for share in (False, True):
        c0 = cpu_seconds()
        t0 = time.perf_counter()
        with LocalExecutor(workers, share_memory=share) as ex:
            res = run_plan(plan_raw, executor=ex)
        total = time.perf_counter() - t0
        main_cpu, workers_cpu = (b - a for a, b in zip(c0, cpu_seconds(), strict=True))
        answers.append(res.to_json()["layouts"])
        objectives = " / ".join(f"{e['objective']:.4g}" for e in res.to_json()["by_count"])
        parts = ", ".join(f"{k} {v:.1f}" for k, v in res.timing.items())
        print(
            f"  {'shared memory' if share else 'pickled':13s} {total:6.1f} s ({parts});"
            f" CPU main {main_cpu:.1f} s + workers {workers_cpu:.1f} s; objectives {objectives}"
        )
    print(f"  identical layouts {answers[0] == answers[1]}")


def branch_and_bound_instances(n_sites: int, seeds: int) -> None:
    """Random instances of the tests (ring of candidates, 120 pairs, the four objectives):
    exhaustive search against greedy + branch-and-bound, both timed in this run."""
    from test_planning_decisions import random_instance, setup

    from ris_planner.planning.certify.branch_bound import branch_and_bound
    from ris_planner.planning.inputs.constraints import unconstrained
    from ris_planner.planning.search.layouts import greedy

    for seed in range(seeds):
        d, sites, _, scorer = setup(random_instance(seed, n=n_sites))
        feas = unconstrained(len(sites))
        for n_ris in (3, 4):
            t0 = time.perf_counter()
            ex = exhaustive(scorer, len(sites), n_ris, SerialExecutor())
            t_ex = time.perf_counter() - t0
            t0 = time.perf_counter()
            gr = greedy(scorer, len(sites), n_ris, d.search, SerialExecutor())
            bb = branch_and_bound(scorer, n_ris, feas, gr, SerialExecutor(), 20)
            t_bb = time.perf_counter() - t0
            same = bb.outcome.ranked(1)[0] == ex.ranked(1)[0]
            print(
                f"seed {seed} {d.objective.kind:11s} L={n_ris}: exhaustive {ex.evaluated} layouts"
                f" {t_ex:.2f} s; greedy {gr.evaluated} + B&B {bb.leaves} layouts, {bb.nodes}"
                f" nodes, {t_bb:.2f} s; finished {bb.finished}, same best {same},"
                f" root bound {bb.root_bound:.4g} → {bb.loss_bound:.4g}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=["hall", "city", "both"], default="hall")
    ap.add_argument("--counts", type=int, nargs="+", default=None)
    ap.add_argument("--city-blocks", type=int, default=4)
    ap.add_argument("--city-pairs", type=int, default=50_000)
    ap.add_argument("--dask", action="store_true")
    ap.add_argument("--hall-pairs", type=int, default=6400)
    ap.add_argument(
        "--greedy-workers",
        type=int,
        default=0,
        help="only compare today's and the new greedy on the hall with N local workers",
    )
    ap.add_argument(
        "--bnb-instances",
        type=int,
        default=0,
        help="only compare exhaustive search and greedy + branch-and-bound on N random"
        " instances of --bnb-sites candidates",
    )
    ap.add_argument("--bnb-sites", type=int, default=16)
    ap.add_argument(
        "--storage-check",
        type=int,
        default=0,
        help="only compare float32 and float64 site-cache storage on the hall: N random layouts"
        " per count, and the plan with each",
    )
    ap.add_argument(
        "--no-default", action="store_true", help="skip the default plan (exclusive mounts)"
    )
    ap.add_argument(
        "--job-memory-mb",
        type=int,
        default=16384,
        help="RIS_PLANNER_JOB_MEMORY_MB for the city case (the estimate counts a 200 000-pair"
        " heatmap and the worker pool's copy of the cache beside the 3 GiB cache budget)",
    )
    ap.add_argument(
        "--city-memory",
        type=int,
        default=0,
        help="only build the city's site cache at full size and score N random layouts on it",
    )
    ap.add_argument(
        "--pool-start",
        type=int,
        default=0,
        help="only time the local pool's start with N workers on the hall, the site cache"
        " pickled and shared",
    )
    ap.add_argument(
        "--swap-rates",
        action="store_true",
        help="only the scoring rate of greedy swap batches on the hall and the city",
    )
    ap.add_argument(
        "--whole-plan", action="store_true", help="with --pool-start: the whole plan both ways"
    )
    ap.add_argument("--quick", action="store_true", help="the hall at 800 pairs, 2 RISs")
    args = ap.parse_args()
    if args.quick:
        args.case, args.hall_pairs, args.counts = "hall", 800, [2]
    if args.swap_rates:
        swap_rates("hall", hall_doc([2], args.hall_pairs), args.counts or [2, 3, 4])
        city = city_doc(args.city_blocks, args.city_pairs, [2])
        swap_rates("city", city, args.counts or [2, 3, 4, 6])
        return
    if args.pool_start:
        pool_start(hall_doc([2], args.hall_pairs), args.pool_start, args.whole_plan)
        return
    if args.city_memory:
        raw = city_doc(args.city_blocks, args.city_pairs, [2])
        city_memory(raw, args.city_memory)
        return
    if args.storage_check:
        storage_check(hall_doc(args.counts or [2, 3, 4], args.hall_pairs), args.storage_check)
        return
    if args.bnb_instances:
        branch_and_bound_instances(args.bnb_sites, args.bnb_instances)
        return
    if args.greedy_workers:
        raw = hall_doc(args.counts or [3], args.hall_pairs)
        greedy_workers({**raw, "search": {"method": "greedy"}}, args.greedy_workers)
        return
    if args.case in ("hall", "both"):
        raw = hall_doc(args.counts or [2, 3, 4], args.hall_pairs)
        report("hall 40 × 25 m", raw, args.dask, not args.no_default)
    if args.case in ("city", "both"):
        raw = city_doc(args.city_blocks, args.city_pairs, args.counts or [2, 3, 4, 5, 6])
        n = len(expand_sites(PlanDocument.model_validate(raw)))
        entries = n * args.city_pairs
        print(f"\ncity: {n} candidates × {args.city_pairs} pairs = {entries:.3g} cache entries"
              f" ({entries * 28 * 8 / 2**30:.1f} GiB of float64)")  # fmt: skip
        os.environ.setdefault("RIS_PLANNER_JOB_MEMORY_MB", str(args.job_memory_mb))
        report(
            f"city {args.city_blocks}×{args.city_blocks} blocks",
            raw,
            args.dask,
            not args.no_default,
        )


if __name__ == "__main__":
    main()
