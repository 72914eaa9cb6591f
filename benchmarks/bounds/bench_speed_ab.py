"""Old vs new in the same run: ``compute_bounds`` on the Fig. 10 workload (4753 pairs; planar
``random`` and ``expected_random`` with N = 100, spherical ``expected_random`` with 100 × 100
RISs) and the planning site cache of the 156-site × 6400-pair hall (``benchmarks/fixtures.py``).

The A/B harness (``benchmarks/harness.py``): each measurement runs in a fresh process of this
checkout or of the base (``--base REF``: a ``git worktree`` of that commit with its own numba
cache, or ``--old-tree PATH``), alternating ``--rounds`` times; the table gives the minimum wall
time per call over all rounds and repeats (the least disturbed one on a shared machine), the
ratio new/old of the per-round medians and its spread. Both run with the machine's default BLAS
threads.

    python benchmarks/bounds/bench_speed_ab.py --base REF [--rounds 3] [--cases ...]
    python benchmarks/bounds/bench_speed_ab.py --quick   # this checkout against itself
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import FIG10_LAYOUTS
from harness import Tree, add_tree_arguments, alternate, compare, conditions, run_command, trees

CASES = [f"planar random {lay}" for lay in FIG10_LAYOUTS]
CASES += [f"planar expected_random {lay}" for lay in FIG10_LAYOUTS]
CASES += [f"spherical expected_random {lay}" for lay in ("2-ris-L", "4-ris")]
CASES += ["site cache hall"]


def measure(case: str, repeats: int) -> dict[str, float]:
    """Min wall and CPU seconds of one call of ``case`` (run in the worker process: the tree's
    ``ris_planner``, this checkout's fixtures)."""
    from fixtures import fig10_document, fig10_pairs, hall_document, spherical_document

    from ris_planner import compute_bounds, load_scenario

    words = case.split()
    if words[0] == "site":
        from ris_planner.environment import Scene
        from ris_planner.planning import PlanDocument
        from ris_planner.planning.inputs.sites import expand_sites
        from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
        from ris_planner.planning.scoring.site_cache import build_site_cache
        from ris_planner.planning.scoring.visibility import pair_visibility

        d = PlanDocument.model_validate(hall_document([3]))
        sites = expand_sites(d)
        pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
        vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)

        def call() -> Any:
            return build_site_cache(d.system, sites, pairs, visibility=vis, known=())

    else:
        wavefront, kind, layout = words
        tx, rx = fig10_pairs()
        doc = (
            spherical_document(layout) if wavefront == "spherical" else fig10_document(layout, kind)
        )
        sc = load_scenario(doc)

        def call() -> Any:
            return compute_bounds(sc, tx=tx, rx=rx)

    call()  # warm-up
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"wall": min(wall), "cpu": min(cpu)}


def run_worker(tree: Tree, case: str, repeats: int) -> dict[str, float]:
    _, done = run_command(tree, [__file__, "--worker", case, "--repeats", str(repeats)], 600)
    result: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_tree_arguments(ap)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cases", nargs="*", default=CASES)
    ap.add_argument("--worker")
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.worker, args.repeats)))
        return
    if args.quick:
        args.rounds, args.repeats, args.cases = 1, 1, CASES[:1]
    sides = trees(args)
    print(f"{conditions()}; old {sides['old'].commit}, new {sides['new'].commit}")
    print(
        f"{'case':32s} {'old [s]':>9s} {'new [s]':>9s} {'new/old':>8s} {'spread':>13s}"
        "   (CPU old, new)"
    )
    for case in args.cases:
        runs = alternate(
            sides, lambda tree, _, case=case: run_worker(tree, case, args.repeats), args.rounds
        )
        o = min(r["wall"] for r in runs["old"])
        n = min(r["wall"] for r in runs["new"])
        c = compare([r["wall"] for r in runs["old"]], [r["wall"] for r in runs["new"]])
        cpu_o = min(r["cpu"] for r in runs["old"])
        cpu_n = min(r["cpu"] for r in runs["new"])
        print(
            f"{case:32s} {o:9.4f} {n:9.4f} {c.ratio:8.2f} {c.low:6.2f}–{c.high:<6.2f}"
            f"   ({cpu_o:.4f}, {cpu_n:.4f})",
            flush=True,
        )


if __name__ == "__main__":
    main()
