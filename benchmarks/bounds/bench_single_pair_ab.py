"""Old vs new in the same run: one Table I pair in-process – ``compute_bounds(scenario)`` and a
REST request's engine work (``bounds_document(load_scenario(doc))``: validation, bounds, JSON
document with provenance).

The A/B harness (``benchmarks/harness.py``): each measurement runs in a fresh process of this
checkout or of the base (``--base REF``: a ``git worktree`` of that commit with its own numba
cache, or ``--old-tree PATH``), alternating ``--rounds`` times; per process ``--repeats`` timed
calls after 30 warm-up calls. Reported: the minimum and the median wall time per call over all
rounds, the ratio new/old of the medians with its spread over the rounds (on a shared machine
the ratio of the minima is the least disturbed figure). The two trees' answers must agree
(``tests/tolerance.py``, ``BOUND_ACCURACY``).

    python benchmarks/bounds/bench_single_pair_ab.py --base REF [--rounds 5] [--repeats 300]
    python benchmarks/bounds/bench_single_pair_ab.py --quick   # this checkout against itself
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from harness import Tree, add_tree_arguments, alternate, compare, conditions, run_in_tree, trees
from tolerance import BOUND_ACCURACY, assert_close

WORKER = r"""
import json, sys, time
import ris_planner
from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.bounds.compute import bounds_document

doc = preset_document("paper-table1")
sc = load_scenario(doc)
repeats = int(sys.argv[1])

def times(fn):
    for _ in range(30):
        fn()
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out

res = {
    "file": ris_planner.__file__,
    "compute_bounds": times(lambda: compute_bounds(sc)),
    "request": times(lambda: bounds_document(load_scenario(doc))),
    "answer": compute_bounds(sc).to_json(batch=False),
}
print(json.dumps(res))
"""


def run(tree: Tree, repeats: int) -> dict[str, Any]:
    """One fresh process importing ``tree``'s ris_planner."""
    res = run_in_tree(tree, WORKER, str(repeats))
    assert Path(res["file"]).resolve().is_relative_to(tree.path.resolve()), res["file"]
    return res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_tree_arguments(parser)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()
    if args.quick:
        args.rounds, args.repeats = 1, 20
    sides = trees(args)
    runs = alternate(sides, lambda tree, _: run(tree, args.repeats), args.rounds)
    assert_close(runs["new"][0]["answer"], runs["old"][0]["answer"], accuracy=BOUND_ACCURACY)
    print(f"{conditions()}; old {sides['old'].commit}, new {sides['new'].commit}")
    print(f"{args.rounds} alternating rounds × {args.repeats} calls per process; answers agree")
    print(
        "| case | old min [ms] | new min [ms] | new/old (min) | old median | new median |"
        " new/old (medians, spread over rounds) |"
    )
    print("|---|---:|---:|---:|---:|---:|---|")
    for case in ("compute_bounds", "request"):
        o = [x for r in runs["old"] for x in r[case]]
        n = [x for r in runs["new"] for x in r[case]]
        c = compare(
            [statistics.median(r[case]) for r in runs["old"]],
            [statistics.median(r[case]) for r in runs["new"]],
        )
        print(
            f"| {case} | {min(o) * 1e3:.3f} | {min(n) * 1e3:.3f} | {min(n) / min(o):.2f} |"
            f" {statistics.median(o) * 1e3:.3f} | {statistics.median(n) * 1e3:.3f} |"
            f" {c.ratio:.2f} ({c.low:.2f}–{c.high:.2f}) |"
        )


if __name__ == "__main__":
    main()
