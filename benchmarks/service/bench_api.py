"""Benchmark: 50 concurrent ``POST /v1/bounds`` (Table I scenario) against a real uvicorn
server on 127.0.0.1, started with ``ris-planner serve`` on a free port and a temporary database.

Each round sends ``--concurrency`` requests at once (one asyncio task each) and waits for all;
every answer must be 200 and equal (``tests/tolerance.py``'s ``BOUND_ACCURACY``) to the
in-process ``compute_bounds(...).to_json()`` (what ``ris-planner bounds`` prints).

Connections: by default the client keeps ``--concurrency`` persistent (keep-alive)
connections, opened by a warm-up burst before the timed rounds – what a real client library
does. ``--fresh-connections`` opens one new connection per request instead (a new client per
round: the measurements of 2026-12-01); on a 2-core machine that client's own
TCP and TLS-free connection set-up costs about as much CPU as the server's work, so the rate
it reports is capped by the client.

Printed per round: requests/s (requests / wall time of the round), p50/p95/max latency; per
server: the **server process's CPU time per request** (user + system from
``/proc/<pid>/stat`` over the timed rounds) and this client's CPU time per request – the
server's capacity, independent of the client, is about ``cores / server CPU per request``.
The reference measured in the same run is the in-process engine time of one request
(validation + bounds + JSON), i.e. the cost without HTTP, threads or serialisation.

    python benchmarks/service/bench_api.py [--concurrency 50] [--rounds 5] [--fresh-connections]
                                           [--blas-compare] [--quick]

``--quick``: one round of 10 requests.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import statistics
import sys
import tempfile
import time
from contextlib import AsyncExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
from threadpoolctl import threadpool_limits

from api.launch import served
from ris_planner import compute_bounds, load_scenario

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from fixtures import table1_document
from tolerance import BOUND_ACCURACY, assert_close


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (Linux ``/proc/<pid>/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def new_client(url: str, n: int) -> httpx.AsyncClient:
    limits = httpx.Limits(max_connections=n, max_keepalive_connections=n)
    return httpx.AsyncClient(base_url=url, limits=limits, timeout=60.0)


async def burst(
    clients: httpx.AsyncClient | list[httpx.AsyncClient], doc: dict[str, Any], n: int
) -> tuple[float, list[float], list[httpx.Response]]:
    """``n`` concurrent requests, on one client or one on each of ``clients``: wall time,
    latencies, answers."""
    pool = clients if isinstance(clients, list) else [clients] * n

    async def request(client: httpx.AsyncClient) -> tuple[float, httpx.Response]:
        t0 = time.perf_counter()
        r = await client.post("/v1/bounds", json=doc)
        return time.perf_counter() - t0, r

    t0 = time.perf_counter()
    results = await asyncio.gather(*(request(pool[i % len(pool)]) for i in range(n)))
    wall = time.perf_counter() - t0
    return wall, [lat for lat, _ in results], [r for _, r in results]


async def one_round(
    url: str, doc: dict[str, Any], n: int
) -> tuple[float, list[float], list[httpx.Response]]:
    """One burst of ``n`` on a new client: one new connection per request."""
    async with new_client(url, n) as client:
        return await burst(client, doc, n)


def percentile(values: list[float], q: float) -> float:
    """Nearest-rank percentile (q in 0–100)."""
    ordered = sorted(values)
    k = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[k]


def engine_time(doc: dict[str, Any], expected: dict[str, Any], repeats: int = 50) -> float:
    """Median in-process time of one request's work (validation, bounds, JSON)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        got = compute_bounds(load_scenario(doc)).to_json(batch=False)
        times.append(time.perf_counter() - t0)
        assert got == expected  # the same process and route: the same bits
    return statistics.median(times)


@dataclass
class Figures:
    """One server's timed rounds."""

    rates: list[float] = field(default_factory=list)
    p95s: list[float] = field(default_factory=list)
    server_cpu: float = 0.0  # seconds per request
    client_cpu: float = 0.0

    @property
    def rate(self) -> float:
        return statistics.median(self.rates)

    @property
    def p95(self) -> float:
        return statistics.median(self.p95s)


def check(responses: list[httpx.Response], expected: dict[str, Any] | None) -> list[Any]:
    """All 200 and, with ``expected``, equal to it (the server's provenance aside); the
    answers' JSON."""
    bad = [r.status_code for r in responses if r.status_code != 200]
    assert not bad, f"non-200 answers: {bad}"
    answers = [r.json() for r in responses]
    if expected is not None:
        for answer in answers:  # another process: the bounds' accuracy rule (tests/tolerance.py)
            body = {k: v for k, v in answer.items() if k != "provenance"}  # the server's own
            assert_close(body, expected, accuracy=BOUND_ACCURACY, where="answer")
    return answers


async def timed_rounds(
    url: str,
    pid: int,
    doc: dict[str, Any],
    expected: dict[str, Any] | None,
    n: int,
    rounds: int,
    fresh: bool,
    answers: list[Any] | None = None,
) -> Figures:
    """Warm up, then ``rounds`` bursts of ``n`` against the server of process ``pid``; every
    answer checked (:func:`check`) and, with ``answers``, appended to it."""
    out = Figures()
    async with AsyncExitStack() as stack:
        # n clients of one keep-alive connection each (one client's pool of n connections
        # costs the client O(n) per request to assign: httpcore scans its connections)
        client = [await stack.enter_async_context(new_client(url, 1)) for _ in range(n)]
        await burst(client, doc, n)  # warm-up: imports, thread pool, the n connections
        server_cpu = client_cpu = 0.0
        for i in range(rounds):
            s0, c0 = cpu_seconds(pid), time.process_time()
            if fresh:
                wall, lat, responses = await one_round(url, doc, n)
            else:
                wall, lat, responses = await burst(client, doc, n)
            server_cpu += cpu_seconds(pid) - s0
            client_cpu += time.process_time() - c0
            got = check(responses, expected)  # outside the CPU window: not request work
            if answers is not None:
                answers.extend(got)
            out.rates.append(n / wall)
            out.p95s.append(percentile(lat, 95))
            if expected is not None:
                print(
                    f"  round {i + 1}: {n} concurrent, all 200 and equal to the CLI;"
                    f" {n / wall:6.1f} req/s, latency p50 {percentile(lat, 50) * 1e3:6.1f} ms,"
                    f" p95 {percentile(lat, 95) * 1e3:6.1f} ms, max {max(lat) * 1e3:6.1f} ms",
                    flush=True,
                )
    out.server_cpu = server_cpu / (n * rounds)
    out.client_cpu = client_cpu / (n * rounds)
    return out


def serve_rounds(
    doc: dict[str, Any], expected: dict[str, Any], n: int, rounds: int, blas: int, fresh: bool
) -> Figures:
    """Start a server with RIS_PLANNER_BLAS_THREADS=blas; the timed rounds' figures."""
    env = {"RIS_PLANNER_BLAS_THREADS": str(blas)}
    with tempfile.TemporaryDirectory() as tmp, served(Path(tmp) / "jobs.db", env=env) as server:
        how = "a new connection per request" if fresh else f"{n} keep-alive connections"
        print(f"server {server.url} (ris-planner serve, BLAS threads {blas}; client: {how})")
        figures = asyncio.run(
            timed_rounds(server.url, server.process.pid, doc, expected, n, rounds, fresh)
        )
    print(
        f"  server CPU {figures.server_cpu * 1e3:.2f} ms/request,"
        f" client CPU {figures.client_cpu * 1e3:.2f} ms/request"
    )
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--concurrency", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument(
        "--fresh-connections",
        action="store_true",
        help=(
            "one new connection per request (the 2026-12-01 measurement's client) instead of"
            " keep-alive"
        ),
    )
    parser.add_argument(
        "--blas-compare",
        action="store_true",
        help="also run a server with as many BLAS threads as cores",
    )
    parser.add_argument("--quick", action="store_true", help="one round of 10 requests")
    args = parser.parse_args()
    if args.quick:
        args.concurrency, args.rounds = 10, 1

    doc = table1_document()
    expected = compute_bounds(load_scenario(doc)).to_json(batch=False)
    cores = os.cpu_count() or 1
    with threadpool_limits(limits=1):
        engine = engine_time(doc, expected)
    print(
        f"in-process reference, 1 BLAS thread (validate + compute_bounds + to_json):"
        f" {engine * 1e3:.2f} ms per request = {1 / engine:.0f} requests/s on one core"
    )
    n, fresh = args.concurrency, args.fresh_connections
    f1 = serve_rounds(doc, expected, n, args.rounds, 1, fresh)
    print(
        f"median over {args.rounds} rounds of {n} concurrent requests"
        f" ({'new connection each' if fresh else 'keep-alive'}): {f1.rate:.1f} requests/s,"
        f" p95 latency {f1.p95 * 1e3:.1f} ms; server CPU {f1.server_cpu * 1e3:.2f} ms/request"
        f" (≈ {cores / f1.server_cpu:.0f} requests/s on {cores} cores without a client),"
        f" client CPU {f1.client_cpu * 1e3:.2f} ms/request; HTTP rate / in-process 1-core rate"
        f" = {f1.rate * engine:.2f} on {cores} cores"
    )
    if args.blas_compare:
        fn = serve_rounds(doc, expected, n, args.rounds, cores, fresh)
        print(
            f"with {cores} BLAS threads: {fn.rate:.1f} requests/s, p95 {fn.p95 * 1e3:.1f} ms,"
            f" server CPU {fn.server_cpu * 1e3:.2f} ms/request (rate x{f1.rate / fn.rate:.2f}"
            " with 1 BLAS thread)"
        )


if __name__ == "__main__":
    main()
