"""Layout-scoring benchmark: the compiled scorer (``Scorer.metric``: fused gather-and-add,
LDLᵀ, trace test and metric in numba, square-root route by certified QR / Jacobi SVD) against
the previous route measured in the same run (``Scorer.metric_reference`` – numpy gather-and-add
of [28, nb, P] blocks, numpy LDLᵀ, every flagged pair through the square-root route – with
LAPACK's SVD, as before this change).

Sections (all in one process; ``numba`` uses every core, ``NUMBA_NUM_THREADS`` to change):
* ``hall``: issue 14's synthetic hall (156 candidates, 6400 pairs): fixed random layouts of 2,
  3 and 4 RISs, matrices/s old and new, the largest difference (0 on the fast path; the
  square-root route's two SVDs differ by rounding), the pair-block copy's size and time;
  ``--plan`` also runs the whole 2/3/4-RIS plan (``run_plan``, serial executor) new and old.
* ``exhaustive``: issue 10's 30 candidates × 3 RISs × 4753 pairs, exhaustive, serial executor.
* ``junction``: the junction preset plan with and without its environment (issue 9), and
  fixed 3-RIS layouts scored with and without the presence masks, old and new.

    python benchmarks/bench_scorer.py [--sections hall exhaustive junction] [--plan]
        [--layouts 300]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from bench_planning import square_plan  # the script's folder is on sys.path
from bench_search import hall_doc

from ris_planner.inversion import crb
from ris_planner.planning import PlanDocument, SerialExecutor, plan_preset, run_plan
from ris_planner.planning.maps import build_map, build_pairs
from ris_planner.planning.objectives import Scorer
from ris_planner.planning.search import all_layouts, exhaustive
from ris_planner.planning.site_cache import build_site_cache
from ris_planner.planning.sites import expand_sites


@contextmanager
def previous_scorer() -> Iterator[None]:
    """``Scorer.metric`` as before the compiled kernel: the numpy route, and the square-root
    route by LAPACK's SVD for every flagged pair."""
    metric, svd, sqrt_diag = Scorer.metric, crb.svd, crb.sqrt_crb_diagonal
    Scorer.metric = Scorer.metric_reference  # type: ignore[method-assign]
    crb.svd = crb.svd_lapack
    crb.sqrt_crb_diagonal = crb.sqrt_crb_diagonal_svd
    try:
        yield
    finally:
        Scorer.metric = metric  # type: ignore[method-assign]
        crb.svd = svd
        crb.sqrt_crb_diagonal = sqrt_diag


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def scorer_of(raw: dict[str, Any]) -> Scorer:
    doc = PlanDocument.model_validate(raw)
    sites = expand_sites(doc)
    pairs = build_pairs(
        build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, doc.max_pairs
    )
    cache = build_site_cache(doc.system, sites, pairs, known=tuple(doc.known))
    return Scorer(cache, pairs.weights, doc.objective, tuple(doc.known))


def compare(scorer: Scorer, layouts: np.ndarray, label: str) -> tuple[float, float]:
    """Old and new time of one batch, matrices/s, and the largest relative difference."""
    scorer.metric(layouts[:1])  # compile or load, build the pair blocks
    t_new, new = timed(lambda: scorer.metric(layouts))
    with previous_scorer():
        t_old, old = timed(lambda: scorer.metric(layouts))
    size = layouts.shape[0] * scorer.cache.n_pairs
    same = np.isinf(new) == np.isinf(old)
    fin = np.isfinite(old)
    diff = float(np.max(np.abs(new[fin] - old[fin]) / old[fin], initial=0.0))
    print(
        f"{label}: {size / 1e6:.2f} M matrices: old {t_old:.2f} s ({size / t_old / 1e6:.2f} M/s),"
        f" new {t_new:.2f} s ({size / t_new / 1e6:.2f} M/s), ×{t_old / t_new:.1f};"
        f" same inf pattern {bool(same.all())}, max rel diff {diff:.1e}"
    )
    return t_old, t_new


def hall(n_layouts: int, plan: bool) -> None:
    raw = hall_doc([2, 3, 4], 6400)
    scorer = scorer_of(raw)
    t_blocks, _ = timed(lambda: scorer._kernel_inputs)
    blocks = scorer._kernel_inputs["blocks"]
    print(
        f"hall: {scorer.cache.n_sites} sites × {scorer.cache.n_pairs} pairs; pair blocks"
        f" {blocks.nbytes / 2**20:.0f} MiB ({scorer.cache.storage}, the cache's own storage),"
        f" kernel inputs in {t_blocks:.2f} s (incl. compile or cache load)"
    )
    rng = np.random.default_rng(0)
    for n_ris in (2, 3, 4):
        lay = all_layouts(scorer.cache.n_sites, n_ris)
        lay = lay[np.sort(rng.choice(len(lay), n_layouts, replace=False))]
        compare(scorer, lay, f"  L = {n_ris}, {n_layouts} layouts")
    if plan:
        t_new, res = timed(lambda: run_plan(raw, executor=SerialExecutor()))
        with previous_scorer():
            t_old, res_old = timed(lambda: run_plan(raw, executor=SerialExecutor()))
        best = [list(c.ranked[0][0]) for c in res.counts]
        same = best == [list(c.ranked[0][0]) for c in res_old.counts]
        print(
            f"  whole 2/3/4-RIS plan, serial executor: old {t_old:.1f} s, new {t_new:.1f} s"
            f" (×{t_old / t_new:.1f}; search {res.timing['search']:.1f} s vs"
            f" {res_old.timing['search']:.1f} s); same best layouts {same}: {best}"
        )


def exhaustive_case() -> None:
    scorer = scorer_of(square_plan())
    n = scorer.cache.n_sites
    scorer.metric(np.array([[0, 1, 2]]))
    t_new, new = timed(lambda: exhaustive(scorer, n, 3, SerialExecutor()))
    with previous_scorer():
        t_old, old = timed(lambda: exhaustive(scorer, n, 3, SerialExecutor()))
    size = new.total_layouts * scorer.cache.n_pairs
    print(
        f"exhaustive: {new.total_layouts} layouts × {scorer.cache.n_pairs} pairs, serial executor:"
        f" old {t_old:.2f} s, new {t_new:.2f} s (×{t_old / t_new:.1f},"
        f" {size / t_new / 1e6:.1f} M matrices/s); same top 10 {new.ranked(10) == old.ranked(10)}"
    )


def junction(n_layouts: int) -> None:
    doc = plan_preset("junction")
    runs = {}
    for name, d in (("with environment", doc), ("free space", {**doc, "environment": None})):
        t, runs[name] = timed(lambda d=d: run_plan(d, executor=SerialExecutor()))
        print(f"junction plan {name}, serial executor: {t:.1f} s")
    rng = np.random.default_rng(1)
    layouts = np.sort(
        np.array(
            [rng.choice(len(runs["free space"].sites), 3, replace=False) for _ in range(n_layouts)]
        ),
        axis=1,
    )
    times: dict[tuple[str, str], float] = {}
    for name, res in runs.items():
        res.scorer.metric(layouts[:1])
        for route in ("new", "old"):
            best = np.inf
            for _ in range(2):
                if route == "new":
                    t, _ = timed(lambda res=res: res.scorer.loss(layouts))
                else:
                    with previous_scorer():
                        t, _ = timed(lambda res=res: res.scorer.loss(layouts))
                best = min(best, t)
            times[name, route] = best
    for route in ("old", "new"):
        env, free = times["with environment", route], times["free space", route]
        print(
            f"  {n_layouts} fixed 3-RIS layouts, {route} scorer: {env:.2f} s with the environment,"
            f" {free:.2f} s without ({env / free - 1:+.0%})"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--sections", nargs="+", default=["hall", "exhaustive", "junction"],
        choices=["hall", "exhaustive", "junction"],
    )  # fmt: skip
    ap.add_argument("--plan", action="store_true", help="also the whole hall plan, old and new")
    ap.add_argument("--layouts", type=int, default=300)
    args = ap.parse_args()
    if "hall" in args.sections:
        hall(args.layouts, args.plan)
    if "exhaustive" in args.sections:
        exhaustive_case()
    if "junction" in args.sections:
        junction(args.layouts)


if __name__ == "__main__":
    main()
