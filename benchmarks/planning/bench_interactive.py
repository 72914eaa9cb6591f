"""Interactive planning: a city block and the hall, end to end on the command line,
against the code of a base commit measured in the same run.

    python benchmarks/planning/bench_interactive.py [--case block|hall|all] [--quick]
        [--repeats N] [--base COMMIT | --old-tree PATH | --no-reference] [--smoke]

Each measurement is one ``python -m ris_planner.cli plan FILE --out DIR`` process (start-up,
imports, plan, plan.json, figures and GIS files: what a user waits for), after one warm-up run
per tree that compiles the kernels into the tree's own numba cache ("warm kernels"). The A/B
harness (``benchmarks/harness.py``) runs this checkout and the base tree (a ``git worktree`` of
``--base``, default the commit before the interactive-planning work, 7ce8dc6) alternately, the
order flipped every round, so both see the same load; the ratio new / base of the medians and
its spread over the rounds is the figure that survives a shared machine, the absolute seconds
need a quiet one. Per stage, the new tree's ``timing_s`` (plan.json) is shown beside the wall
time, and ``sum/wall`` checks that the stages account for the process.

Cases (``benchmarks/fixtures.py``): ``block`` – the Kamppi block (the committed
``examples/helsinki`` site: OSM buildings, facade candidates, 1000 sampled pairs, 64 × 64 RISs,
2–4 RISs); ``hall`` – ``--preset hall``. ``--quick``: one timed run per tree. ``--smoke``: a
small plan once, this tree only (the suite's check, seconds).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import helsinki_block, smoke_document
from harness import (
    Tree,
    alternate,
    base_tree,
    compare,
    conditions,
    run_command,
    this_tree,
)

REFERENCE = "7ce8dc6"
"""The commit before the interactive-planning work: the default base of the ratios."""
TARGET_S = {"block": 5.0, "hall": 7.0}
"""The interactive-planning targets, end to end on 2 cores with warm kernels."""


@dataclass(frozen=True)
class Run:
    """One CLI process: its wall time and plan.json's ``timing_s``."""

    wall_s: float
    timing_s: dict[str, float]


def case_args(case: str, work: Path) -> list[str]:
    """The ``plan`` arguments of a case (its document written under ``work``)."""
    if case == "hall":
        return ["--preset", "hall"]
    doc = helsinki_block() if case == "block" else smoke_document()
    path = work / f"{case}.json"
    path.write_text(json.dumps(doc))
    return [str(path)]


def run_cli(tree: Tree, args: list[str], out: Path, workers: int | None = None) -> Run:
    """``python -m ris_planner.cli plan ARGS --out OUT`` in a fresh process of ``tree``."""
    cmd = ["-m", "ris_planner.cli", "plan", *args, "--out", str(out)]
    if workers is not None:
        cmd += ["--workers", str(workers)]
    wall, _ = run_command(tree, cmd)
    plan = json.loads((out / "plan.json").read_text())
    return Run(wall, {k: float(v) for k, v in plan["timing_s"].items()})


def median_wall(runs: list[Run]) -> float:
    return statistics.median(r.wall_s for r in runs)


def section_end_to_end(opts: argparse.Namespace, work: Path) -> list[str]:
    """Per case: wall time of the new and the base tree, their ratio and its spread, the
    target, and the new tree's stage times (median over the repeats) with their sum over the
    wall time."""
    cases = ["block", "hall"] if opts.case == "all" else [opts.case]
    trees = {"new": this_tree()}
    if opts.old_tree is not None:
        trees = {"old": Tree("old", opts.old_tree.resolve()), **trees}
    elif opts.reference:
        trees = {"old": base_tree(opts.reference), **trees}
    lines = [f"trees: {', '.join(f'{n} {t.commit} ({t.path})' for n, t in trees.items())}", ""]
    lines += [
        "| case | new s | base s | new / base (spread over rounds) | target s |"
        " sum(timing_s) / wall |",
        "|---|---|---|---|---|---|",
    ]
    stage_lines: list[str] = []
    for case in cases:
        args = case_args(case, work)
        runs = alternate(
            trees,
            lambda tree, r, args=args, case=case: run_cli(
                tree, args, work / f"{case}-{tree.name}-{r}"
            ),
            opts.repeats,
            warm=lambda tree, args=args, case=case: run_cli(
                tree, args, work / f"{case}-warm-{tree.name}"
            ),
        )
        new = median_wall(runs["new"])
        sums = [sum(r.timing_s.values()) / r.wall_s for r in runs["new"]]
        if "old" in runs:
            c = compare([r.wall_s for r in runs["old"]], [r.wall_s for r in runs["new"]])
            base, ratio = f"{c.old:.2f}", f"{c.ratio:.3f} ({c.low:.3f}–{c.high:.3f})"
        else:
            base, ratio = "–", "–"
        lines.append(
            f"| {case} | {new:.2f} | {base} | {ratio} | {TARGET_S.get(case, '-')} |"
            f" {statistics.median(sums):.3f} |"
        )
        names = list(dict.fromkeys(k for r in runs["new"] for k in r.timing_s))
        stages = {k: statistics.median(r.timing_s.get(k, 0.0) for r in runs["new"]) for k in names}
        stage_lines.append(
            f"{case} stages (s, new tree): " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
        )
        if "old" in runs:
            old = {k: statistics.median(r.timing_s.get(k, 0.0) for r in runs["old"]) for k in names}
            stage_lines.append(
                f"{case} stages (s, base, timed ones only): "
                + ", ".join(f"{k} {v:.2f}" for k, v in old.items() if v > 0)
            )
            stage_lines.append(
                f"{case} wall per round (s): base "
                + ", ".join(f"{r.wall_s:.2f}" for r in runs["old"])
                + "; new "
                + ", ".join(f"{r.wall_s:.2f}" for r in runs["new"])
            )
    return [*lines, "", *stage_lines]


def section_smoke(opts: argparse.Namespace, work: Path) -> list[str]:
    """The smoke case once in the new tree: its wall time and the stage sum over it."""
    run = run_cli(this_tree(), case_args("smoke", work), work / "smoke")
    share = sum(run.timing_s.values()) / run.wall_s
    return [f"smoke: {run.wall_s:.2f} s, sum(timing_s) / wall {share:.3f}, stages {run.timing_s}"]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("block", "hall", "all"), default="all")
    ap.add_argument("--quick", action="store_true", help="one timed run per tree (default 3)")
    ap.add_argument("--repeats", type=int, default=3)
    base = ap.add_mutually_exclusive_group()
    base.add_argument("--base", dest="reference", default=REFERENCE, help="commit of the old code")
    base.add_argument("--old-tree", type=Path, help="another checkout as the old code")
    base.add_argument("--no-reference", dest="reference", action="store_const", const="")
    ap.add_argument("--smoke", action="store_true", help="a small plan, new tree only")
    opts = ap.parse_args(argv)
    if opts.quick:
        opts.repeats = 1
    with tempfile.TemporaryDirectory(prefix="bench-interactive-") as tmp:
        work = Path(tmp)
        if opts.smoke:
            print("\n".join(section_smoke(opts, work)))
            return
        print(f"{conditions()}; os.cpu_count() = {os.cpu_count()}")
        print("\n## end_to_end\n")
        print("\n".join(section_end_to_end(opts, work)))


if __name__ == "__main__":
    main()
