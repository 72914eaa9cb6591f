"""Layout-scoring benchmark: the compiled scorer (``Scorer.metric``: fused gather-and-add,
LDLᵀ, trace test and metric in numba, square-root route by certified QR / Jacobi SVD) against
the previous route measured in the same run (``Scorer.metric_reference`` – numpy gather-and-add
of [28, nb, P] blocks, numpy LDLᵀ, every flagged pair through the square-root route – with
LAPACK's SVD, as before this change).

Sections (all in one process; ``numba`` uses every core, ``NUMBA_NUM_THREADS`` to change):
* ``hall``: the synthetic hall of the fixtures (156 candidates, 6400 pairs): fixed random layouts
  of 2, 3 and 4 RISs, matrices/s old and new, the largest difference (0 on the fast path; the
  square-root route's two SVDs differ by rounding), the pair-block copy's size and time; ``--plan``
  also runs the whole 2/3/4-RIS plan (``run_plan``, serial executor) new and old.
* ``exhaustive``: the square plan's 30 candidates × 3 RISs × 4753 pairs, exhaustive, serial
  executor.
* ``junction``: the junction preset plan with and without its environment, and
  fixed 3-RIS layouts scored with and without the presence masks, old and new.
* ``flops``: the compiled kernel alone (``_crb_jit.score_layouts``, no screen, no
  square-root route) on the hall's pairs: the search's own batches (the first layouts of an
  exhaustive search over 24 sites, whose pair blocks fit the L2 cache: each layout adds about
  one site block to the partial sum of the one before) and random layouts of 2, 3 and 4 RISs
  among all 156 sites (every block added, from memory), as floating-point operations per
  layout-pair – the blocks the kernel adds (:func:`batch_flops`) and the FLOP model
  :func:`ris_planner.inversion._crb_jit.score_flops`, checked against an instrumented count in
  tests/test_ldl.py –, flop/s and the fraction of the machine's peak – a float64 matrix product
  by numpy with the same thread count, measured in the same run, interleaved with the kernel
  (best of ``--repeats`` each, so a loaded machine's slices count alike; OpenBLAS's threads
  given :data:`BLAS_PARK_S` to stop spinning) – for 1 and 2 threads; then the LDLᵀ alone, the
  loop kernel against the unrolled one (``factor_chunk``), and the divider's measured
  throughput and the bound its 7 divisions per pair put on the LDLᵀ.

    python benchmarks/planning/bench_scorer.py [--sections hall exhaustive junction flops]
        [--plan] [--layouts 300] [--repeats 7] [--flops-layouts 24] [--quick]

``--quick``: the hall section, 20 layouts.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numba
import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import hall_document as hall_doc
from fixtures import square_plan

from ris_planner.inversion import _crb_jit, crb
from ris_planner.inversion.ldl import ldl_flops
from ris_planner.planning import PlanDocument, SerialExecutor, plan_preset, run_plan
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.search.layouts import all_layouts, exhaustive


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


PEAK_N = 1024
"""Size of the float64 matrix product that measures the peak (2n³ flops: 2.1 Gflop, ~50 ms
on one core: as long as each kernel run, so that on a loaded machine the best of several
catches equally quiet slices for both)."""


def peak_flops(threads: int) -> float:
    """flop/s of one n × n float64 product by numpy's BLAS with ``threads`` threads."""
    rng = np.random.default_rng(0)
    a, b = rng.random((PEAK_N, PEAK_N)), rng.random((PEAK_N, PEAK_N))
    with threadpool_limits(threads, user_api="blas"):
        t, _ = timed(lambda: a @ b)
    return 2.0 * PEAK_N**3 / t


@numba.njit(cache=False, nogil=True, error_model="numpy")
def _ldl_loop(chunks: np.ndarray, unrolled: bool, reps: int) -> float:
    """The LDLᵀ of chunks [K, 28, CHUNK], ``reps`` times over, by the loop kernel or the
    unrolled one; returns a checksum (so nothing is optimised away)."""
    c = chunks.shape[2]
    a = np.empty((28, c))
    work = np.empty((_crb_jit.work_rows(7), c))
    diag, trace = np.empty((7, c)), np.empty(c)
    sing = np.empty(c, dtype=np.bool_)
    acc = 0.0
    for _ in range(reps):
        for k in range(chunks.shape[0]):
            a[:, :] = chunks[k]
            if unrolled:
                _crb_jit.factor_chunk(a, 7, c, work, diag, trace, sing)
            else:
                _crb_jit.ldl_chunk(a, 7, c, work, diag, trace, sing)
            acc += diag[6, 0]
    return acc


@numba.njit(cache=False, nogil=True, error_model="numpy")
def _divider(x: np.ndarray, y: np.ndarray, out: np.ndarray, reps: int) -> float:
    """``reps`` vector passes of x / y over L1-resident rows: the divider's rate."""
    acc = 0.0
    for r in range(reps):
        for q in range(x.shape[0]):
            out[q] = x[q] / y[q]
        acc += out[r % x.shape[0]]
    return acc


def divider_rate() -> float:
    """Divisions/s of one thread on vectors that stay in the L1 cache."""
    rng = np.random.default_rng(3)
    x, y = np.abs(rng.standard_normal(512)) + 1.0, np.abs(rng.standard_normal(512)) + 1.0
    o = np.empty(512)
    _divider(x, y, o, 1)
    t = min(timed(lambda: _divider(x, y, o, 20_000))[0] for _ in range(3))
    return 20_000 * 512 / t


def best_times(threads: int, repeats: int, runs: dict[Any, Callable[[], Any]]) -> dict[Any, float]:
    """Best of ``repeats`` times of each run with ``threads`` numba threads, the runs
    interleaved (each repeat runs every one once) so a loaded machine's slices count alike;
    key "peak": 1 / the peak flop/s, measured among them."""
    numba.set_num_threads(threads)
    best: dict[Any, float] = {}
    for _ in range(repeats):
        best["peak"] = min(best.get("peak", np.inf), 1.0 / peak_flops(threads))
        time.sleep(BLAS_PARK_S)  # OpenBLAS's threads spin after a product: let them park
        for key, run in runs.items():
            best[key] = min(best.get(key, np.inf), timed(run)[0])
    return best


BLAS_PARK_S = 0.3
"""Pause after each peak measurement: OpenBLAS's worker threads keep spinning for a while
after a threaded product (``OPENBLAS_THREAD_TIMEOUT``: 2²⁸ cycles, ~0.1 s), and a kernel
started meanwhile shares its cores with them (measured: 2 threads gave the layouts 1.2× the
rate of 1 without the pause)."""


NEAR_SITES = 24
"""Sites of the ``flops`` runs whose pair blocks fit the L2 cache (24 × 28 × 64 × 8 B = 344 KB
per block, against 2.2 MB for all 156): the difference to the runs over all sites is the cost
of gathering the site blocks from the L3 cache or memory."""


def summed_columns(layouts: np.ndarray) -> int:
    """Site blocks :func:`ris_planner.inversion._crb_jit.score_layouts` adds per pair over the
    batch ``layouts`` [B, L] (every pair live): each chunk starts afresh (all L columns), and a
    layout that shares its first k < L sites with the one before reuses their partial sum
    (the search's lexicographic batches: about one column per layout)."""
    b_all, n_l = layouts.shape
    total = n_l if b_all else 0
    for b in range(1, b_all):
        same = 0
        while same < n_l - 1 and layouts[b, same] == layouts[b - 1, same]:
            same += 1
        total += n_l - same
    return total


def batch_flops(layouts: np.ndarray, n: int, los: bool, rows: tuple[int, ...]) -> int:
    """Floating-point operations per pair of scoring the batch ``layouts`` (all pairs live
    and factored): E additions per site block added (:func:`summed_columns`; the first
    column is a copy without LOS), plus :func:`~ris_planner.inversion._crb_jit.score_flops`'s
    LDLᵀ and metric per layout."""
    e_n = n * (n + 1) // 2
    per_layout = _crb_jit.score_flops(n, 0, los, rows) + (0 if los else e_n)
    columns = summed_columns(layouts)
    if not los:  # a chunk's first layout copies its first block (no additions)
        columns -= 1
    return layouts.shape[0] * per_layout + columns * e_n


RUNS = (
    ("search", 2, NEAR_SITES),
    ("search", 3, NEAR_SITES),
    ("search", 4, NEAR_SITES),
    ("random", 2, 0),
    ("random", 3, 0),
    ("random", 4, 0),
)
"""The ``flops`` runs: (kind, L, sites drawn from; 0 = all). ``search``: the first layouts of
an exhaustive search over the first :data:`NEAR_SITES` sites, in its lexicographic order (each
layout adds about one site block to the partial sum of the one before: the search's own
batches, blocks in the L2 cache); ``random``: layouts drawn at random among all the hall's
sites (every block added, from memory: the worst case)."""


def flops(n_layouts: int, repeats: int, n_pairs: int = 6400, reps: int = 1000) -> dict[str, float]:
    """The kernel's flop/s against the peak measured in the same run (module docstring);
    returns the fractions of the peak by run name (the test suite's fast check)."""
    scorer = scorer_of(hall_doc([2, 3, 4], n_pairs))
    args = dict(scorer._kernel_inputs)
    n, p, los = args["n"], scorer.cache.n_pairs, args["los"].size > 0
    rows = (len(args["first"]),) if args["mode"] == 0 else (len(args["first"]), len(args["second"]))
    model = ldl_flops(n)
    print(
        f"flops: hall ({scorer.cache.n_sites} sites × {p} pairs, n = {n} states, metric PEB over"
        f" {rows} states): LDLᵀ + diagonal + trace {sum(model.values())} flop per pair {model};"
        f" sum {n * (n + 1) // 2} per site block added; every block added:"
        f" {_crb_jit.score_flops(n, 3, los, rows)} per layout-pair at 3 RISs"
    )
    rng = np.random.default_rng(2)
    lays = {}
    for kind, n_ris, n_drawn in RUNS:
        lay = all_layouts(n_drawn or scorer.cache.n_sites, n_ris)
        if kind == "search":
            lays[kind, n_ris, n_drawn] = lay[:n_layouts]
        else:
            lays[kind, n_ris, n_drawn] = lay[
                np.sort(rng.choice(len(lay), n_layouts, replace=False))
            ]
    out = np.empty((n_layouts, p))
    route = np.empty((n_layouts, p), dtype=np.uint8)
    factored = {}

    def kernel(key: tuple[str, int, int]) -> None:
        _crb_jit.score_layouts(
            layouts=lays[key], out=out, route=route, n_tasks=_crb_jit.n_tasks(),
            screen_limit=0.0, **args,
        )  # fmt: skip
        # factored: flagged for the square-root route (its ``out`` undefined) or finite;
        # the rest are blind (``inf`` from the presence rule: neither summed nor factored)
        slow = route == _crb_jit.SLOW
        factored[key] = int(np.count_nonzero(slow | np.isfinite(out)))

    kernel(RUNS[0])
    chunks = np.ascontiguousarray(scorer.cache.blocks[:8, 0, :28])  # one site's 512 pairs
    chunks += np.eye(7)[np.tril_indices(7)][None, :, None]  # regular: no singular pair
    # reps = 1000: 512 000 matrices, ~15 ms
    count = reps * chunks.shape[0] * chunks.shape[2]
    _ldl_loop(chunks, True, 1)
    _ldl_loop(chunks, False, 1)
    runs: dict[Any, Callable[[], Any]] = {k: lambda k=k: kernel(k) for k in lays}
    fractions: dict[str, float] = {}
    for threads in (1, 2):
        extra = {("ldl", u): lambda u=u: _ldl_loop(chunks, u, reps) for u in (False, True)}
        best = best_times(threads, repeats, {**runs, **(extra if threads == 1 else {})})
        peak = 1.0 / best["peak"]
        print(f"  {threads} thread(s): peak (numpy {PEAK_N}² product) {peak / 1e9:.1f} Gflop/s")
        for (kind, n_ris, n_drawn), t in ((k, best[k]) for k in lays):
            key = (kind, n_ris, n_drawn)
            assert factored[key] == n_layouts * p, "every pair live and factored"
            per = batch_flops(lays[key], n, los, rows) / n_layouts
            rate = factored[key] * per / t
            where = (
                f"exhaustive's first {n_layouts} layouts of {n_drawn} sites (blocks in L2)"
                if kind == "search"
                else "random layouts of all sites (blocks from memory)"
            )
            fractions[f"{threads} threads, L = {n_ris}, {kind}"] = rate / peak
            print(
                f"    L = {n_ris}, {where}: {n_layouts * p / t / 1e6:.1f} M layout-pairs/s"
                f" ({per:.0f} flop each): {rate / 1e9:.2f} Gflop/s = {rate / peak:.1%} of the"
                " peak"
            )
        if threads == 1:
            for unrolled, name in ((False, "loop kernel (before)"), (True, "unrolled kernel")):
                rate = count * sum(model.values()) / best["ldl", unrolled]
                fractions[f"LDLᵀ alone, {name}"] = rate / peak
                print(
                    f"    LDLᵀ alone, {name}: {best['ldl', unrolled] / count * 1e9:.1f} ns per"
                    f" matrix, {rate / 1e9:.2f} Gflop/s = {rate / peak:.1%} of the peak"
                )
            div = divider_rate()
            bound = div / model_divisions(n)
            print(
                f"    divider: {div / 1e9:.2f} G divisions/s: the {model_divisions(n)} divisions"
                f" of a pair bound the LDLᵀ to {bound / 1e6:.0f} M matrices/s ="
                f" {bound * sum(model.values()) / peak:.0%} of the peak"
            )
    return fractions


def model_divisions(n: int) -> int:
    """Divisions per LDLᵀ (ldl.ldl_flops: the n inverse pivots 1/D_j; every other quotient is a
    product by one of them)."""
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--sections", nargs="+", default=["hall", "exhaustive", "junction", "flops"],
        choices=["hall", "exhaustive", "junction", "flops"],
    )  # fmt: skip
    ap.add_argument("--plan", action="store_true", help="also the whole hall plan, old and new")
    ap.add_argument("--layouts", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=7, help="flops: best of this many")
    ap.add_argument(
        "--flops-layouts",
        type=int,
        default=24,
        help=f"flops: layouts per run, ≤ C({NEAR_SITES}, 2) (24: ~50 ms each)",
    )
    ap.add_argument("--quick", action="store_true", help="the hall section, 20 layouts")
    args = ap.parse_args()
    if args.quick:
        args.sections, args.layouts = ["hall"], 20
    if "hall" in args.sections:
        hall(args.layouts, args.plan)
    if "exhaustive" in args.sections:
        exhaustive_case()
    if "junction" in args.sections:
        junction(args.layouts)
    if "flops" in args.sections:
        most = math.comb(NEAR_SITES, 2)  # the smallest search run: every L = 2 layout
        if not 1 <= args.flops_layouts <= most:
            ap.error(f"--flops-layouts must be 1 … {most} (the L = 2 search run's layouts)")
        flops(args.flops_layouts, args.repeats)


if __name__ == "__main__":
    main()
