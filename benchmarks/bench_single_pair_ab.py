"""Old vs new in the same run: one Table I pair in-process – ``compute_bounds(scenario)`` and a
REST request's engine work (``bounds_document(load_scenario(doc))``: validation, bounds, JSON
document with provenance).

Each measurement runs in a fresh process of this checkout or of ``--old-tree`` (another
checkout, e.g. ``git worktree add ../base <commit>``; the same interpreter, that tree first on
the path), alternating ``--rounds`` times; per process ``--repeats`` timed calls after 30
warm-up calls. Reported: the minimum and the median wall time per call over all rounds, and
the ratio new/old (on a shared machine the ratio of the minima is the least disturbed figure).
The two trees' answers must agree (``tests/tolerance.py``, ``BOUND_ACCURACY``).

    python benchmarks/bench_single_pair_ab.py --old-tree ../base [--rounds 5] [--repeats 300]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from timing import run_in_tree  # noqa: E402  (the script's folder is on sys.path)
from tolerance import BOUND_ACCURACY, assert_close  # noqa: E402

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


def run(tree: Path, repeats: int) -> dict[str, Any]:
    """One fresh process importing ``tree``'s ris_planner."""
    res = run_in_tree(tree, WORKER, str(repeats))
    assert Path(res["file"]).resolve().is_relative_to(tree), res["file"]
    return res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old-tree", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()
    trees = {"old": args.old_tree.resolve(), "new": ROOT}
    got: dict[str, dict[str, list[float]]] = {name: {} for name in trees}
    answers = {}
    for _ in range(args.rounds):
        for name, tree in trees.items():
            res = run(tree, args.repeats)
            answers[name] = res["answer"]
            for case in ("compute_bounds", "request"):
                got[name].setdefault(case, []).extend(res[case])
    assert_close(answers["new"], answers["old"], accuracy=BOUND_ACCURACY, where="bounds")
    print(f"{args.rounds} alternating rounds × {args.repeats} calls per process; answers agree")
    print("| case | old min [ms] | new min [ms] | new/old (min) | old median | new median |")
    print("|---|---:|---:|---:|---:|---:|")
    for case in ("compute_bounds", "request"):
        o, n = got["old"][case], got["new"][case]
        print(
            f"| {case} | {min(o) * 1e3:.3f} | {min(n) * 1e3:.3f} | {min(n) / min(o):.2f} |"
            f" {statistics.median(o) * 1e3:.3f} | {statistics.median(n) * 1e3:.3f} |"
        )


if __name__ == "__main__":
    main()
