"""The district relaxation's solve strategies (docs/validation/benchmarks.md, "Faster LP
solves"): on a district plan document's relaxation, each variant in a process of its own
(HiGHS schedules its threads once per process), the certificate's solves one after another –
the first count (interior point from nothing, crossed over to a basis), one round of
separated cuts and the re-solve from that basis, then the sizing question (min Σ z subject to
the goal) and its round – with the seconds of each solve, the bound and the lower count.

Variants: the dual simplex on one thread (the code before 7 December 2026, evening), on two,
and its parallel variant (PAMI) on two (the plan's own, ``LP_THREADS``); the sizing question
from the coverage basis (before) or again by interior point (the plan's own, for a large
model).

    python benchmarks/district/bench_district.py --only headline --out DIR   # DIR/headline.json
    python benchmarks/district/lp_solves.py DIR/headline.json [--count 40 --share 0.9]
    python benchmarks/district/lp_solves.py --quick   # the suite's street site, forced large
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

VARIANTS: dict[str, dict[str, Any]] = {
    "dual simplex, 1 thread; sizing from the coverage basis": {
        "strategy": 1,
        "threads": 1,
        "cold_sizing": False,
    },
    "dual simplex, 2 threads; sizing from the coverage basis": {
        "strategy": 1,
        "threads": 2,
        "cold_sizing": False,
    },
    "PAMI, 2 threads; sizing from the coverage basis": {
        "strategy": 2,
        "threads": 2,
        "cold_sizing": False,
    },
    "PAMI, 2 threads; sizing by interior point (the plan's)": {
        "strategy": 2,
        "threads": 2,
        "cold_sizing": True,
    },
}


def run_variant(plan: Path, count: int, share: float, spec: dict[str, Any], quick: bool) -> None:
    """One variant in this process: prints one JSON line (each solve's seconds, the bound at
    ``count``, the lower count for ``share`` of the servable weight)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from fixtures import district_inputs

    import ris_planner.planning.certify.district_lp as dl
    from ris_planner.planning.district_plan import constraints_of, district_state
    from ris_planner.planning.scoring.sparse import servable_pairs

    if quick:  # the street site's model is small: made a large one, solved the large way
        dl.SIMPLEX_MAX_NONZEROS = 0
    inputs = district_inputs(plan)
    problem = district_state(inputs).problem  # a designed codebook's blocks as the plan's
    model = dl.build_relaxation(problem, dl.sites_needed(problem), *constraints_of(inputs))
    h = model._model()
    h.setOptionValue("threads", int(spec["threads"]))
    h.setOptionValue("simplex_strategy", int(spec["strategy"]))
    seconds: list[tuple[str, float]] = []
    solve = model._solve

    def timed() -> Any:
        kind = "interior point" if not h.getBasis().valid else "simplex"
        out = solve()
        seconds.append((kind, round(out[4], 2)))
        return out

    model._solve = timed  # type: ignore[method-assign]
    t0 = time.perf_counter()
    bound = model.coverage(count).bound
    goal = share * float(problem.weights[servable_pairs(problem)].sum())
    if not spec["cold_sizing"]:
        model.mode = ""  # lower_count keeps the coverage basis (the code before)
    lower = model.lower_count(goal)
    print(
        json.dumps(
            {
                "solves": seconds,
                "bound": bound,
                "lower_count": lower,
                "nonzeros": model.base_nonzeros,
                "total_s": round(time.perf_counter() - t0, 1),
            }
        )
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plan", type=Path, nargs="?", help="a district plan document")
    ap.add_argument("--count", type=int, default=40, help="the count solved first")
    ap.add_argument("--share", type=float, default=0.9, help="sizing goal (servable share)")
    ap.add_argument("--quick", action="store_true", help="the suite's small street site")
    ap.add_argument("--variant", help=argparse.SUPPRESS)  # one variant, in a child process
    args = ap.parse_args()
    if args.quick:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from fixtures import quick_street_plan

        args.plan, args.count, args.share = quick_street_plan("lp-solves-"), 2, 0.5
    elif args.plan is None:
        ap.error("a plan document is needed (or --quick)")
    if args.variant is not None:
        run_variant(args.plan, args.count, args.share, VARIANTS[args.variant], args.quick)
        return
    print(
        f"# District LP solves ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}):"
        f" {args.plan.name}, count {args.count}, sizing goal {args.share:g} of the servable"
    )
    print("| variant | solves (kind: s) | total s | bound | lower count |")
    print("|---|---|---|---|---|")
    for name in VARIANTS:
        cmd = [sys.executable, __file__, str(args.plan), "--count", str(args.count)]
        cmd += ["--share", str(args.share), "--variant", name] + (["--quick"] * args.quick)
        done = subprocess.run(cmd, capture_output=True, text=True, check=True)
        got = json.loads(done.stdout.strip().splitlines()[-1])
        solves = ", ".join(f"{k}: {s:.1f}" for k, s in got["solves"])
        print(
            f"| {name} | {solves} | {got['total_s']:.1f} | {got['bound']:.4f} |"
            f" {got['lower_count']} |"
        )
    print(f"(the model's nonzeros at build: {got['nonzeros']})")


if __name__ == "__main__":
    main()
