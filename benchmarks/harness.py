"""Timing and the one A/B harness of the benchmark scripts (their folder's parent is put on
``sys.path`` first: ``sys.path.insert(0, str(Path(__file__).resolve().parents[1]))``).

**A/B.** Two trees – this checkout (``new``) and a base (``old``): a commit checked out once
as a detached ``git worktree`` under the system's temporary folder (:func:`base_tree`, from
``--base REF``), or any other checkout (``--old-tree PATH``) – each imported first on the path
of fresh processes and each with **its own numba cache** (the base worktree's
``NUMBA_CACHE_DIR`` lies inside it; this checkout keeps the cache ``make setup`` filled), so
the compiled kernels of one never serve the other. :func:`alternate` measures them
alternately, the order flipped every round, so both see the same load on a shared machine;
:func:`compare` reports the ratio new / old of the medians and its spread (the smallest and
largest ratio of one round's pair of measurements). A command (:func:`run_command`: ``python -m
ris_planner.cli …`` and the like) or a function (:func:`run_in_tree`: Python source whose last
line of output is a JSON object) is what each side runs.

``--quick`` in an A/B script compares this checkout with itself (no worktree, one round): the
harness's own smoke test, not a measurement.
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

ROOT = Path(__file__).resolve().parents[1]
"""This checkout."""

T = TypeVar("T")


def median_time(fn: Callable[..., Any], repeats: int) -> float:
    """Median wall time [s] of ``repeats`` calls of ``fn`` after one warm-up call."""
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


@dataclass(frozen=True)
class Tree:
    """A source tree the A/B harness runs: its code first on the path, its own numba cache."""

    name: str
    path: Path
    numba_cache: Path | None = None
    """The tree's own numba cache (``NUMBA_CACHE_DIR``); ``None``: the environment's choice
    (numba's default caches next to the tree's sources, ``__pycache__``, where ``make setup``
    compiled this checkout's kernels)."""

    def env(self, **extra: str) -> dict[str, str]:
        """The environment of a process that imports this tree's code."""
        cache = {} if self.numba_cache is None else {"NUMBA_CACHE_DIR": str(self.numba_cache)}
        return {**os.environ, "PYTHONPATH": str(self.path), **cache, **extra}

    @property
    def commit(self) -> str:
        """The tree's commit (short), or ``?`` outside git."""
        done = subprocess.run(
            ["git", "-C", str(self.path), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=False,
        )
        return done.stdout.strip() or "?"


def this_tree() -> Tree:
    return Tree("new", ROOT)


def base_tree(ref: str) -> Tree:
    """A detached ``git worktree`` of ``ref`` (made once per commit under the system's
    temporary folder) with its own numba cache (``.numba-cache`` in the worktree, kept with it:
    a second run finds the base's kernels compiled)."""
    sha = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", f"{ref}^{{commit}}"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    path = Path(tempfile.gettempdir()) / f"ris-planner-base-{sha}"
    if not (path / "ris_planner").is_dir():
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(path), sha],
            check=True,
            capture_output=True,
        )
    return Tree("old", path, path / ".numba-cache")


def add_tree_arguments(parser: argparse.ArgumentParser, default_base: str | None = None) -> None:
    """``--base REF`` / ``--old-tree PATH`` and ``--quick`` of an A/B script."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument(
        "--base", default=default_base, help=f"commit of the old code (default {default_base})"
    )
    group.add_argument("--old-tree", type=Path, help="another checkout as the old code")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="this checkout against itself, one round: the harness's smoke test",
    )


def trees(args: argparse.Namespace) -> dict[str, Tree]:
    """``{"old": …, "new": …}`` from :func:`add_tree_arguments`' options."""
    new = this_tree()
    if getattr(args, "quick", False):
        return {"old": Tree("old", ROOT), "new": new}
    if args.old_tree is not None:
        return {"old": Tree("old", args.old_tree.resolve()), "new": new}
    if args.base is None:
        sys.exit("give the old code: --base REF or --old-tree PATH (or --quick)")
    return {"old": base_tree(args.base), "new": new}


def run_in_tree(tree: Tree, code: str, *args: str, timeout: float = 600) -> dict[str, Any]:
    """``python -c CODE ARGS`` in a fresh process that imports ``tree``'s code (its path and
    working directory, its numba cache); the JSON object on its last line of output."""
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=tree.path,
        env=tree.env(),
        capture_output=True,
        text=True,
        check=False,
        timeout=timeout,
    )
    if out.returncode != 0:
        raise RuntimeError(f"{tree.name} ({tree.path}) failed:\n{out.stderr[-3000:]}")
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def run_command(
    tree: Tree, argv: Sequence[str], timeout: float = 1800, **env: str
) -> tuple[float, subprocess.CompletedProcess[str]]:
    """``python ARGV`` (e.g. ``-m ris_planner.cli plan …``) in a fresh process of ``tree``:
    its wall seconds and the finished process (raises naming the tree when it fails)."""
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *argv],
        cwd=tree.path,
        env=tree.env(**env),
        capture_output=True,
        text=True,
        check=False,
        timeout=timeout,
    )
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{tree.name} ({tree.path}): {argv} failed:\n{done.stderr[-3000:]}")
    return wall, done


def alternate(
    trees: dict[str, Tree],
    measure: Callable[[Tree, int], T],
    rounds: int,
    warm: Callable[[Tree], object] | None = None,
    on_result: Callable[[int, Tree, T], None] | None = None,
) -> dict[str, list[T]]:
    """``measure(tree, round)`` for every tree, ``rounds`` times, the order flipped every
    round (old, new; new, old; …); ``warm(tree)`` once per tree first (compiles its kernels
    into its cache). Each tree's results in round order."""
    if warm is not None:
        for tree in trees.values():
            warm(tree)
    out: dict[str, list[T]] = {name: [] for name in trees}
    order = list(trees.items())
    for r in range(rounds):
        for name, tree in order if r % 2 == 0 else order[::-1]:
            value = measure(tree, r)
            out[name].append(value)
            if on_result is not None:
                on_result(r, tree, value)
    return out


@dataclass(frozen=True)
class Comparison:
    """New against old over alternating rounds (:func:`compare`)."""

    old: float
    """Median of the old tree's measurements."""
    new: float
    ratio: float
    """new / old of the medians."""
    low: float
    """The smallest per-round ratio new / old."""
    high: float
    rounds: int

    def text(self, unit: str = "s") -> str:
        return (
            f"old {self.old:.4g} {unit}, new {self.new:.4g} {unit}: new/old {self.ratio:.3f}"
            f" (rounds {self.low:.3f}–{self.high:.3f}, {self.rounds} rounds)"
        )


def compare(old: Sequence[float], new: Sequence[float]) -> Comparison:
    """The ratio new / old of the medians of paired alternating measurements and its spread
    (the range of the per-round ratios)."""
    per_round = [n / o for o, n in zip(old, new, strict=True) if o > 0]
    return Comparison(
        statistics.median(old),
        statistics.median(new),
        statistics.median(new) / statistics.median(old),
        min(per_round),
        max(per_round),
        len(per_round),
    )


def conditions() -> str:
    """The run's date, cores and load, for the report's first line."""
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    return f"{when}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}"
