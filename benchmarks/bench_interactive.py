"""Interactive planning: a city block and the hall, end to end on the command line,
against the code of a reference commit measured in the same run.

    python benchmarks/bench_interactive.py [--case block|hall|all] [--quick] [--repeats N]
                                           [--reference COMMIT | --no-reference] [--smoke]

Each measurement is one ``python -m ris_planner.cli plan FILE --out DIR`` process (start-up,
imports, plan, plan.json, figures and GIS files: what a user waits for), after one warm-up run
per tree that compiles and caches the kernels ("warm kernels"). The new tree and the reference
tree (a ``git worktree`` of ``--reference``, default the commit before this work, 7ce8dc6)
run alternately, so both see the same load; the ratio reference / new of the medians is the
figure that survives a shared machine, the absolute seconds need a quiet one. Per stage, the
new tree's ``timing_s`` (plan.json) is shown beside the wall time, and ``sum/wall`` checks that
the stages account for the process.

Cases: ``block`` – the Kamppi block of ``examples/plan_helsinki.py`` (OSM buildings, facade
candidates, 1000 sampled pairs, 64 × 64 RISs, 2–4 RISs); ``hall`` – ``--preset hall``.
``--smoke``: a small plan once, new tree only (the suite's check, seconds).

The script is a list of sections (one function each: :func:`section_end_to_end`, …) that
share :func:`run_cli`; another section adds a function and a line in :data:`SECTIONS`.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "7ce8dc6"
"""The commit before the interactive-planning work: today's code of the ratios."""
TARGET_S = {"block": 5.0, "hall": 7.0}
"""The interactive-planning targets, end to end on 2 cores with warm kernels."""


@dataclass(frozen=True)
class Run:
    """One CLI process: its wall time and plan.json's ``timing_s``."""

    wall_s: float
    timing_s: dict[str, float]


def block_document(pairs: int = 1000) -> dict[str, Any]:
    """The Kamppi block (examples/plan_helsinki.py) with ``pairs`` sampled pairs."""
    sys.path.insert(0, str(ROOT / "examples"))
    from plan_helsinki import helsinki_document

    return helsinki_document(pairs)[0]


def smoke_document() -> dict[str, Any]:
    """A small free-space plan: six candidates on a ring, 200 pairs, 2–3 RISs of 8 × 8."""
    import math

    ring = [
        {"position": [6 * math.cos(a), 6 * math.sin(a), 2.0], "orientation": [a + math.pi, 0.3, 0]}
        for a in (2 * math.pi * k / 6 for k in range(6))
    ]
    grid = {"grid": {"x": [-4, 4, 1], "y": [-4, 4, 1], "z": [0, 0, 1]}}
    return {
        "ris": {"rows": 8, "cols": 8},
        "candidates": ring,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 200, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3],
    }


def case_args(case: str, work: Path) -> list[str]:
    """The ``plan`` arguments of a case (its document written under ``work``)."""
    if case == "hall":
        return ["--preset", "hall"]
    doc = block_document() if case == "block" else smoke_document()
    path = work / f"{case}.json"
    path.write_text(json.dumps(doc))
    return [str(path)]


def run_cli(tree: Path, args: list[str], out: Path, workers: int | None = None) -> Run:
    """``python -m ris_planner.cli plan ARGS --out OUT`` with ``tree`` first on the path."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", *args, "--out", str(out)]
    if workers is not None:
        cmd += ["--workers", str(workers)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{tree}: plan {args} failed:\n{proc.stderr[-2000:]}")
    plan = json.loads((out / "plan.json").read_text())
    return Run(wall, {k: float(v) for k, v in plan["timing_s"].items()})


def reference_tree(commit: str) -> Path:
    """A detached ``git worktree`` of ``commit`` (made once, under the system's temp folder)."""
    path = Path(tempfile.gettempdir()) / f"ris-planner-ref-{commit}"
    if not (path / "ris_planner").is_dir():
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(path), commit],
            check=True,
            capture_output=True,
        )
    return path


def timed_runs(
    trees: dict[str, Path], args: list[str], repeats: int, work: Path
) -> dict[str, list[Run]]:
    """One warm-up per tree, then ``repeats`` rounds running the trees alternately."""
    runs: dict[str, list[Run]] = {name: [] for name in trees}
    for name, tree in trees.items():
        run_cli(tree, args, work / f"warm-{name}")
    for r in range(repeats):
        for name, tree in trees.items():
            runs[name].append(run_cli(tree, args, work / f"{name}-{r}"))
    return runs


def median_wall(runs: list[Run]) -> float:
    return statistics.median(r.wall_s for r in runs)


def section_end_to_end(opts: argparse.Namespace, work: Path) -> list[str]:
    """Per case: wall time of the new and the reference tree, their ratio, the target, and
    the new tree's stage times (median over the repeats) with their sum over the wall time."""
    cases = ["block", "hall"] if opts.case == "all" else [opts.case]
    trees = {"new": ROOT}
    if opts.reference:
        trees["ref"] = reference_tree(opts.reference)
    lines = [
        "| case | new s | reference s | reference / new | target s | sum(timing_s) / wall |",
        "|---|---|---|---|---|---|",
    ]
    stage_lines: list[str] = []
    for case in cases:
        runs = timed_runs(trees, case_args(case, work), opts.repeats, work)
        new = median_wall(runs["new"])
        ref = median_wall(runs["ref"]) if "ref" in runs else float("nan")
        sums = [sum(r.timing_s.values()) / r.wall_s for r in runs["new"]]
        lines.append(
            f"| {case} | {new:.2f} | {ref:.2f} | {ref / new:.2f} | {TARGET_S.get(case, '-')} |"
            f" {statistics.median(sums):.3f} |"
        )
        names = list(dict.fromkeys(k for r in runs["new"] for k in r.timing_s))
        stages = {k: statistics.median(r.timing_s.get(k, 0.0) for r in runs["new"]) for k in names}
        stage_lines.append(
            f"{case} stages (s, new tree): " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
        )
        if "ref" in runs:
            old = {k: statistics.median(r.timing_s.get(k, 0.0) for r in runs["ref"]) for k in names}
            stage_lines.append(
                f"{case} stages (s, reference, timed ones only): "
                + ", ".join(f"{k} {v:.2f}" for k, v in old.items() if v > 0)
            )
    return [*lines, "", *stage_lines]


def section_smoke(opts: argparse.Namespace, work: Path) -> list[str]:
    """The smoke case once in the new tree: its wall time and the stage sum over it."""
    run = run_cli(ROOT, case_args("smoke", work), work / "smoke")
    share = sum(run.timing_s.values()) / run.wall_s
    return [f"smoke: {run.wall_s:.2f} s, sum(timing_s) / wall {share:.3f}, stages {run.timing_s}"]


SECTIONS: dict[str, Callable[[argparse.Namespace, Path], list[str]]] = {
    "end_to_end": section_end_to_end,
}
"""Section name → function (options, a work folder) → report lines; run in this order."""


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("block", "hall", "all"), default="all")
    ap.add_argument("--quick", action="store_true", help="one timed run per tree (default 3)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--reference", default=REFERENCE, help="commit of the old code")
    ap.add_argument("--no-reference", dest="reference", action="store_const", const="")
    ap.add_argument("--smoke", action="store_true", help="a small plan, new tree only")
    opts = ap.parse_args(argv)
    if opts.quick:
        opts.repeats = 1
    with tempfile.TemporaryDirectory(prefix="bench-interactive-") as tmp:
        work = Path(tmp)
        if opts.smoke:
            print("\n".join(section_smoke(opts, work)))
            return
        print(f"load average {os.getloadavg()[0]:.2f}, cores {os.cpu_count()}")
        for name, section in SECTIONS.items():
            print(f"\n## {name}\n")
            print("\n".join(section(opts, work)))


if __name__ == "__main__":
    main()
