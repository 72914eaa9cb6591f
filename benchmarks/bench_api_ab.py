"""Old vs new ``POST /v1/bounds`` in the same run: ``bench_api.py``'s burst (``--concurrency``
concurrent requests of Table I, one connection each) against a ``ris-planner serve`` of this
checkout and one of ``--old-tree`` (another checkout, e.g. ``git worktree add ../base <commit>``),
alternating ``--alternations`` times, ``--rounds`` bursts per server start.

Per server and burst: requests/s, p95 latency, and the **server's CPU time per request**
(user + system of the server process from ``/proc``, over the bursts). On a machine shared
with other work the wall-clock figures move with the load; the CPU time per request moves much
less, and the ratio new/old of both, measured alternately in one run, is what to compare.
Every answer must be 200, and the new server's answers must equal the old server's (floats to
``tests/tolerance.py``'s ``BOUND_ACCURACY``, the rest exactly) – the same results.

    python benchmarks/bench_api_ab.py --old-tree ../base [--alternations 3] [--rounds 5]
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

from bench_api import one_round, percentile  # the script's folder is on sys.path

from api.launch import Server, served
from ris_planner import preset_document

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from tolerance import BOUND_ACCURACY, assert_close  # noqa: E402


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (Linux ``/proc/<pid>/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@contextmanager
def served_from(tree: Path, db: Path) -> Iterator[Server]:
    """A ``ris-planner serve`` importing ``tree``'s code (its folder first on the path)."""
    here = Path.cwd()
    os.chdir(tree)  # ``python -m`` puts the working folder first on sys.path
    try:
        env = {"PYTHONPATH": str(tree), "RIS_PLANNER_BLAS_THREADS": "1"}
        with served(db, env=env) as server:
            os.chdir(here)
            yield server
    finally:
        os.chdir(here)


def bursts(server: Server, doc: dict[str, Any], n: int, rounds: int) -> dict[str, Any]:
    """Warm up, then ``rounds`` bursts of ``n``: rates, p95s, CPU per request, one answer."""
    asyncio.run(one_round(server.url, doc, 5))
    rates, p95s, answer = [], [], None
    cpu0 = cpu_seconds(server.process.pid)
    for _ in range(rounds):
        wall, lat, responses = asyncio.run(one_round(server.url, doc, n))
        bad = [r.status_code for r in responses if r.status_code != 200]
        assert not bad, f"non-200 answers: {bad}"
        first = responses[0].json()
        assert all(r.json() == first for r in responses), "answers differ within a burst"
        answer = first
        rates.append(n / wall)
        p95s.append(percentile(lat, 95))
    cpu = (cpu_seconds(server.process.pid) - cpu0) / (n * rounds)
    return {"rates": rates, "p95s": p95s, "cpu": cpu, "answer": answer}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old-tree", type=Path, required=True)
    parser.add_argument("--concurrency", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--alternations", type=int, default=3)
    args = parser.parse_args()
    doc = preset_document("paper-table1")
    trees = {"old": args.old_tree.resolve(), "new": ROOT}
    runs: dict[str, list[dict[str, Any]]] = {"old": [], "new": []}
    for i in range(args.alternations):
        for name, tree in trees.items():
            with tempfile.TemporaryDirectory() as tmp, served_from(tree, Path(tmp) / "j.db") as s:
                r = bursts(s, doc, args.concurrency, args.rounds)
            runs[name].append(r)
            print(
                f"{i + 1} {name}: {statistics.median(r['rates']):6.1f} req/s,"
                f" p95 {statistics.median(r['p95s']) * 1e3:6.1f} ms,"
                f" server CPU {r['cpu'] * 1e3:5.2f} ms/request",
                flush=True,
            )
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
    print(
        f"median over {args.alternations} × {args.rounds} bursts of {args.concurrency}:"
        f" old {ro:.1f} req/s, p95 {po * 1e3:.1f} ms, CPU {co * 1e3:.2f} ms/request;"
        f" new {rn:.1f} req/s, p95 {pn * 1e3:.1f} ms, CPU {cn * 1e3:.2f} ms/request;"
        f" new/old: rate ×{rn / ro:.2f}, p95 ×{pn / po:.2f}, CPU per request ×{cn / co:.2f};"
        " answers equal"
    )


if __name__ == "__main__":
    main()
