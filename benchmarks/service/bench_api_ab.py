"""Old vs new ``POST /v1/bounds`` in the same run: ``bench_api.py``'s burst (``--concurrency``
concurrent requests of Table I, on keep-alive connections unless ``--fresh-connections``)
against a ``ris-planner serve`` of this checkout and one of the base (the A/B harness,
``benchmarks/harness.py``: ``--base REF``, a ``git worktree`` of that commit with its own numba
cache, or ``--old-tree PATH``), alternating ``--alternations`` times, ``--rounds`` bursts per
server start.

Per server and burst: requests/s, p95 latency, and the **server's CPU time per request**
(user + system of the server process from ``/proc``, over the bursts). On a machine shared
with other work the wall-clock figures move with the load; the CPU time per request moves much
less, and the ratio new/old of both, measured alternately in one run, is what to compare.
Every answer must be 200, and the new server's answers must equal the old server's (floats to
``tests/tolerance.py``'s ``BOUND_ACCURACY``, the rest exactly) – the same results.

    python benchmarks/service/bench_api_ab.py --base REF [--alternations 3] [--rounds 5]
    python benchmarks/service/bench_api_ab.py --quick   # this checkout against itself
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from bench_api import timed_rounds  # the script's folder is on sys.path
from fixtures import table1_document
from harness import Tree, add_tree_arguments, alternate, compare, conditions, trees
from tolerance import BOUND_ACCURACY, assert_close

from api.launch import Server, served


@contextmanager
def served_from(tree: Tree, db: Path, blocked: Path | None = None) -> Iterator[Server]:
    """A ``ris-planner serve`` importing ``tree``'s code (its folder first on the path, its
    numba cache); with ``blocked``, a folder of modules that refuse to import, before it."""
    here = Path.cwd()
    os.chdir(tree.path)  # ``python -m`` puts the working folder first on sys.path
    try:
        path = str(tree.path) if blocked is None else f"{blocked}{os.pathsep}{tree.path}"
        env = tree.env(PYTHONPATH=path, RIS_PLANNER_BLAS_THREADS="1")
        with served(db, env=env) as server:
            os.chdir(here)
            yield server
    finally:
        os.chdir(here)


def pure_python_http(folder: Path) -> Path:
    """A folder whose ``httptools`` and ``uvloop`` refuse to import: uvicorn's "auto" then
    takes h11 and asyncio – a server as installed without ``uvicorn[standard]``."""
    for name in ("httptools", "uvloop"):
        (folder / f"{name}.py").write_text(f"raise ImportError('{name} blocked (bench_api_ab)')\n")
    return folder


def bursts(server: Server, doc: dict[str, Any], n: int, rounds: int, fresh: bool) -> dict[str, Any]:
    """Warm up, then ``rounds`` bursts of ``n`` (bench_api.py's): rates, p95s, server CPU per
    request, one answer."""
    answers: list[dict[str, Any]] = []
    figures = asyncio.run(
        timed_rounds(server.url, server.process.pid, doc, None, n, rounds, fresh, answers)
    )
    first = answers[0]
    assert all(a == first for a in answers), "answers differ between requests"
    rates, p95s = figures.rates, figures.p95s
    return {"rates": rates, "p95s": p95s, "cpu": figures.server_cpu, "answer": first}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_tree_arguments(parser)
    parser.add_argument("--concurrency", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--alternations", type=int, default=3)
    parser.add_argument(
        "--fresh-connections",
        action="store_true",
        help=(
            "one new connection per request (the 2026-12-01 measurement's client) instead of"
            " keep-alive"
        ),
    )
    parser.add_argument(
        "--old-without-standard",
        action="store_true",
        help="the old server without httptools and uvloop (h11, asyncio), as before"
        " uvicorn[standard] was a dependency",
    )
    args = parser.parse_args()
    if args.quick:
        args.concurrency, args.rounds, args.alternations = 10, 1, 1
    doc = table1_document()
    blocks = Path(tempfile.mkdtemp(prefix="bench-api-ab-"))
    blocked = {"old": pure_python_http(blocks) if args.old_without_standard else None, "new": None}
    sides = trees(args)

    def measure(tree: Tree, _: int) -> dict[str, Any]:
        with (
            tempfile.TemporaryDirectory() as tmp,
            served_from(tree, Path(tmp) / "j.db", blocked[tree.name]) as s,
        ):
            return bursts(s, doc, args.concurrency, args.rounds, args.fresh_connections)

    def show(i: int, tree: Tree, r: dict[str, Any]) -> None:
        print(
            f"{i + 1} {tree.name}: {statistics.median(r['rates']):6.1f} req/s,"
            f" p95 {statistics.median(r['p95s']) * 1e3:6.1f} ms,"
            f" server CPU {r['cpu'] * 1e3:5.2f} ms/request",
            flush=True,
        )

    print(f"{conditions()}; old {sides['old'].commit}, new {sides['new'].commit}")
    runs = alternate(sides, measure, args.alternations, on_result=show)
    new_doc, old_doc = runs["new"][0]["answer"], runs["old"][0]["answer"]
    assert_close(new_doc, old_doc, accuracy=BOUND_ACCURACY, where="answer")
    summary = {}
    for name, rs in runs.items():
        summary[name] = (
            statistics.median(x for r in rs for x in r["rates"]),
            statistics.median(x for r in rs for x in r["p95s"]),
            statistics.median(r["cpu"] for r in rs),
        )
    (ro, po, co), (rn, pn, cn) = summary["old"], summary["new"]
    cpu = compare([r["cpu"] for r in runs["old"]], [r["cpu"] for r in runs["new"]])
    print(
        f"median over {args.alternations} × {args.rounds} bursts of {args.concurrency}:"
        f" old {ro:.1f} req/s, p95 {po * 1e3:.1f} ms, CPU {co * 1e3:.2f} ms/request;"
        f" new {rn:.1f} req/s, p95 {pn * 1e3:.1f} ms, CPU {cn * 1e3:.2f} ms/request;"
        f" new/old: rate ×{rn / ro:.2f}, p95 ×{pn / po:.2f}, CPU per request ×{cpu.ratio:.2f}"
        f" (rounds {cpu.low:.2f}–{cpu.high:.2f}); answers equal"
    )


if __name__ == "__main__":
    main()
